"""Issue 12, item 3: the stand-alone diagonal and straight subtasks, the paper's
policy (sigma = 1) against the learned exploration width, over held-out seeds.

  .venv/bin/python scripts/subtask_width.py [--seeds 100-119] [--episodes 15000]

Prints, per subtask and policy, the online success rate per 1,000 calls (the
paper's Figures 10 and 11) and the final greedy success rate over 1,000 fixed
starts, each the mean over seeds with a 95% bootstrap band (scipy.stats.bootstrap,
SPEC section 7). The width's step size and clip were chosen on seed 0 only.
`hpg-mj reproduce beyond` runs the same measurement (hpg_mj.experiments.beyond)
on its seeds and draws it into its report.
"""
import argparse
import json
import pathlib

import numpy as np

from hpg_mj.hierarchy import ship_subtask
from hpg_mj.experiments import beyond
from hpg_mj.experiments import stats


def main():
  p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  p.add_argument("--seeds", default="100-119", help="first-last (inclusive)")
  p.add_argument("--episodes", type=int, default=15000)
  p.add_argument("--json", help="also write the curves here")
  p.add_argument("--plot", help="also draw the curves with their bands here (.png)")
  args = p.parse_args()
  first, last = (int(v) for v in args.seeds.split("-"))
  seeds = range(first, last + 1)
  out, curves = {}, {}
  for task in ship_subtask.TASKS:
    for name, options in beyond.WIDTH_VARIANTS.items():
      runs = [beyond.subtask_seed(task, seed, args.episodes, options) for seed in seeds]
      mean, low, high = stats.band(np.array([r[0] for r in runs]))
      curves[task, name] = (mean, low, high)
      rows = np.column_stack([mean, low, high]).tolist()
      g = stats.mean_ci([r[1] for r in runs])
      out[f"{task}/{name}"] = {"online": rows, "greedy": g}
      print(f"{task:8s} {name:18s} online per 1,000 calls (mean [95% CI]):")
      for k in range(0, len(rows), max(1, len(rows) // 5)):
        m, lo, hi = rows[k]
        print(f"    calls {1000 * (k + 1):6d}: {m:.3f} [{lo:.3f}, {hi:.3f}]")
      m, lo, hi = rows[-1]
      print(f"    final online    : {m:.3f} [{lo:.3f}, {hi:.3f}]")
      print(f"    final greedy    : {g[0]:.3f} [{g[1]:.3f}, {g[2]:.3f}]  ({len(seeds)} seeds)")
  if args.json:
    with open(args.json, "w") as f:
      json.dump(out, f, indent=1)
  if args.plot:
    path = pathlib.Path(args.plot)
    beyond.draw_subtasks(path.parent, curves, len(seeds), path.name)


if __name__ == "__main__":
  main()
