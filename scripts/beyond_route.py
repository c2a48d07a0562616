"""Issue 12, item 4: the route past the paper's (tasks/ship_hybrid_beyond.toml),
trained on held-out seeds and evaluated greedily on one fixed set of 1,000 starts.

  .venv/bin/python scripts/beyond_route.py [--seeds 100-109] [--episodes N]

Prints per seed and as mean with a 95% bootstrap band (SPEC section 7): gate
passes, control steps to the gate (over the passes), J (gamma 0.99, MushroomRL's
rewards), calls per episode. The task file was tuned on seed 0 only.
"""
import argparse

import numpy as np
from scipy import stats

from hpg_mj import agents
from hpg_mj.agents import ship_beyond


def starts(n=1000, seed=2026):
  """The fixed evaluation starts: uniform over the field, heading and turning rate."""
  rs = np.random.default_rng(seed)
  return np.column_stack([rs.uniform(0, 1000, n), rs.uniform(0, 1000, n),
                          rs.uniform(-180, 180, n), rs.uniform(-15, 15, n)])


def band(values):
  values = np.asarray(values, dtype=np.float64)
  ci = stats.bootstrap((values,), np.mean, confidence_level=0.95, n_resamples=2000,
                       random_state=0).confidence_interval
  return f"{values.mean():.3f} [{ci.low:.3f}, {ci.high:.3f}]"


def main():
  p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  p.add_argument("--seeds", default="100-109")
  p.add_argument("--episodes", type=int, default=None)
  p.add_argument("--task", default="ship_hybrid_beyond")
  args = p.parse_args()
  first, last = (int(v) for v in args.seeds.split("-"))
  task = agents.load_task(args.task)
  fixed = starts()
  rows = []
  for seed in range(first, last + 1):
    agent, _, seconds = agents.train(task, episodes=args.episodes, seed=seed)
    record = agent.as_record(np.concatenate(
        [agent.compiled(1, False, False, start=s) for s in fixed]))
    ok = record["passed"] > 0
    j = ship_beyond.discounted_return(record).mean()
    rows.append((ok.mean(), record["steps"][ok].mean(), j, record["calls"].mean()))
    print(f"seed {seed}: gate {ok.mean():.3f}  steps {rows[-1][1]:.1f}  J {j:.2f}  "
          f"calls {rows[-1][3]:.2f}  ({seconds:.0f} s)", flush=True)
  rows = np.array(rows)
  for k, name in enumerate(("gate passes", "steps to gate", "J", "calls")):
    print(f"{name:14s} {band(rows[:, k])}")


if __name__ == "__main__":
  main()
