"""What the ship agents share: the [environment] section, the environments, the
starts of the full task (drawn from the agent's generator, the same way on every
path), and the gate metrics."""
import dataclasses

import numba
import numpy as np

from hpg_mj.agents import base
from hpg_mj.agents import taskfile
from hpg_mj.agents.taskfile import param
from hpg_mj.worlds import ship_core as core
from hpg_mj.learners import rng

METRIC_WINDOW = 1000   # online metrics are over the last 1,000 episodes


@dataclasses.dataclass(frozen=True)
class ShipEnvironment(taskfile.Section):
  """[environment] of a ship task file (SPEC section 2)."""
  world: str = param("ship", "the world", choices=("ship",))
  backend: str = param("analytic", "train on Equation 1 (analytic) or the MuJoCo ship",
                       choices=base.BACKENDS)
  gate_reward: float = param(core.GATE_REWARD, "reward for passing the gate")
  out_of_bounds_reward: float = param(core.OUT_OF_BOUNDS_REWARD, "reward for leaving the field")
  max_steps: int = param(core.STEER_MAX_STEPS, "control steps, then truncated", low=1)


@numba.njit(cache=True)
def sample_start(rng_state, out):
  """A start of the full task (SPEC section 2), drawn in the order x, y, theta, theta_dot."""
  out[0] = rng.uniform_range(rng_state, 0.0, core.FIELD_SIZE)
  out[1] = rng.uniform_range(rng_state, 0.0, core.FIELD_SIZE)
  out[2] = core.wrap_deg(rng.uniform_range(rng_state, -180.0, 180.0))
  out[3] = rng.uniform_range(rng_state, -core.MAX_TURN_RATE, core.MAX_TURN_RATE)


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
    start = np.empty(4)
    sample_start(self.rng_state, start)
    return start

  def end_episode(self, row, total, steps, last, learn):
    row[self.record_fields.index("passed")] = last.info.get("event") == "gate"
    row[self.record_fields.index("steps")] = steps
    row[self.record_fields.index("return")] = total

  def metrics(self, record):
    w = record[-METRIC_WINDOW:]
    passed = w["passed"] > 0
    return {
        "episodes_measured": int(len(w)),
        "gate_pass_rate": float(passed.mean()) if len(w) else None,
        "steps_to_gate": float(w["steps"][passed].mean()) if passed.any() else None,
        "mean_return": float(w["return"].mean()) if len(w) else None,
        "control_steps": int(record["steps"].sum()),
    }
