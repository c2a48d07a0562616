#!/usr/bin/env bash
# Sets hpg_mj up on a fresh machine: OSMesa for the render worker's headless
# rendering where there is no GPU, a virtual environment in .venv, and the
# package installed from this checkout as a wheel, assets included.
# `scripts/setup.sh test` adds the test-only dependencies (pytest, Ray, and Sphinx with
# furo and MyST, since the tests build the documentation); `scripts/setup.sh docs`
# only the documentation's. The main job (scripts/run.sh) installs none of them.
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
# The test and sb3 extras bring Stable-Baselines3 and with it torch, which PyPI serves
# as its CUDA build (~5 GB installed). The tests and the reference agents run on the
# CPU: take the CPU-only build (~0.9 GB) where its index answers, else PyPI's.
if [[ "${1:-}" =~ (^|,)(test|sb3)(,|$) ]] && ! .venv/bin/python -c "import torch" 2>/dev/null; then
  echo "setup: installing the CPU-only torch"
  .venv/bin/python -m pip install -q --disable-pip-version-check --retries 1 --timeout 20 \
      torch --index-url https://download.pytorch.org/whl/cpu \
    || echo "setup: the CPU-only torch index did not answer; pip takes torch from PyPI"
fi
# setuptools reuses build/lib between builds, so a module deleted from the checkout
# would otherwise still ship in the wheel.
rm -rf build
echo "setup: installing hpg_mj${EXTRAS} and its pinned dependencies into .venv"
.venv/bin/python -m pip install -q --disable-pip-version-check ".${EXTRAS}"
