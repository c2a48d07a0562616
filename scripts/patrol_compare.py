"""The continuing ship task's comparison from `scripts/patrol_seeds.py`'s JSON lines:
per seed and as means with 95% bootstrap intervals, greedy gate passes an hour
of the average-reward root, the episodic hybrid sailed on the same task and the
figure-eight helmsman; the paired difference root minus hybrid; the seeds below
the helmsman. Prints Markdown. The intervals are `hpg-mj reproduce beyond`'s (percentile bootstrap,
`hpg_mj.experiments.stats.mean_ci`).

  .venv/bin/python scripts/patrol_seeds.py 10001-10020 > fresh.jsonl
  .venv/bin/python scripts/patrol_compare.py fresh.jsonl
  .venv/bin/python scripts/patrol_compare.py --report fresh.jsonl   # REPORT.md's section

With --report, the continuing task's section of figures/beyond/REPORT.md as
`hpg-mj reproduce beyond` writes it (`hpg_mj.experiments.beyond`), from these lines.
"""
import json
import sys

import numpy as np

from hpg_mj import agents
from hpg_mj.experiments import beyond
from hpg_mj.experiments import stats


def band(values):
  """mean [95% interval] by the report's rule (`hpg_mj.experiments.stats.mean_ci`)."""
  mean, low, high = stats.mean_ci(values)
  sign = "+" if min(values) < 0 else ""
  return f"{mean:{sign}.1f} [{low:{sign}.1f}, {high:{sign}.1f}]"


def main(paths):
  rows = [json.loads(line) for path in paths for line in open(path) if line.startswith("{")]
  if not rows:
    raise SystemExit(f"no JSON lines in {paths}")
  rows.sort(key=lambda r: r["seed"])
  seeds = [r["seed"] for r in rows]
  root = np.array([r["greedy_gates_per_hour"] for r in rows])
  hybrid = np.array([r["episodic_gates_per_hour"] for r in rows])
  helmsman = np.array([r["scripted_gates_per_hour"] for r in rows])
  online = np.array([r["online_gates_per_hour"] for r in rows])
  diff = root - hybrid
  print(f"Seeds {seeds[0]}-{seeds[-1]} ({len(seeds)} runs), greedy gate passes an hour over "
        f"100 hours, mean [95% bootstrap CI]\n")
  print("| policy | mean | per seed |\n|---|---|---|")
  for name, values in (("average-reward root, greedy", root),
                       ("average-reward root, online (last 125 h, exploring)", online),
                       ("episodic hybrid, greedy on the continuing task", hybrid),
                       ("figure-eight helmsman", helmsman),
                       ("paired: root minus episodic hybrid", diff)):
    print(f"| {name} | {band(values)} | {', '.join(f'{v:.1f}' for v in values)} |")
  print(f"\nRoot ahead on {(diff > 0).sum()} of {len(diff)} seeds; below the helmsman: root "
        f"{(root < helmsman).sum()} (min {root.min():.1f}), episodic hybrid "
        f"{(hybrid < helmsman).sum()} (min {hybrid.min():.1f}).")


def report(paths):
  rows = sorted((json.loads(line) for path in paths for line in open(path)
                 if line.startswith("{")), key=lambda r: r["seed"])
  task = agents.load_task(beyond.TASK)
  print("\n".join(beyond._report(task, [r["seed"] for r in rows], task.protocol.episodes,
                                  rows, False)))


if __name__ == "__main__":
  if sys.argv[1:2] == ["--report"]:
    report(sys.argv[2:])
  else:
    main(sys.argv[1:])
