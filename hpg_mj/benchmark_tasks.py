"""The benchmark's tasks (`hpg_mj.benchmark`): which world and environment settings a
task name, a task file or an agent stands for, and the fixed seeded starts every
report scores from (SPEC section 7). Its names are `hpg_mj.benchmark`'s too."""
import dataclasses
import pathlib
import types

import numpy as np

from hpg_mj.agents import _ship
from hpg_mj.agents import _taxi
from hpg_mj.agents import base
from hpg_mj.experiments import bounds as bounds_mod
from hpg_mj.experiments.bounds import LADDER, LEVELS, TASKS
from hpg_mj.worlds import ship_core
from hpg_mj.worlds import ship_ladder
from hpg_mj.worlds import taxi_core
from hpg_mj.worlds import taxi_rules


# ---- tasks ---------------------------------------------------------------------------

ENV_IDS = {"ship": "hpg_mj/ShipSteering-v0", "taxi_fuel": "hpg_mj/TaxiFuel-v0",
           "taxi": "hpg_mj/Taxi-v0", **ship_ladder.ENV_IDS}


@dataclasses.dataclass(frozen=True)
class Task:
  """One benchmark task: the world and its environment's settings."""
  name: str                   # "ship", "taxi_fuel", "taxi" or a ladder task of `LADDER`
  max_steps: int                              # the step limit (then truncated)
  gate_reward: float = ship_core.GATE_REWARD                    # ships only
  out_of_bounds_reward: float = ship_core.OUT_OF_BOUNDS_REWARD  # ships only
  capacity: int = taxi_core.FUEL_CAPACITY                       # taxi_fuel only
  level: str = None                           # the ladder's tasks only: a name of LEVELS

  def __post_init__(self):
    # A ladder level's time limit closes the episode, whatever the limit asked.
    if self.name in LADDER and self.level is not None:
      object.__setattr__(self, "max_steps",
                         ship_ladder.episode_steps(self.name, self.level, self.max_steps))

  @property
  def world(self):
    """What the record holds: "ship" (a gate: the steering task, the current, the
    goal), "regatta" (a course of gates) or "taxi"."""
    if self.name == "ship_regatta":
      return "regatta"
    return "ship" if self.name in ("ship",) + LADDER else "taxi"

  @property
  def key(self):
    """The task's name in the bounds: "ship", ..., "<task>/<level>" on the ladder."""
    return bounds_mod.bounds_key(self.name, self.level)

  @property
  def env_id(self):
    """The Gymnasium id of its environment."""
    return ENV_IDS[self.name]

  @property
  def default_max_steps(self):
    """Its world's own episode length in steps (the taxi's, the ship's steer, or a ladder
    task's at its level)."""
    if self.name in LADDER and self.level is not None:
      return ship_ladder.episode_steps(self.name, self.level)
    return taxi_core.MAX_STEPS if self.world == "taxi" else ship_core.STEER_MAX_STEPS

  @property
  def standard(self):
    """Whether its rules are the benchmark's own: its world's episode length and the
    taxi's tank (a score of anything else is not official)."""
    return self.max_steps == self.default_max_steps and self.capacity == taxi_core.FUEL_CAPACITY

  def env_kwargs(self, backend="analytic"):
    """The keyword arguments that make its environment: the ship's backend, length,
    rewards and level, or the taxi's length and capacity."""
    if self.world != "taxi":
      level = {} if self.level is None else {"level": self.level}
      return {"backend": backend, "max_steps": self.max_steps, "gate_reward": self.gate_reward,
              "out_of_bounds_reward": self.out_of_bounds_reward, **level}
    extra = {"capacity": self.capacity} if self.name == "taxi_fuel" else {}
    return {"max_steps": self.max_steps, **extra}

  def rules(self):
    """The taxi's `TaxiRules` (its starts and its world array)."""
    return taxi_core.TaxiRules(self.name == "taxi_fuel", capacity=self.capacity,
                               max_steps=self.max_steps, who=f"benchmark task {self.name!r}")


