"""Konda's actor-critic on the full ship task (SPEC section 4): the flat PGRL
actor (a Gaussian-with-sigmoid policy over its CMAC), stepped along
Q_critic(s, a) * psi(s, a); the critic is linear over 9 tilings of
5 x 5 x 36 x 5 x 30 = 135,000 tiles of (x, y, theta, theta_dot, r), learned by
TD(lambda) (SARSA-style on the actions taken). Acts every 0.6 s with SPEC
section 2's rewards. A baseline of the hierarchy (tag "baseline").
"""
import collections
import dataclasses

import numba
import numpy as np

from hpg_mj.agents import _ship
from hpg_mj.agents import taskfile
from hpg_mj.agents.taskfile import param
from hpg_mj.agents.ship_flat_pg import actor_coder
from hpg_mj.hierarchy import flat as flat_graph
from hpg_mj.learners import arrays
from hpg_mj.learners import actor_critic
from hpg_mj.learners import agents as learners
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core as core

# Per-episode record columns (the order of `record_fields`).
PASSED, STEPS, RETURN = 0, 1, 2
N_RECORD = 3

def critic_coder(n_tilings=9, tiles=(5, 5, 36, 5, 30)):
  return tiles_mod.TileCoder(
      (0.0, 0.0, -180.0, -core.MAX_TURN_RATE, -core.MAX_TURN_RATE),
      (core.FIELD_SIZE, core.FIELD_SIZE, 180.0, core.MAX_TURN_RATE, core.MAX_TURN_RATE),
      tuple(tiles), (False, False, True, False, False), n_tilings)


# The hyper-parameters the compiled loop takes, named [section] key as in the task file.
Settings = collections.namedtuple("Settings", (
    "actor_alpha", "critic_alpha", "critic_trace_decay", "environment_max_steps",
    "environment_gate_reward", "environment_out_of_bounds_reward"))


def settings(config):
  actor, critic, env = config.actor, config.critic, config.environment
  return Settings(float(actor.alpha), float(critic.alpha), float(critic.trace_decay),
                  int(env.max_steps), float(env.gate_reward), float(env.out_of_bounds_reward))


# error_model="numpy": no raising branch on division, less reference counting (learners.policies).
@numba.njit(cache=True, error_model="numpy")
def train_actor_critic(n_episodes, learn, sample, rng_state, actor_w, actor_tiling, critic,
                       critic_tiling, s, record, fixed_start):
  """Konda's actor-critic on the full task: the actor's weights over `actor_tiling`,
  the critic's TD(lambda) trace over `critic_tiling` (`learners.actor_critic`).

  Per step, with a = (u, r) drawn from the actor in s and a' in s':
    delta = R + Q(s', a') - Q(s, a)                   (no Q(s', a') at the end)
  then `actor_critic.learn`. Q(s, a) is the critic's value before this step's update.
  """
  state = np.empty(4)
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  sa = np.empty(5)
  a_tiles = np.empty(actor_tiling.offsets.shape[0], dtype=np.int64)
  a_next = np.empty_like(a_tiles)
  c_tiles = np.empty(critic_tiling.offsets.shape[0], dtype=np.int64)
  c_next = np.empty_like(c_tiles)
  ones = np.ones(critic_tiling.offsets.shape[0])
  for episode in range(n_episodes):
    if fixed_start.shape[0] == 4:
      arrays.copy_into(state, fixed_start)
    else:
      _ship.sample_start(rng_state, state)
    el.reset(critic)                                   # e <- 0
    tiles_mod.active_tiles(state, actor_tiling, a_tiles)
    m = policies.tile_mean(actor_w, a_tiles)
    u = policies.gaussian_draw(m, rng_state) if sample else m
    total = 0.0
    steps = 0
    event = core.NO_EVENT
    r = policies.squash(u, core.MAX_TURN_RATE)
    arrays.copy_into(sa[:4], state)
    sa[4] = r
    tiles_mod.active_tiles(sa, critic_tiling, c_tiles)
    while True:
      q = actor_critic.critic_value(critic, c_tiles)
      core.euler_control(state, r, samples)
      steps += 1
      event, reward = core.global_outcome(samples, s.environment_gate_reward,
                                          s.environment_out_of_bounds_reward)
      total += reward
      done = event != core.NO_EVENT or steps >= s.environment_max_steps
      target = reward
      if not done or event == core.NO_EVENT:
        # The next action (also at a truncation, to bootstrap from it).
        tiles_mod.active_tiles(state, actor_tiling, a_next)
        m_next = policies.tile_mean(actor_w, a_next)
        u_next = policies.gaussian_draw(m_next, rng_state) if sample else m_next
        r_next = policies.squash(u_next, core.MAX_TURN_RATE)
        arrays.copy_into(sa[:4], state)
        sa[4] = r_next
        tiles_mod.active_tiles(sa, critic_tiling, c_next)
        target += actor_critic.critic_value(critic, c_next)
      if learn:
        actor_critic.learn(critic, c_tiles, ones, s.critic_alpha, target - q,
                           s.critic_trace_decay, actor_w, a_tiles, s.actor_alpha, q, u, m)
      if done:
        break
      arrays.copy_into(a_tiles, a_next)   # (s', a') is the next step's (s, a): its tiles are known
      arrays.copy_into(c_tiles, c_next)
      m = m_next
      u = u_next
      r = r_next
    record[episode, PASSED] = event == core.SUCCESS
    record[episode, STEPS] = steps
    record[episode, RETURN] = total


