"""What the ship agents share: the [environment] section, the environments, the
starts of the full task (drawn from the agent's generator, the same way on every
path), and the gate metrics; `ContinuingShipAgent`, what an agent on the continuing
task (SPEC section 8) needs beside its graph."""
import dataclasses

import numpy as np

from hpg_mj.agents import base
from hpg_mj import taskfile
from hpg_mj.taskfile import param
from hpg_mj.hierarchy import algorithm
from hpg_mj.hierarchy import ship_rules as rules
from hpg_mj.hierarchy.patrol import NEVER, AgentRestarts
from hpg_mj.worlds import ship_core as core

# SPEC section 7: J, the discounted return under MushroomRL's ShipSteering rewards,
# so that our ships compare with MushroomRL-based results.
J_GAMMA = 0.99
J_STEP_REWARD = -1.0          # every control step that neither passes nor leaves
J_GATE_REWARD = 0.0           # the step that passes the gate
J_OUT_OF_BOUNDS_REWARD = -100.0   # the step that leaves the field
# Published J on the 1,000 m task (Tateo and Erdenlig's hierarchical experiments,
# MushroomRL), set beside ours in the reports.
PUBLISHED_J = {"Ghavamzadeh-style hybrid (Tateo and Erdenlig)": -92.7,
               "best hierarchy (Tateo and Erdenlig)": -87.3}


def mushroom_j(record, max_steps, out_of_bounds_reward, gamma=J_GAMMA):
  """Per episode of a ship record (fields passed, steps, return), its discounted
  return under MushroomRL's rewards: the -1s of all steps but the last, then 0 if
  it passed the gate, -100 if it left the field, -1 if it was truncated.

  An episode that neither passed nor ran to `max_steps` left the field; one that
  stopped at `max_steps` left it only if its return holds the task's
  `out_of_bounds_reward` (the full task's return is -steps, plus that or the gate's
  reward on the last step)."""
  steps = np.asarray(record["steps"], dtype=np.float64)
  passed = np.asarray(record["passed"]) > 0
  ret = np.asarray(record["return"], dtype=np.float64)
  if np.any(steps < 1):
    raise ValueError(f"a ship episode has at least one control step; got {steps.min()}")
  left = ~passed & ((steps < max_steps) | (
      (out_of_bounds_reward != 0.0) & np.isclose(ret + steps, out_of_bounds_reward)))
  last = np.where(passed, J_GATE_REWARD, np.where(left, J_OUT_OF_BOUNDS_REWARD, J_STEP_REWARD))
  discount = gamma ** (steps - 1.0)
  return J_STEP_REWARD * (1.0 - discount) / (1.0 - gamma) + discount * last


def straight_line_j(starts=100_000, seed=0, gamma=J_GAMMA):
  """The straight-line bound on J over uniform starts (SPEC section 7): a ship that
  sails straight at the gate from any start, without turning, crosses it on the
  control step ceil(distance / (V * 0.6 s)); the mean of that episode's J."""
  rng_ = np.random.default_rng(seed)
  p = rng_.uniform(0.0, core.FIELD_SIZE, (starts, 2))
  a, b = core.GATE
  t = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
  distance = np.linalg.norm(p - (a + t[:, None] * (b - a)), axis=1)
  steps = np.maximum(np.ceil(distance / (core.SPEED * core.CONTROL_INTERVAL)), 1.0)
  discount = gamma ** (steps - 1.0)
  return float(np.mean(J_STEP_REWARD * (1.0 - discount) / (1.0 - gamma)
                       + discount * J_GATE_REWARD))


@dataclasses.dataclass(frozen=True)
class ShipEnvironment(taskfile.Section):
  """[environment] of a ship task file (SPEC section 2)."""
  world: str = param("ship", "the world", choices=("ship",))
  backend: str = param("analytic", "train on Equation 1 (analytic) or the MuJoCo ship",
                       choices=base.BACKENDS)
  gate_reward: float = param(core.GATE_REWARD, "reward for passing the gate")
  out_of_bounds_reward: float = param(core.OUT_OF_BOUNDS_REWARD, "reward for leaving the field")
  max_steps: int = param(core.STEER_MAX_STEPS, "control steps, then truncated", low=1)


sample_start = rules.sample_start   # the full task's start (SPEC section 2)


