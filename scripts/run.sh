#!/usr/bin/env bash
# Sets up (scripts/setup.sh) and runs the main job: videos of the scripted ship and
# taxi in videos/, the ship's verification against the continuous ODE, and the
# environment benchmark.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/hpg-mj demo --out videos "$@"
