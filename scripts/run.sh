#!/usr/bin/env bash
# Sets up (scripts/setup.sh) and runs the main job: a quick reproduction of the
# paper's Figures 6-12 (runs/fig6_quick, runs/fig7_11_quick, runs/fig12_quick, runs/REPORT.md: PNGs, CSVs,
# the learned hybrid's MP4s on the MuJoCo ship), then videos of the scripted ship
# and taxi in runs/videos, the ship's verification against the continuous ODE, and
# the environment benchmark. Everything it writes is under runs/, which git ignores:
# the showcase videos in videos/ are remade only on purpose (hpg-mj demo --out videos).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/hpg-mj reproduce all --quick --out runs --quiet
exec .venv/bin/hpg-mj demo --out runs/videos "$@"
