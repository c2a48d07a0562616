#!/usr/bin/env bash
# Builds the documentation (Sphinx, furo, MyST) into docs/_build/html and says where
# it is. Warnings are errors and cross-references nitpicky: a broken link or
# reference, or a docstring that does not parse, fails the build. It documents the
# installed hpg_mj: run scripts/setup.sh (with the test or docs extra) first, or
# `bash scripts/docs.sh --setup` to do both.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${1:-}" = "--setup" ]; then
  shift
  bash scripts/setup.sh docs
fi
.venv/bin/sphinx-build -q -n -W --keep-going -b html "$@" docs docs/_build/html
echo "docs: $(pwd)/docs/_build/html/index.html"
