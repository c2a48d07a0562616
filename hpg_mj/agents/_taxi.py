"""What the taxi agents share: the [environment] section, the environments, the
starts (drawn by the compiled rules, as the fused loops draw them), the episode's
outcome, and the metrics against the exact optimum."""
import dataclasses

import numpy as np

from hpg_mj.agents import base
from hpg_mj import taskfile
from hpg_mj.taskfile import param
from hpg_mj.hierarchy import taxi_subtasks
from hpg_mj.worlds import taxi_core
from hpg_mj.worlds import taxi_rules as world_rules


def draw_start(rng_state, world):
  """A start drawn from `rng_state` (`taxi_subtasks.sample_start`) as a new array: (row, col,
  passenger, destination, fuel), the fuel left out in the classic task."""
  state = np.empty(5, dtype=np.int64)
  taxi_subtasks.sample_start(rng_state, world, state)
  return state if world[world_rules.W_FUEL_ENABLED] != 0 else state[:4].copy()


@dataclasses.dataclass(frozen=True)
class TaxiEnvironment(taskfile.Section):
  """[environment] of a taxi task file (SPEC section 5)."""
  world: str = param("taxi", "the world", choices=("taxi",))
  backend: str = param("analytic", "the compiled loop (analytic) or the dm_control board "
                       "(mujoco)", choices=base.BACKENDS)
  fuel: bool = param(True, "taxi-fuel (true) or Dietterich's classic taxi (false)")
  capacity: int = param(taxi_core.FUEL_CAPACITY, "the tank", low=1)
  max_steps: int = param(taxi_core.MAX_STEPS, "primitive steps, then truncated", low=1)


class TaxiAgent(base.Agent):
  """An agent on the taxi (subclass it for your own): the environments, starts,
  the outcome of each episode and the metrics against the exact optimum. Its
  Config needs an `environment: TaxiEnvironment` section; its record the fields
  return, steps, outcome. A shipped agent's `engine` holds its learners and its
  episode count (which drives their schedules)."""

  figure = "mean_return"

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    env = self.config.environment
    self.rules = taxi_core.TaxiRules(env.fuel, capacity=env.capacity, max_steps=env.max_steps)
    self.world = world_rules.world_config(self.rules)
    self._optimal = None

  def _adopt(self, engine):
    """Shares one generator and one episode count with the engine."""
    engine.rng_state = self.rng_state
    self.engine = engine

  @property
  def episodes(self):
    engine = self.__dict__.get("engine")
    return engine.episodes if engine is not None else self.__dict__.get("_episodes", 0)

  @episodes.setter
  def episodes(self, value):
    engine = self.__dict__.get("engine")
    if engine is not None:
      engine.episodes = int(value)
    else:
      self.__dict__["_episodes"] = int(value)

  def make_env(self, api="gymnasium", backend="analytic", **kwargs):
    r = self.rules
    if api == "gymnasium":
      import gymnasium

      import hpg_mj  # noqa: F401  (registers the ids)
      extra = {"capacity": r.capacity} if r.fuel_enabled else {}
      return gymnasium.make("hpg_mj/TaxiFuel-v0" if r.fuel_enabled else "hpg_mj/Taxi-v0",
                            max_steps=r.max_steps, **extra, **kwargs)
    if api == "dm_control":
      from hpg_mj import suite
      task_kwargs = {"random": 0, "max_steps": r.max_steps, **kwargs}
      if r.fuel_enabled:
        task_kwargs["capacity"] = r.capacity
      return suite.load("taxi", "fuel" if r.fuel_enabled else "classic", task_kwargs)
    raise ValueError(f"unknown environment api {api!r}; allowed: ['gymnasium', 'dm_control']")

  def stepwise_env(self, backend):
    # The taxi's MuJoCo world is the dm_control board; its Gymnasium one is the rules.
    return self.make_env("dm_control" if backend == "mujoco" else "gymnasium")

  def start_state(self):
    return draw_start(self.rng_state, self.world)

  def end_episode(self, row, total, steps, last, learn):
    row[self.record_fields.index("return")] = total
    row[self.record_fields.index("steps")] = steps
    row[self.record_fields.index("outcome")] = world_rules.outcome_of(last)
    engine = self.__dict__.get("engine")
    if learn and engine is not None:
      engine.primitive_steps += steps

  def optimal_mean_return(self):
    if self._optimal is None:
      from hpg_mj.worlds import taxi_values
      self._optimal = taxi_values.optimal_mean_return(self.rules.fuel_enabled,
                                                      capacity=self.rules.capacity)
    return self._optimal

  def metrics(self, record):
    from hpg_mj.worlds import taxi_values
    w = record[-self.metric_window:]
    optimal = self.optimal_mean_return()
    mean = float(w["return"].mean()) if len(w) else None
    return {"episodes_measured": int(len(w)), "mean_return": mean,
            "optimal_mean_return": optimal,
            "reaches_95_percent": bool(mean is not None and mean >=
                                       taxi_values.performance_threshold(optimal, 0.95)),
            "primitive_steps": int(record["steps"].sum())}


class TaxiMachineAgent(base.MachineAgent, TaxiAgent):
  """A taxi agent whose `graph()` is made of blocks (`base.MachineAgent`), fused with
  the taxi's rules; its record's first field is the outcome."""

  end_field = "outcome"
  required_fields = ("return", "steps", "outcome")

  @property
  def machine_world(self):
    return self.world

  def compiled(self, episodes, learn, sample, starts=None):
    """The fused loop; `starts`: rows (row, col, passenger, destination, fuel) used
    in turn, checked against the task, or None to draw each start."""
    if starts is not None:
      rows = np.asarray(starts)
      starts = [self.rules.check_state(row) for row in (rows[None] if rows.ndim == 1 else rows)]
    self.machine.start_schedule(self.episodes)
    return self._record_rows(self.machine.run_taxi(episodes, learn, sample, self.rng_state,
                                                   starts))

  def _ended(self, last):
    return world_rules.outcome_of(last)
