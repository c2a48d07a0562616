#!/usr/bin/env bash
# Sets up (scripts/setup.sh, with the test extras) and runs the test suite against
# the installed package.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh test
# .venv/bin/pytest (not `python -m pytest`) keeps the checkout off sys.path, so the
# tests import the installed hpg_mj and its packaged assets.
# One worker a core (at most 4: each compiles the numba code a cold cache lacks), a test
# file to one worker, so that a file's module-level set-up is made once.
exec .venv/bin/pytest -q -p no:cacheprovider -n auto --maxprocesses 4 --dist loadfile "$@"