def draw_start(rng_state):
  """A start of the full task drawn from `rng_state` (`sample_start`), as a new array."""
  start = np.empty(4)
  sample_start(rng_state, start)
  return start


def make_env(gym_id, suite_task, api, backend, settings, kwargs):
  """A ship task's environment with the task file's `settings`: Gymnasium's
  hpg_mj/`gym_id` on `backend`, or dm_control's suite task ("ship", `suite_task`)."""
  if api == "gymnasium":
    import gymnasium

    import hpg_mj  # noqa: F401  (registers the ids)
    return gymnasium.make(f"hpg_mj/{gym_id}", backend=backend, **settings, **kwargs)
  if api == "dm_control":
    from hpg_mj import suite
    return suite.load("ship", suite_task, {"random": 0, **settings, **kwargs})
  raise ValueError(f"unknown environment api {api!r}; allowed: ['gymnasium', 'dm_control']")


def gate_metrics(record, max_steps, out_of_bounds_reward):
  """What a ship record (fields passed, steps, return) says, over all its
  episodes: the gate pass rate, the control steps to the gate over the passes,
  the mean return (the task's rewards) and the mean J (`mushroom_j`)."""
  passed = record["passed"] > 0
  n = len(record)
  return {
      "gate_pass_rate": float(passed.mean()) if n else None,
      "steps_to_gate": float(record["steps"][passed].mean()) if passed.any() else None,
      "mean_return": float(record["return"].mean()) if n else None,
      "J": float(mushroom_j(record, max_steps, out_of_bounds_reward).mean()) if n else None,
  }


class ShipAgent(base.Agent):
  """An agent on the full ship task (subclass it for your own): the environments,
  the starts, and the gate metrics. Its Config needs an `environment:
  ShipEnvironment` section; its record the fields passed, steps, return."""

  figure = "gate_pass_rate"

  @property
  def task_rewards(self):
    env = self.config.environment
    return np.array([env.gate_reward, env.out_of_bounds_reward], dtype=np.float64)

  def make_env(self, api="gymnasium", backend="analytic", **kwargs):
    env = self.config.environment
    return make_env("ShipSteering-v0", "steer", api, backend,
                    {"max_steps": env.max_steps, "gate_reward": env.gate_reward,
                     "out_of_bounds_reward": env.out_of_bounds_reward}, kwargs)

  def start_state(self):
    return draw_start(self.rng_state)

  def end_episode(self, row, total, steps, last, learn):
    row[self.record_fields.index("passed")] = last.info.get("event") == "gate"
    row[self.record_fields.index("steps")] = steps
    row[self.record_fields.index("return")] = total

  def j(self, record):
    """Each episode's J under MushroomRL's rewards (`mushroom_j`)."""
    env = self.config.environment
    return mushroom_j(record, env.max_steps, env.out_of_bounds_reward)

  def metrics(self, record):
    w = record[-self.metric_window:]
    env = self.config.environment
    return {"episodes_measured": int(len(w)),
            **gate_metrics(w, env.max_steps, env.out_of_bounds_reward),
            "control_steps": int(record["steps"].sum())}

class ShipMachineAgent(base.MachineAgent, ShipAgent):
  """A ship agent whose `graph()` is made of blocks (`base.MachineAgent`), fused with
  the analytic ship."""

  required_fields = ("passed", "steps", "return")

  def compiled(self, episodes, learn, sample, start=None):
    env = self.config.environment
    self.machine.start_schedule(self.episodes)
    rows = self.machine.run(episodes, learn, sample, self.rng_state,
                            (env.gate_reward, env.out_of_bounds_reward, env.max_steps), start)
    return self._record_rows(rows)

  def _ended(self, last):
    return last.info.get("event") == "gate"


@dataclasses.dataclass(frozen=True)
class ContinuingEnvironment(taskfile.Section):
  """[environment] of the continuing ship task (SPEC section 8)."""
  world: str = param("ship", "the world", choices=("ship",))
  backend: str = param("analytic", "train on Equation 1 (the compiled path)",
                       choices=("analytic",))
  gate_reward: float = param(core.GATE_REWARD, "reward for each pass of the gate")
  out_of_bounds_reward: float = param(core.OUT_OF_BOUNDS_REWARD,
                                      "reward for leaving the field (then a fresh start)")


