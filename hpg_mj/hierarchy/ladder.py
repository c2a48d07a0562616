"""The task ladder's worlds (SPEC section 11) as the open machine fuses them
(`hierarchy.algorithm.run_world`): each world's pure functions over a state and its
parameters (`env_reset`, `env_step`, `env_end` of `worlds.ship_<task>_core`), and here the
episode's start drawn from the run's generator (`learners.rng`, which the worlds do not
know: the layers).

A start is one float64 row: the ship's [x, y, theta_deg, theta_dot_deg], then the task's
layout: the goal's gate [x, y, heading_deg], the regatta's course (its gates' rows [x, y,
heading_deg] one after another); the current's and the harbour's nothing more (the
harbour's obstacles are the level's). `World.options(start)` is the same start as the
Gymnasium environment's reset options, so that the step-by-step path starts the
environment where the fused loop starts its world; `draw` is the one rule by which both
paths draw it from the agent's generator.

  world(task, level, ...)     a `World`: the task's parameters, its compiled functions
                              (bound into a graph's program by `Program(fused=...)`),
                              its observation's length
"""
import dataclasses
import math

import numba
import numpy as np

from hpg_mj.hierarchy import ship_rules
from hpg_mj.learners import rng
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_current_core as current_core
from hpg_mj.worlds import ship_goal_core as goal_core
from hpg_mj.worlds import ship_harbour_core as harbour_core
from hpg_mj.worlds import ship_ladder
from hpg_mj.worlds import ship_regatta_core as regatta_core

TASKS, LEVELS = ship_ladder.TASKS, ship_ladder.LEVELS         # SPEC section 11
_START_TRIES = 10_000       # the harbour's draws of a start off the obstacles


# ---- the starts, drawn from the run's generator ------------------------------------

@numba.njit(cache=True, error_model="numpy")
def draw_current(params, state, rng_state, start):
  """The current's start: the steering task's (`ship_rules.sample_start`)."""
  ship_rules.sample_start(rng_state, start)


@numba.njit(cache=True, error_model="numpy")
def draw_harbour(params, state, rng_state, start):
  """The harbour's start: the harbour's rule (`ship_harbour_core.start_of`: the steering
  task's uniform start) from four uniforms, drawn again while it lies on an obstacle."""
  draws = state.draws
  for _ in range(_START_TRIES):
    for i in range(4):
      draws[i] = rng.uniform(rng_state)
    if harbour_core.start_of(draws, core.FIELD_SIZE, params.islands, params.piers, start):
      return
  start[0] = -1.0            # refused by env_reset's caller (`World.draw`)


@numba.njit(cache=True, error_model="numpy")
def draw_goal(params, state, rng_state, start):
  """The goal's start: the steering task's (among obstacles, the harbour's rule:
  `draw_harbour`), then the gate's centre x, y and heading uniform on the level's ranges
  (`ship_goal_core.LEVELS`), drawn again until it stands clear of the obstacles
  (`ship_goal_core.gate_clear`: the first, in open water)."""
  if params.islands.shape[0] + params.piers.shape[0] == 0:
    ship_rules.sample_start(rng_state, start)
  else:
    draw_harbour(params, state, rng_state, start)
    if start[0] < 0.0:
      return
  low, high, largest = params.level[0], params.level[1], params.level[2]
  for _ in range(_START_TRIES):
    start[4] = rng.uniform_range(rng_state, low, high)
    start[5] = rng.uniform_range(rng_state, low, high)
    start[6] = rng.uniform_range(rng_state, -largest, largest)
    heading = math.radians(start[6])
    if goal_core.gate_clear(start[4], start[5], math.sin(heading), math.cos(heading),
                            params.islands, params.piers):
      return
  start[0] = -1.0            # refused by env_reset's caller (`World.draw`)


@numba.njit(cache=True, error_model="numpy")
def draw_regatta(params, state, rng_state, start):
  """The regatta's start: the steering task's, then a course laid by the regatta's rule
  (`ship_regatta_core.lay_course`) from uniforms, drawn afresh for each try."""
  ship_rules.sample_start(rng_state, start)
  layout = params.layout
  course, draws = state.course, state.draws
  while True:
    for i in range(draws.shape[0]):
      draws[i] = rng.uniform(rng_state)
    if regatta_core.lay_course(draws, layout[1], layout[2], layout[3], course):
      break
  for k in range(course.shape[0]):
    for j in range(3):
      start[4 + 3 * k + j] = course[k, j]


# ---- the worlds ---------------------------------------------------------------------

