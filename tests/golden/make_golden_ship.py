"""Regenerates golden/ship_*.npz (run by hand after a deliberate change of the
physics or rules, from the checkout: `.venv/bin/python tests/golden/make_golden_ship.py`
with hpg_mj installed; name tasks, e.g. `patrol` or `current_hard`, to write only theirs).

Each file holds a short trajectory of one ship task under a fixed seed and a
fixed action sequence: on the analytic ship through Gymnasium, and on the
MuJoCo ship through the dm_control suite (`hpg_mj.verify`'s rollouts, the same
that `hpg-mj verify golden` and tests/test_golden_ship.py replay).
"""
import pathlib

import numpy as np

from hpg_mj import verify

HERE = pathlib.Path(__file__).resolve().parents[2] / "golden"


TASKS = ("steer", "diagonal", "straight", "patrol", "current_easy", "current_medium",
         "current_hard", "goal_easy", "goal_medium", "goal_hard", "regatta_easy",
         "regatta_medium", "regatta_hard", "harbour_easy", "harbour_medium", "harbour_hard")


def main(tasks=TASKS):
  for name in tasks:
    # "current_hard": the ship_current domain's task "hard" (file ship_current_hard.npz).
    domain, task = ("ship_" + name.split("_")[0], name.split("_")[1]) if "_" in name \
        else ("ship", name)
    actions = verify.ship_golden_actions(task)
    a_obs, a_rew, a_end = verify.ship_analytic_rollout(task, actions, domain)
    m_obs, m_rew, m_end = verify.ship_mujoco_rollout(task, actions, domain)
    np.savez(HERE / f"{domain}_{task}.npz", actions=actions, analytic_obs=a_obs,
             analytic_rewards=a_rew, analytic_ends=a_end, mujoco_obs=m_obs,
             mujoco_rewards=m_rew, mujoco_ends=m_end)
    print(task, "analytic ends", int((a_end > 0).sum()), "mujoco ends", int((m_end > 0).sum()))


if __name__ == "__main__":
  import sys
  main(tuple(sys.argv[1:])) if sys.argv[1:] else main()
