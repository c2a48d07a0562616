"""The pictures of the ladder's task pages (docs/tasks/, docs/_ext/task_pages.py):

  .venv/bin/python scripts/task_pictures.py          # writes figures/tasks/*.png
  .venv/bin/python scripts/task_pictures.py ship_goal_hard      # only that one

ship_current_<level>.png: the still-water helmsman (`ship_core.pilot_turn_rate` to the
gate's middle, which knows nothing of the water) from one fixed start in each level's
current, drawn by the Gymnasium environment's own `render()` with its wake: where the
wake bends, the water carried the ship.

ship_goal_<level>.png: a gate of each level (drawn with seed 4) where the episode put it,
and the scripted helmsman's wake to and through it (`ship_goal_core.pilot_target`); at
hard, among the obstacles the helmsman does not see, the best known episode's wake
(`planners.plan`'s turning rates, replayed).

ship_regatta_<level>.png: a course of each level (laid out with seed 4) and the scripted
helmsman's wake round it (`ship_regatta_core.pilot_target`), drawn when half its gates
are passed: those grey, the next yellow, the rest white.

ship_harbour_<level>.png: each level's obstacles (islands and piers) and the scripted
helmsman's wake round them from one fixed start in the north-west
(`planners_harbour.helmsman`, down the level's distance field to the gate).
"""
import pathlib
import sys

import gymnasium
import imageio.v2 as imageio
import numpy as np

import hpg_mj  # noqa: F401  (registers the ids)
from hpg_mj import planners
from hpg_mj import planners_harbour
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_goal_core as goal_core
from hpg_mj.worlds import ship_regatta_core as regatta_core

OUT = pathlib.Path(__file__).resolve().parents[1] / "figures" / "tasks"
START = [150.0, 850.0, 90.0, 0.0]      # the north-west, heading east
STEPS = 500
HARBOUR_START = [120.0, 920.0, 90.0, 0.0]     # the north-west corner, heading east


def current_picture(level):
  env = gymnasium.make("hpg_mj/ShipCurrent-v0", level=level, backend="analytic",
                       render_mode="rgb_array", width=480, height=360)
  obs, _ = env.reset(options={"state": START})
  mid = core.GATE.mean(axis=0)
  for _ in range(STEPS):
    r = core.pilot_turn_rate(np.ascontiguousarray(obs[:4]), mid[0], mid[1])
    obs, _, terminated, truncated, _ = env.step(np.array([r]))
    if terminated or truncated:
      break
  frame = env.render()
  env.close()
  return frame


def goal_picture(level, seed=4):
  """The episode's gate (seeded) and the scripted helmsman's way to and through it."""
  env = gymnasium.make("hpg_mj/ShipGoal-v0", level=level, backend="analytic",
                       render_mode="rgb_array", width=480, height=360)
  obs, _ = env.reset(seed=seed)
  rates = None
  if goal_core.OBSTACLES[level] is not None:
    desired = obs["desired_goal"]
    gate = [desired[0], desired[1], goal_core.gate_heading_deg(desired)]
    _, _, rates = planners.plan("ship_goal", level, {"state": obs["observation"][None],
                                                     "gate": np.array([gate])}, actions=True)
  phase = 0
  for t in range(STEPS * 4):
    if rates is None:
      tx, ty, phase = goal_core.pilot_target(obs["observation"], phase, obs["desired_goal"])
      r = core.pilot_turn_rate(obs["observation"], tx, ty)
    else:
      r = rates[0, t]
    obs, _, terminated, truncated, _ = env.step(np.array([r]))
    if terminated or truncated:
      break
  frame = env.render()
  env.close()
  return frame


def regatta_picture(level, seed=4):
  """The episode's course (seeded) and the scripted helmsman's way round its first half."""
  env = gymnasium.make("hpg_mj/ShipRegatta-v0", level=level, backend="analytic",
                       render_mode="rgb_array", width=480, height=360)
  obs, info = env.reset(seed=seed)
  gates, spacing, _, _ = regatta_core.LEVELS[level]
  phase, passed = 0, 0
  while passed < (gates + 1) // 2:
    tx, ty, phase = regatta_core.pilot_target(obs[:4], phase, info["course"], passed,
                                              0.5 * spacing)
    obs, _, terminated, truncated, step_info = env.step(
        np.array([core.pilot_turn_rate(obs[:4], tx, ty)]))
    if step_info["gates_passed"] > passed:
      passed, phase = step_info["gates_passed"], 0
    if terminated or truncated:
      break
  frame = env.render()
  env.close()
  return frame


def harbour_picture(level):
  """The level's obstacles and the scripted helmsman's way round them to the gate."""
  env = gymnasium.make("hpg_mj/ShipHarbour-v0", level=level, backend="analytic",
                       render_mode="rgb_array", width=480, height=360)
  obs, _ = env.reset(options={"state": HARBOUR_START})
  for _ in range(STEPS * 4):
    obs, _, terminated, truncated, _ = env.step(planners_harbour.helmsman(level, obs))
    if terminated or truncated:
      break
  frame = env.render()
  env.close()
  return frame


def main():
  OUT.mkdir(parents=True, exist_ok=True)
  only = set(sys.argv[1:])        # names such as ship_goal_hard: only those pictures
  for level in ("easy", "medium", "hard"):
    for name, picture in (("ship_current", current_picture), ("ship_goal", goal_picture),
                          ("ship_regatta", regatta_picture),
                          ("ship_harbour", harbour_picture)):
      if only and f"{name}_{level}" not in only:
        continue
      imageio.imwrite(OUT / f"{name}_{level}.png", picture(level))
      print(OUT / f"{name}_{level}.png")


if __name__ == "__main__":
  main()
