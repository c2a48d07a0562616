"""Writes the taxi golden trajectories that tests/envs/test_taxi_env.py replays.

Each file holds one fixed action sequence (drawn once, stored in the file) and
what the dm_control task answered: observations, rewards, discounts and step
types, across episode ends (dm_control resets on the step after LAST, ignoring
that step's action). Regenerate only when a rule changes on purpose (SPEC
section 5), and say so in the change:

    cd /work/main && MUJOCO_GL=osmesa PYTHONPATH=. .venv/bin/python tests/golden/make_golden_taxi.py

The tests never run this script.
"""
import pathlib

import numpy as np

from hpg_mj.worlds import taxi

HERE = pathlib.Path(__file__).resolve().parent
STEPS = 60
TASK_SEED = 2024     # the task's `random`
ACTION_SEED = 7      # draws the action sequence, once


def trajectory(task_name, actions, seed):
  env = getattr(taxi, task_name)(random=seed)
  time_steps = [env.reset()]
  for action in actions:
    time_steps.append(env.step(action))
  keys = list(time_steps[0].observation)
  record = {f"obs_{k}": np.stack([ts.observation[k] for ts in time_steps]) for k in keys}
  record["reward"] = np.array([np.nan if ts.reward is None else ts.reward for ts in time_steps])
  record["discount"] = np.array([np.nan if ts.discount is None else ts.discount
                                 for ts in time_steps])
  record["step_type"] = np.array([int(ts.step_type) for ts in time_steps], dtype=np.int64)
  return record


def main():
  for task_name, n_actions in (("fuel", 7), ("classic", 6)):
    actions = np.random.RandomState(ACTION_SEED).randint(0, n_actions, STEPS).astype(np.int64)
    record = trajectory(task_name, actions, TASK_SEED)
    path = HERE / f"taxi_{task_name}.npz"
    np.savez(path, actions=actions, seed=TASK_SEED, **record)
    ends = int((record["step_type"] == 2).sum())
    print(f"wrote {path}: {STEPS} actions, {ends} episode end(s), "
          f"return {np.nansum(record['reward']):.0f}")


if __name__ == "__main__":
  main()