def task_of(task, max_steps=None, level=None):
  """A `Task` from a name of `TASKS` or of the ladder's `LADDER` (at `level`, a name of
  `LEVELS`, default "easy" as the environments'; or written "ship_goal/hard"), a
  `Task`, an agent (its own task), a loaded task file, or a task file's path or
  shipped name; `max_steps` replaces its step limit. A name the benchmark does not
  have, or a level it does not, is refused in one line naming what is allowed."""
  name = task
  if isinstance(task, str) and "/" in task and task.split("/", 1)[0] in LADDER:
    name, written = task.split("/", 1)
    if level is not None and level != written:
      raise ValueError(f"task {task!r} names level {written!r} and level={level!r} another; "
                       "give the level once")
    level = written
  if level is not None and not (isinstance(name, str) and name in LADDER):
    raise ValueError(f"level={level!r} is for the ladder's tasks {list(LADDER)}; task "
                     f"{getattr(name, 'name', name)!r} has no levels")
  if isinstance(name, str) and name in LADDER:
    level = LEVELS[0] if level is None else level
    if not isinstance(level, str) or level not in LEVELS:
      raise ValueError(f"level {level!r} of task {name!r} is not known; allowed levels: "
                       f"{list(LEVELS)}")
    out = Task(name, ship_core.STEER_MAX_STEPS, level=level)
  elif isinstance(task, Task):
    out = task
  elif isinstance(task, str) and task in TASKS:
    out = Task(task, ship_core.STEER_MAX_STEPS if task == "ship" else taxi_core.MAX_STEPS)
  else:
    out = _task_of_environment(task)
  if max_steps is not None:
    if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) \
        or max_steps < 1:
      raise ValueError(f"max_steps must be a positive integer, got {max_steps!r}")
    out = dataclasses.replace(out, max_steps=int(max_steps))
  return out


_ALLOWED = (f"{', '.join(TASKS)}, {', '.join(LADDER)} (at a level: {', '.join(LEVELS)}; "
            "for example ship_goal/hard), or a task file (a shipped name or a path)")


def _task_of_environment(task):
  from hpg_mj import agents
  if isinstance(task, base.Agent):
    holder, where = task, f"agent {task.name!r}"
  else:
    if isinstance(task, (str, pathlib.Path)):
      try:
        task = agents.load_task(task)
      except ValueError as err:
        if isinstance(task, str) and not task.endswith(".toml") and "/" not in task:
          raise ValueError(f"task {task!r} is not known; allowed: {_ALLOWED}") from None
        raise err
    elif not (hasattr(task, "config") and hasattr(task, "kind")):
      what = (f"an array of shape {task.shape}" if isinstance(task, np.ndarray)
              else repr(task)[:80])
      raise ValueError(f"task {what} is not known; allowed: {_ALLOWED} or an hpg_mj agent")
    holder = types.SimpleNamespace(config=task.config,
                                   record_steps=agents.lookup(task.kind).record_steps)
    where = f"task file {task.path}"
  name = bounds_mod.task_name(holder)
  if name is None:
    raise ValueError(f"{where}: not one of the benchmark's tasks {list(TASKS)} (the full "
                     "ship task or the taxi, episodic)")
  env = holder.config.environment
  if "/" in name:                       # a ladder task at its level, under its rewards
    name, level = name.split("/")     # (SPEC section 11's, whatever rewards train on it)
    return Task(name, int(env.max_steps), level=level)
  if name == "ship":
    return Task(name, int(env.max_steps), float(env.gate_reward), float(env.out_of_bounds_reward))
  return Task(name, int(env.max_steps), capacity=int(env.capacity))


def fixed_starts(task="ship", episodes=base.GREEDY_STARTS, seed=base.GREEDY_SEED, *,
                 level=None):
  """The fixed seeded starts of every report (SPEC section 7): row i from seed
  `seed + i`, drawn as every agent of the task draws its starts; an array of rows.
  `task` and `level` as `evaluate`'s (`"ship_goal", level="hard"` or "ship_goal/hard").

  On the ladder's tasks (`LADDER`), start i is the episode the Gymnasium environment
  lays out at `reset(seed=seed + i)`: the ship's state (the harbour's drawn again while
  it lies on an obstacle), then the goal's gate or the regatta's course, from one
  generator. A dictionary of arrays, the reset options
  that set it: "state" (n, 4), and "gate" (n, 3) rows [x, y, heading_deg] or
  "course" (n, gates, 3)."""
  task = task_of(task, level=level)
  if task.name in LADDER:
    return _ladder_starts(task, episodes, seed)
  if task.world == "ship":
    return base.seeded_starts(_ship.draw_start, episodes, seed)
  world = taxi_rules.world_config(task.rules())
  return base.seeded_starts(lambda generator: _taxi.draw_start(generator, world), episodes,
                            seed).astype(np.int64)


def _ladder_starts(task, episodes, seed):
  """`fixed_starts` of a ladder task: each environment's reset, drawn alike
  (`worlds.ship_ladder.fixed_starts`, which the ladder's agents read too)."""
  _count("episodes", episodes)
  _count("seed", seed)
  return ship_ladder.fixed_starts(task.name, task.level, episodes, seed)


def _start_count(starts):
  return len(starts["state"]) if isinstance(starts, dict) else len(starts)


def optimal_returns(task, starts):
  """V* of each taxi start (`worlds.taxi_values`, exact)."""
  from hpg_mj.worlds import taxi_values
  task = task_of(task)
  values = taxi_values.taxi_values(task.name == "taxi_fuel", capacity=task.capacity)
  return np.array([values.state_value(*(int(v) for v in s)) for s in starts], dtype=np.float64)


def _count(name, value):
  if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
    raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
