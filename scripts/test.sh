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
PYTEST=(.venv/bin/pytest -q -p no:cacheprovider -n auto --maxprocesses 4 --dist loadfile)
if [ "$#" -gt 0 ]; then
  exec "${PYTEST[@]}" "$@"
fi
# The JAX environments' tests run on their own: JAX starts threads when it is
# imported, and a worker that had imported it would then fork the runs' processes
# (the process pool, Ray), which may deadlock.
# XLA's CPU intra-op pool (multi-threaded Eigen) can wedge for good on vmapped programs
# on CI machines (seen elsewhere: github.com/PyAutoLabs/PyAutoFit/issues/1528, 14 of 16
# runs; the flag, 0 of 12); here a CI run sat in the JAX tests until its 90-minute limit.
# The tests' networks are small: one thread does their matrix work as fast.
"${PYTEST[@]}" --ignore=tests/jax
XLA_FLAGS="${XLA_FLAGS:+$XLA_FLAGS }--xla_cpu_multi_thread_eigen=false" exec "${PYTEST[@]}" tests/jax