@dataclasses.dataclass(frozen=True, eq=False)
class World:
  """One ladder task at one level as the machine fuses it: its `params` (the world's
  `EnvParams`), its compiled functions (`draw`, `reset`, `step`, `end`), a fresh state
  (`new_state()`: its `EnvState`), the lengths of its starts and observations."""
  task: str
  level: str
  params: object
  draw_fn: object
  reset: object
  step: object
  end: object
  start_size: int
  obs_size: int

  @property
  def functions(self):
    """{the name the graph's module binds: the compiled function} (`Program`)."""
    return {"world_draw": self.draw_fn, "world_reset": self.reset, "world_step": self.step,
            "world_end": self.end}

  def new_state(self):
    """A fresh `EnvState` of the world."""
    return _MODULES[self.task].env_state(self.params)

  def draw(self, rng_state, state=None):
    """A start (a new row) drawn from `rng_state` (the agent's generator) by the fused
    loop's own rule."""
    start = np.zeros(self.start_size)
    self.draw_fn(self.params, self.new_state() if state is None else state, rng_state, start)
    if start[0] < 0.0:
      raise RuntimeError(f"{self.task}/{self.level}: no start (or gate) clear of the "
                         f"obstacles in {_START_TRIES:,} draws")
    return start

  def options(self, start):
    """The Gymnasium (and dm_control) reset options of a start row: "state", and the
    goal's "gate" or the regatta's "course"."""
    start = np.asarray(start, dtype=np.float64)
    if start.shape != (self.start_size,):
      raise ValueError(f"{self.task}/{self.level}: a start is {self.start_size} numbers (the "
                       f"ship's state, then its layout), got shape {start.shape}")
    out = {"state": start[:4].copy()}
    if self.task == "ship_goal":
      out["gate"] = start[4:7].copy()
    elif self.task == "ship_regatta":
      out["course"] = start[4:].reshape(-1, 3).copy()
    return out

  def start_of(self, options):
    """A start row of reset options (`options`' inverse): the benchmark's fixed starts."""
    parts = [np.asarray(options["state"], dtype=np.float64).reshape(4)]
    if self.task == "ship_goal":
      parts.append(np.asarray(options["gate"], dtype=np.float64).reshape(3))
    elif self.task == "ship_regatta":
      parts.append(np.asarray(options["course"], dtype=np.float64).reshape(-1))
    return np.concatenate(parts)

  def flatten(self, obs):
    """The environment's observation as the machine's vector (the goal's dictionary
    flattened in `ship_goal_core.OBSERVATION_KEYS`' order; the rest as they are)."""
    if self.task == "ship_goal" and isinstance(obs, dict):
      return goal_core.flatten(obs)
    return obs


_MODULES = {"ship_current": current_core, "ship_goal": goal_core,
            "ship_regatta": regatta_core, "ship_harbour": harbour_core}
_DRAWS = {"ship_current": draw_current, "ship_goal": draw_goal, "ship_regatta": draw_regatta,
          "ship_harbour": draw_harbour}


def check_task(task, level, who="the ladder"):
  """(task, level), or a one-line error naming what is allowed."""
  if task not in TASKS:
    raise ValueError(f"{who}: unknown task {task!r}; the ladder's tasks: {list(TASKS)}")
  if level not in LEVELS:
    raise ValueError(f"{who}: unknown level {level!r} of {task}; allowed levels: {list(LEVELS)}")
  return task, level


def world(task, level, gate_reward=core.GATE_REWARD,
          out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD, max_steps=core.STEER_MAX_STEPS,
          finish_reward=regatta_core.FINISH_REWARD):
  """The `World` of ladder task `task` ("ship_current", ...) at `level`, with the
  environment's rewards (`finish_reward`: the regatta's last gate) and step limit."""
  check_task(task, level)
  module = _MODULES[task]
  if task == "ship_regatta":
    params = module.env_params(level, gate_reward, finish_reward, out_of_bounds_reward,
                               max_steps)
    start_size, obs_size = regatta_core.start_size(level), regatta_core.OBSERVATION_SIZE
  else:
    params = module.env_params(level, gate_reward, out_of_bounds_reward, max_steps)
    start_size = module.START_SIZE
    obs_size = {"ship_current": current_core.OBSERVATION_SIZE,
                "ship_goal": goal_core.OBSERVATION_SIZE,
                "ship_harbour": harbour_core.OBSERVATION_SIZE}[task]
  return World(task, level, params, _DRAWS[task], module.env_reset, module.env_step,
               module.env_end, int(start_size), int(obs_size))
