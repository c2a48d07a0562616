"""The task ladder's fixed starts (SPEC sections 7 and 11): start i of every report is
the episode the Gymnasium environment lays out at `reset(seed=seed + i)`, the ship's
state (the harbour's and the goal's drawn again while it lies on an obstacle), then the
goal's gate (drawn again until it stands clear of them) or the regatta's course, from one
generator. One rule, read by the scorer
(`hpg_mj.benchmark`) and by the agents that act on the ladder, so that both sail from
the same starts."""
import numpy as np

from hpg_mj.worlds import ship_current_core
from hpg_mj.worlds import ship_goal_core
from hpg_mj.worlds import ship_harbour_core
from hpg_mj.worlds import ship_regatta_core
from hpg_mj.worlds import ship_task

TASKS = ("ship_current", "ship_goal", "ship_regatta", "ship_harbour")   # SPEC section 11
LEVELS = ("easy", "medium", "hard")
# Each task's Gymnasium id (`gymnasium.make(ENV_IDS[task], level=...)`; the JAX
# environments, where a task has one, are registered under the same id).
ENV_IDS = {task: f"hpg_mj/{name}-v0" for task, name in zip(
    TASKS, ("ShipCurrent", "ShipGoal", "ShipRegatta", "ShipHarbour"))}

_CORES = dict(zip(TASKS, (ship_current_core, ship_goal_core, ship_regatta_core,
                          ship_harbour_core)))


def episode_steps(task, level, max_steps=None):
  """The control steps an episode of ladder task `task` at `level` runs at most:
  `max_steps` (None: `ship_core.STEER_MAX_STEPS`), or the level's time limit where that
  is shorter (each task's `TIME_LIMITS`: the goal's, the current's and the regatta's
  hard levels close; a larger `max_steps` does not reopen them)."""
  if task not in _CORES:
    raise ValueError(f"unknown ladder task {task!r}; allowed: {list(TASKS)}")
  return _CORES[task].episode_steps(level, max_steps)


def fixed_starts(task, level, episodes, seed):
  """The fixed starts of ladder task `task` ("ship_current", "ship_goal", "ship_regatta",
  "ship_harbour") at `level`: a dictionary of arrays, the reset options that set them:
  "state" (n, 4), and "gate" (n, 3) rows [x, y, heading_deg] or "course" (n, gates, 3)."""
  from gymnasium.utils import seeding
  rules = ship_task.ShipRules("steer")
  states, extra = np.zeros((int(episodes), 4)), []
  for i in range(int(episodes)):
    generator, _ = seeding.np_random(int(seed) + i)    # as gymnasium.Env.reset does
    if task == "ship_harbour":                          # drawn again on an obstacle
      states[i] = ship_harbour_core.sample_start(
          rules, generator, *ship_harbour_core.level_shapes(level))
    elif task == "ship_goal":                           # the same, among the goal's obstacles
      states[i] = ship_goal_core.sample_start(rules, generator, level)
    else:
      states[i] = rules.sample_start(generator)
    if task == "ship_goal":                             # drawn again until clear of them
      extra.append(ship_goal_core.draw_gate(generator, level))
    elif task == "ship_regatta":
      extra.append(ship_regatta_core.sample_course(
          generator, ship_regatta_core.level_layout(level)))
  if task == "ship_goal":
    return {"state": states, "gate": np.array(extra, dtype=np.float64).reshape(-1, 3)}
  if task == "ship_regatta":
    gates = ship_regatta_core.level_layout(level)[0]
    return {"state": states, "course": np.array(extra, dtype=np.float64).reshape(-1, gates, 3)}
  return {"state": states}
