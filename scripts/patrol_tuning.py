"""Tuning measurements of the continuing ship task's average-reward root (issue 12),
on its task file's tuning seeds only: for each seed, the agent trains on its
protocol with `[root]` keys replaced by the JSON object given, then sails 100
greedy hours (`ShipPatrol.evaluation`); the episodic hybrid is not trained (its
numbers do not depend on the root's keys). Held-out seeds are refused: those are
`scripts/patrol_seeds.py`'s.

  .venv/bin/python scripts/patrol_tuning.py 0-9 '{"epsilon_every": 4000}'
"""
import dataclasses
import json
import sys
import time

from hpg_mj import agents


def main(argv):
  task = agents.load_task("ship_patrol_average_reward")
  low, _, high = argv[0].partition("-")
  seeds = range(int(low), int(high or low) + 1)
  held_out = [seed for seed in seeds if seed not in task.tuning_seeds]
  if held_out:
    raise SystemExit(f"refused: seeds {held_out} are not tuning seeds {list(task.tuning_seeds)}")
  root = json.loads(argv[1]) if len(argv) > 1 else {}
  config = dataclasses.replace(task.config, root=dataclasses.replace(task.config.root, **root))
  for seed in seeds:
    start = time.perf_counter()
    agent = agents.lookup(task.kind)(config, seed=seed, task=task)
    record = agent.train(task.protocol.episodes)
    print(json.dumps({
        "seed": seed, **root,
        "greedy_gates_per_hour": agent.metrics(agent.evaluation(100))["gates_per_hour"],
        "online_gates_per_hour": agent.metrics(record[-125:])["gates_per_hour"],
        "wall_seconds": round(time.perf_counter() - start, 1)}), flush=True)


if __name__ == "__main__":
  main(sys.argv[1:] or ["0-9"])
