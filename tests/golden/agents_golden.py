"""Golden records of every shipped agent: what a fixed schedule of training and
evaluation gives, on both training paths, stored under tests/golden/agents/.

A schedule per task file (seed 3): train on the compiled path; train on, step by
step, through the Gymnasium environment (and, for the taxi, the dm_control
board); then evaluate greedily on both paths. Stored per step: every record
column by name; at the end: the SHA-256 of every array of the agent's state.
Regenerate (only when a change is meant to change the numbers):

  .venv/bin/python tests/golden/agents_golden.py
"""
import hashlib
import pathlib

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent / "agents"
SEED = 3

# task file -> (compiled episodes, step-by-step episodes, dm_control episodes, greedy episodes)
SCHEDULES = {
    "ship_hybrid": (1500, 12, 0, 20),
    "ship_flat_pg": (400, 3, 0, 5),
    "ship_actor_critic": (300, 3, 0, 5),
    "taxi_fuel_hpg": (3000, 150, 20, 200),
    "taxi_fuel_maxq": (3000, 150, 20, 200),
    "taxi_fuel_flat_q": (3000, 150, 20, 200),
}


def produce(name):
  """The golden arrays of one task file, computed by the installed hpg_mj."""
  from hpg_mj import agents
  compiled, stepwise, dm, greedy = SCHEDULES[name]
  agent = agents.build(agents.load_task(name), seed=SEED)
  out = {}

  def keep(tag, record):
    for field in record.dtype.names:
      out[f"{tag}.{field}"] = np.asarray(record[field], dtype=np.float64)

  keep("compiled", agent.train(compiled, backend="analytic"))
  keep("stepwise", agent.train_stepwise(agent.make_env("gymnasium"), stepwise))
  if dm:
    keep("dm_control", agent.train_stepwise(agent.make_env("dm_control"), dm))
  keep("greedy_compiled", agent.evaluate(greedy, backend="analytic", policy="greedy"))
  keep("greedy_stepwise", agent.run_stepwise(agent.make_env("gymnasium"), greedy // 4,
                                             learn=False))
  for key, value in agent.state().items():
    out[f"state.{key}"] = np.frombuffer(hashlib.sha256(
        np.ascontiguousarray(value).tobytes()).digest(), dtype=np.uint8)
  return out


if __name__ == "__main__":
  HERE.mkdir(exist_ok=True)
  for name in SCHEDULES:
    np.savez_compressed(HERE / f"{name}.npz", **produce(name))
    print("wrote", HERE / f"{name}.npz")
