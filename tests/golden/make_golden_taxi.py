"""Writes the taxi golden trajectories (golden/taxi_*.npz) that `hpg-mj verify
golden` and tests/envs/test_taxi_env.py replay.

Each file holds one fixed action sequence (drawn once, stored in the file) and
what the dm_control task answered (`hpg_mj.verify.taxi_trajectory`):
observations, rewards, discounts and step types, across episode ends.
Regenerate only when a rule changes on purpose (docs/SPEC.md section 5), and say
so in the change, from the checkout with hpg_mj installed:

    MUJOCO_GL=osmesa .venv/bin/python tests/golden/make_golden_taxi.py

The tests never run this script.
"""
import pathlib

import numpy as np

from hpg_mj import verify

HERE = pathlib.Path(__file__).resolve().parents[2] / "golden"
STEPS = 60
TASK_SEED = 2024     # the task's `random`
ACTION_SEED = 7      # draws the action sequence, once


def main():
  for task_name, n_actions in (("fuel", 7), ("classic", 6)):
    actions = np.random.RandomState(ACTION_SEED).randint(0, n_actions, STEPS).astype(np.int64)
    record = verify.taxi_trajectory(task_name, actions, TASK_SEED)
    path = HERE / f"taxi_{task_name}.npz"
    np.savez(path, actions=actions, seed=TASK_SEED, **record)
    ends = int((record["step_type"] == 2).sum())
    print(f"wrote {path}: {STEPS} actions, {ends} episode end(s), "
          f"return {np.nansum(record['reward']):.0f}")


if __name__ == "__main__":
  main()
