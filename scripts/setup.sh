#!/usr/bin/env bash
# Sets hpg_mj up on a fresh machine: OSMesa for the render worker's headless
# rendering where there is no GPU, a virtual environment in .venv, and the
# package installed from this checkout as a wheel, assets included.
# `scripts/setup.sh test` adds the test-only dependencies (pytest, Ray); the
# main job (scripts/run.sh) installs none of them.
set -euo pipefail
cd "$(dirname "$0")/.."

if [ ! -e /dev/nvidia0 ] && ! ldconfig -p 2>/dev/null | grep -q 'libOSMesa\.so'; then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  echo "setup: installing OSMesa (libosmesa6) for headless rendering"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libosmesa6 >/dev/null
fi

PYTHON=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv"
  "$PYTHON" -m venv .venv
fi
.venv/bin/python -m pip install -q --disable-pip-version-check --upgrade pip
EXTRAS=${1:+[$1]}
# setuptools reuses build/lib between builds, so a module deleted from the checkout
# would otherwise still ship in the wheel.
rm -rf build
echo "setup: installing hpg_mj${EXTRAS} and its pinned dependencies into .venv"
.venv/bin/python -m pip install -q --disable-pip-version-check ".${EXTRAS}"
