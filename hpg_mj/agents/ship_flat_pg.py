"""Flat PGRL on the full ship task (paper section 5.2; SPEC section 4): Eq. 3 over
the whole episode with the Gaussian-with-sigmoid policy on a CMAC of 9 tilings x
20 x 20 x 36 x 5 = 72,000 tiles (648,000 weights), acting every 0.6 s with SPEC
section 2's rewards. A baseline of the hierarchy (tag "baseline").

Every step touches only the 9 active tiles: the trace is applied lazily
(`learners.eligibility`), so a step's cost does not grow with the episode or the
number of weights. Both paths (the fused loop `train_flat_pg`, the one-node task
graph step by step) call the same compiled rules.
"""
import collections
import dataclasses

import numba
import numpy as np

from hpg_mj.agents import _ship
from hpg_mj.agents import taskfile
from hpg_mj.agents.taskfile import param
from hpg_mj.hierarchy import flat as flat_graph
from hpg_mj.learners import agents as learners
from hpg_mj.learners import arrays
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core as core

# Per-episode record columns (the order of `record_fields`).
PASSED, STEPS, RETURN = 0, 1, 2
N_RECORD = 3

def actor_coder(n_tilings=9, tiles=(20, 20, 36, 5)):
  return tiles_mod.TileCoder((0.0, 0.0, -180.0, -core.MAX_TURN_RATE),
                             (core.FIELD_SIZE, core.FIELD_SIZE, 180.0, core.MAX_TURN_RATE),
                             tuple(tiles), (False, False, True, False), n_tilings)



# The hyper-parameters the compiled loop takes, named [section] key as in the task file.
Settings = collections.namedtuple("Settings", (
    "policy_alpha", "policy_trace_gamma", "environment_max_steps", "environment_gate_reward",
    "environment_out_of_bounds_reward"))


def settings(config):
  pol, env = config.policy, config.environment
  return Settings(float(pol.alpha), float(pol.trace_gamma), int(env.max_steps),
                  float(env.gate_reward), float(env.out_of_bounds_reward))


# error_model="numpy": no raising branch on division, less reference counting (learners.policies).
@numba.njit(cache=True, error_model="numpy")
def train_flat_pg(n_episodes, learn, sample, rng_state, policy, tiling, s, record, fixed_start):
  """Flat PGRL (Eq. 3 over the full task, trace `policy` over `tiling`): z <- 0 at
  the start of an episode."""
  state = np.empty(4)
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  active = np.empty(tiling.offsets.shape[0], dtype=np.int64)
  psi = np.empty(tiling.offsets.shape[0])
  for episode in range(n_episodes):
    if fixed_start.shape[0] == 4:
      arrays.copy_into(state, fixed_start)
    else:
      _ship.sample_start(rng_state, state)
    el.reset(policy)
    total = 0.0
    steps = 0
    event = core.NO_EVENT
    while True:
      tiles_mod.active_tiles(state, tiling, active)
      if sample:
        r = policies.gaussian_act(policy, active, core.MAX_TURN_RATE, rng_state, psi)
      else:
        r = policies.gaussian_greedy(policy, active, core.MAX_TURN_RATE)
      core.euler_control(state, r, samples)
      steps += 1
      event, reward = core.global_outcome(samples, s.environment_gate_reward,
                                          s.environment_out_of_bounds_reward)
      total += reward
      if learn:
        el.learn(policy, s.policy_alpha, reward, s.policy_trace_gamma)
      if event != core.NO_EVENT or steps >= s.environment_max_steps:
        break
    record[episode, PASSED] = event == core.SUCCESS
    record[episode, STEPS] = steps
    record[episode, RETURN] = total


@dataclasses.dataclass(frozen=True)
class Policy(taskfile.Section):
  """[policy]: Eq. 3 over the full task."""
  learner: str = param("policy_gradient", "Eq. 3", choices=("policy_gradient",))
  alpha: float = param(0.01, "Eq. 3 step size", low=0, low_open=True)
  trace_gamma: float = param(1.0, "discount on the Eq. 3 trace (1 = plain Eq. 3)", low=0,
                             high=1, low_open=True)
  tilings: int = param(9, "CMAC tilings", low=1)
  tiles: tuple = param((20, 20, 36, 5), "tiles per tiling over x, y, theta, theta_dot",
                       length=4, low=1)


@dataclasses.dataclass(frozen=True)
class Config:
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)
  policy: Policy = dataclasses.field(default_factory=Policy)


class ShipFlatPG(_ship.ShipAgent):
  """Flat PGRL's learner and generator, trained step by step or compiled."""

  name = "ship_flat_pg"
  Config = Config
  record_fields = ("passed", "steps", "return")
  tags = ("baseline",)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    pol = self.config.policy
    self.coder = actor_coder(pol.tilings, pol.tiles)
    self.tile_arrays = self.coder.arrays()
    self.learner = learners.GaussianPolicyGradient(self.coder.size, pol.tilings, core.MAX_TURN_RATE,
                                                   pol.alpha, pol.trace_gamma)
    self._active = np.empty(pol.tilings, dtype=np.int64)

  def state(self):
    out = {"rng_state": self.rng_state}
    out.update({f"policy_{k}": v for k, v in self.learner.trace._asdict().items()})
    return out

  def compiled(self, episodes, learn, sample, start=None):
    rows = np.zeros((episodes, N_RECORD))
    fixed = np.empty(0) if start is None else np.array(start, dtype=np.float64)
    train_flat_pg(episodes, learn, sample, self.rng_state, self.learner.trace, self.tile_arrays,
                  settings(self.config), rows, fixed)
    return rows

  def _view(self, call, obs):
    tiles_mod.active_tiles(np.asarray(obs, dtype=np.float64), self.tile_arrays, self._active)
    return self._active

  def graph(self):
    return flat_graph.flat_graph(self.learner, self._view, ["turn"], continuous=True)
