"""Issue 12, item 3: the stand-alone diagonal and straight subtasks, the paper's
policy (sigma = 1) against the learned exploration width, over held-out seeds.

  .venv/bin/python scripts/subtask_width.py [--seeds 100-119] [--episodes 15000]

Prints, per subtask and policy, the online success rate per 1,000 calls (the
paper's Figures 10 and 11) and the final greedy success rate over 1,000 fixed
starts, each the mean over seeds with a 95% bootstrap band (scipy.stats.bootstrap,
SPEC section 7). The width's step size and clip were chosen on seed 0 only.
"""
import argparse
import json

import numpy as np
from scipy import stats

from hpg_mj.agents import ship_subtask

VARIANTS = {"paper (sigma = 1)": {},
            "learned width": {"width_alpha": 0.003, "sigma_low": 0.25, "sigma_high": 1.0}}


def band(values):
  values = np.asarray(values, dtype=np.float64)
  if np.ptp(values) == 0:
    return float(values.mean()), float(values[0]), float(values[0])
  ci = stats.bootstrap((values,), np.mean, confidence_level=0.95, n_resamples=2000,
                       random_state=0).confidence_interval
  return float(values.mean()), float(ci.low), float(ci.high)


def main():
  p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  p.add_argument("--seeds", default="100-119", help="first-last (inclusive)")
  p.add_argument("--episodes", type=int, default=15000)
  p.add_argument("--json", help="also write the curves here")
  p.add_argument("--plot", help="also draw the curves with their bands here (.png; a .csv "
                 "beside it)")
  args = p.parse_args()
  first, last = (int(v) for v in args.seeds.split("-"))
  seeds = range(first, last + 1)
  out = {}
  for task in ship_subtask.TASKS:
    for name, options in VARIANTS.items():
      curves, greedy = [], []
      for seed in seeds:
        run = ship_subtask.train_subtask(task, args.episodes, seed, greedy_every=args.episodes,
                                         greedy_episodes=1000, **options)
        curves.append(run["success"].reshape(-1, 1000).mean(axis=1))
        greedy.append(run["greedy"][-1])
      curves = np.array(curves)
      rows = [band(curves[:, k]) for k in range(curves.shape[1])]
      g = band(greedy)
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
    plot(out, args.plot, len(seeds))


def plot(out, path, n_seeds):
  import pathlib

  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True)
  lines = ["subtask,policy,calls,mean,ci_low,ci_high"]
  for ax, task in zip(axes, ship_subtask.TASKS):
    for name in VARIANTS:
      rows = np.array(out[f"{task}/{name}"]["online"])
      calls = 1000 * np.arange(1, len(rows) + 1)
      ax.plot(calls, rows[:, 0], label=name)
      ax.fill_between(calls, rows[:, 1], rows[:, 2], alpha=0.25)
      lines += [f"{task},{name},{c},{m:.4f},{lo:.4f},{hi:.4f}" for c, (m, lo, hi) in
                zip(calls, rows)]
    ax.set_title(f"ship/{task} ({n_seeds} seeds, 95% CI)")
    ax.set_xlabel("calls")
    ax.grid(alpha=0.3)
  axes[0].set_ylabel("successes per 1,000 calls (online)")
  axes[0].legend()
  fig.tight_layout()
  fig.savefig(path, dpi=110)
  pathlib.Path(path).with_suffix(".csv").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
  main()
