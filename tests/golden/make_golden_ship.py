"""Regenerates tests/golden/ship_*.npz (run by hand after a deliberate change of the
physics or rules: `PYTHONPATH=. python tests/golden/make_golden_ship.py`).

Each file holds a short trajectory of one ship task under a fixed seed and a
fixed action sequence: on the analytic ship through Gymnasium, and on the
MuJoCo ship through the dm_control suite. tests/test_golden.py replays them.
"""
import pathlib

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
SEED = 123
STEPS = 80


def actions():
  return np.random.default_rng(7).uniform(-15.0, 15.0, (STEPS, 1))


def analytic_rollout(task):
  import gymnasium

  import hpg_mj  # noqa: F401
  ids = {"steer": "hpg_mj/ShipSteering-v0", "diagonal": "hpg_mj/ShipSteeringDiagonal-v0",
         "straight": "hpg_mj/ShipSteeringStraight-v0"}
  env = gymnasium.make(ids[task], backend="analytic").unwrapped
  obs, _ = env.reset(seed=SEED)
  rows, rewards, ends = [obs], [], []
  for a in actions():
    obs, reward, terminated, truncated, _ = env.step(a)
    rewards.append(reward)
    ends.append(2 * terminated + truncated)
    if terminated or truncated:
      obs, _ = env.reset()
    rows.append(obs)
  return np.array(rows), np.array(rewards), np.array(ends)


def mujoco_rollout(task):
  from hpg_mj import suite
  env = suite.load("ship", task, {"random": SEED})
  flat = lambda ts: np.concatenate([np.ravel(v) for v in ts.observation.values()])  # noqa: E731
  ts = env.reset()
  rows, rewards, ends = [flat(ts)], [], []
  for a in actions():
    ts = env.step(a)
    rewards.append(ts.reward)
    ends.append(0 if not ts.last() else (2 if ts.discount == 0.0 else 1))
    if ts.last():
      ts = env.reset()
    rows.append(flat(ts))
  return np.array(rows), np.array(rewards), np.array(ends)


def main():
  for task in ("steer", "diagonal", "straight"):
    a_obs, a_rew, a_end = analytic_rollout(task)
    m_obs, m_rew, m_end = mujoco_rollout(task)
    np.savez(HERE / f"ship_{task}.npz", actions=actions(), analytic_obs=a_obs,
             analytic_rewards=a_rew, analytic_ends=a_end, mujoco_obs=m_obs,
             mujoco_rewards=m_rew, mujoco_ends=m_end)
    print(task, "analytic ends", int((a_end > 0).sum()), "mujoco ends", int((m_end > 0).sum()))


if __name__ == "__main__":
  main()