@dataclasses.dataclass(frozen=True)
class Actor(taskfile.Section):
  """[actor]: flat PGRL's policy, stepped along Q(s, a) psi."""
  learner: str = param("policy_gradient", "the actor", choices=("policy_gradient",))
  alpha: float = param(1e-4, "actor step size", low=0, low_open=True)
  tilings: int = param(9, "CMAC tilings", low=1)
  tiles: tuple = param((20, 20, 36, 5), "tiles per tiling over x, y, theta, theta_dot",
                       length=4, low=1)


@dataclasses.dataclass(frozen=True)
class Critic(taskfile.Section):
  """[critic]: linear over tiles of (state, r), learned by TD(lambda)."""
  learner: str = param("td_lambda", "the critic", choices=("td_lambda",))
  alpha: float = param(0.01, "critic step size", low=0, low_open=True)
  trace_decay: float = param(0.9, "TD(lambda)'s lambda", low=0, high=1, low_open=True)
  tilings: int = param(9, "CMAC tilings", low=1)
  tiles: tuple = param((5, 5, 36, 5, 30), "tiles per tiling over x, y, theta, theta_dot, r",
                       length=5, low=1)


@dataclasses.dataclass(frozen=True)
class Config:
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)
  actor: Actor = dataclasses.field(default_factory=Actor)
  critic: Critic = dataclasses.field(default_factory=Critic)


class ShipActorCritic(_ship.ShipAgent):
  """The actor-critic's arrays and generator, trained step by step or compiled."""

  name = "ship_actor_critic"
  Config = Config
  record_fields = ("passed", "steps", "return")
  tags = ("baseline",)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    actor, critic = self.config.actor, self.config.critic
    self.actor_coder = actor_coder(actor.tilings, actor.tiles)
    self.critic_coder = critic_coder(critic.tilings, critic.tiles)
    self.learner = learners.ActorCritic(self.actor_coder, self.critic_coder, core.MAX_TURN_RATE,
                                        actor.alpha, critic.alpha, critic.trace_decay)

  def state(self):
    lr = self.learner
    out = {"rng_state": self.rng_state, "actor_w": lr.actor_w}
    out.update({f"critic_{k}": v for k, v in lr.critic._asdict().items()})
    return out

  def compiled(self, episodes, learn, sample, start=None):
    lr = self.learner
    rows = np.zeros((episodes, N_RECORD))
    fixed = np.empty(0) if start is None else np.array(start, dtype=np.float64)
    train_actor_critic(episodes, learn, sample, self.rng_state, lr.actor_w, lr.actor_arrays,
                       lr.critic, lr.critic_arrays, settings(self.config), rows, fixed)
    return rows

  def graph(self):
    return flat_graph.flat_graph(self.learner,
                                 lambda call, obs: np.array(obs, dtype=np.float64), ["turn"],
                                 continuous=True)