class ContinuingShipAgent(ShipMachineAgent):
  """An agent on the continuing ship task (SPEC section 8) whose graph's root is a
  `blocks.Clock`: one process that never ends (each gate pass pays and the ship sails
  on; a departure pays and the ship restarts at a start drawn from the agent's
  generator), one record row per `record_steps` control steps (an hour). Both paths
  are the machine: fused with the analytic ship (`Program.run_continuing`) and step
  by step through the Gymnasium patrol without its truncation (`AgentRestarts`);
  for a fixed seed they give the same rows. Its Config needs an `environment:
  ContinuingEnvironment`; its record the fields steps, gates, departures, return."""

  end_field, illegal_field = "gates", "departures"    # a continuing row's (algorithm.run_continuing)
  required_fields = ("steps", "gates", "departures", "return")
  record_steps = core.HOUR_STEPS       # one record row per hour

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    self.ship = np.zeros(4)            # the process's state
    self.started = np.zeros(1)         # 1 once the process has its first start

  def state(self):
    return {**super().state(), "ship_state": self.ship, "ship_started": self.started}

  def make_env(self, api="gymnasium", backend="analytic", **kwargs):
    env = self.config.environment
    return make_env("ShipPatrol-v0", "patrol", api, backend,
                    {"gate_reward": env.gate_reward,
                     "out_of_bounds_reward": env.out_of_bounds_reward}, kwargs)

  def finish_row(self, row):
    """Fills the agent's own columns of a record row just sailed (nothing here)."""

  def _process(self, learn, start):
    """The state the rows sail from: learning continues the agent's own process
    (from `start`, if given); without learning, a fresh start from the agent's
    generator (or `start`)."""
    if not learn:
      return np.array(start, dtype=np.float64) if start is not None else \
          draw_start(self.rng_state)
    if start is not None:
      self.ship[:] = start
      self.started[0] = 1.0
    elif not self.started[0]:
      sample_start(self.rng_state, self.ship)
      self.started[0] = 1.0
    return self.ship

  def _rows(self, hours, row_of):
    """`hours` record rows, each from `row_of()` (one machine row), finished by
    `finish_row`."""
    out = np.zeros((int(hours), len(self.record_fields)))
    for i in range(int(hours)):
      out[i] = self._record_rows(row_of())[0]
      self.finish_row(out[i])
    return out

  def compiled(self, episodes, learn, sample, ship=None, rng_state=None):
    """`episodes` rows (hours) fused with the analytic ship, from `ship` (None: the
    process, `_process`), drawing from `rng_state` (None: the agent's)."""
    ship = self._process(learn, None) if ship is None else ship
    rng_state = self.rng_state if rng_state is None else rng_state
    env = self.config.environment
    world = (env.gate_reward, env.out_of_bounds_reward)
    return self._rows(episodes, lambda: self.machine.run_continuing(1, learn, sample, rng_state,
                                                                    world, ship))

  def stepwise_env(self, backend):
    """The Gymnasium patrol on `backend`, without its one-hour truncation: the
    agent's rows are its own hours, ended between calls as the compiled loop's."""
    return self.make_env("gymnasium", backend=backend, max_steps=NEVER)

  def run_stepwise(self, env, episodes, learn=True, sample=None, start=None, on_call=None):
    """`episodes` rows (hours) through `env`, a Gymnasium patrol without truncation
    (`stepwise_env`), continuing the process as the compiled path does; after a
    departure the ship restarts at a start drawn from the agent's generator (the
    environment's own draw replaced, `AgentRestarts`)."""
    from hpg_mj.hierarchy import executor
    adapter = AgentRestarts(executor.adapter_for(env), self.rng_state)
    ship = self._process(learn, start)

    def row():
      rows = self.machine.run_stepwise(adapter, 1, learn, sample, self.rng_state,
                                       lambda: ship.copy(), lambda last: adapter.gates,
                                       on_call=on_call)
      rows[0, algorithm.ROW_ILLEGAL] = adapter.departures
      ship[:] = adapter.last_obs                # the next row sails on from here
      return rows
    out = self._rows(episodes, row)
    if learn:
      self.episodes += int(episodes)
    return self.as_record(out)
