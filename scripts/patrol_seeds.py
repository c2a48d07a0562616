"""The continuing ship task's final comparison on any seeds (SPEC section 8), as
`hpg-mj reproduce beyond` measures it after training, without its per-block
greedy probes (they sail from their own generator and change nothing): for each
seed, tasks/ship_patrol_average_reward.toml's agent trains on its protocol, then
`ShipPatrol.final_metrics` (greedy gates per hour of it, of the episodic hybrid
trained on its own protocol with that seed, and of the scripted helmsman).

  .venv/bin/python scripts/patrol_seeds.py 105-109      # one JSON line per seed
"""
import json
import sys
import time

from hpg_mj import agents


def seeds_of(text):
  low, _, high = text.partition("-")
  return range(int(low), int(high or low) + 1)


def main(argv):
  task = agents.load_task("ship_patrol_average_reward")
  if any(seed in task.tuning_seeds for arg in argv for seed in seeds_of(arg)):
    raise SystemExit(f"refused: {argv} include tuning seeds {list(task.tuning_seeds)}")
  for arg in argv:
    for seed in seeds_of(arg):
      start = time.perf_counter()
      agent = agents.build(task, seed=seed)
      record = agent.train(task.protocol.episodes)
      final = agent.final_metrics(record)
      final.update(seed=seed, online_gates_per_hour=agent.metrics(record[-125:])["gates_per_hour"],
                   wall_seconds=round(time.perf_counter() - start, 1))
      print(json.dumps(final), flush=True)


if __name__ == "__main__":
  main(sys.argv[1:] or ["105-109"])
