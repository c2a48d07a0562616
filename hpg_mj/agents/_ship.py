"""What the ship agents share: the [environment] section, the environments, the
starts of the full task (drawn from the agent's generator, the same way on every
path), and the gate metrics."""
import dataclasses

import numpy as np

from hpg_mj.agents import base
from hpg_mj import taskfile
from hpg_mj.taskfile import param
from hpg_mj.hierarchy import ship_rules as rules
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
    settings = {"max_steps": env.max_steps, "gate_reward": env.gate_reward,
                "out_of_bounds_reward": env.out_of_bounds_reward}
    if api == "gymnasium":
      import gymnasium

      import hpg_mj  # noqa: F401  (registers the ids)
      return gymnasium.make("hpg_mj/ShipSteering-v0", backend=backend, **settings, **kwargs)
    if api == "dm_control":
      from hpg_mj import suite
      return suite.load("ship", "steer", {"random": 0, **settings, **kwargs})
    raise ValueError(f"unknown environment api {api!r}; allowed: ['gymnasium', 'dm_control']")

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

  def compiled(self, episodes, learn, sample, start=None):
    env = self.config.environment
    self.machine.start_schedule(self.episodes)
    rows = self.machine.run(episodes, learn, sample, self.rng_state,
                            (env.gate_reward, env.out_of_bounds_reward, env.max_steps), start)
    return self._record_rows(rows)

  def _ended(self, last):
    return last.info.get("event") == "gate"
