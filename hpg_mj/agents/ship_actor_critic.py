"""Konda's actor-critic on the full ship task (SPEC section 4): the flat PGRL
actor (a Gaussian-with-sigmoid policy over its CMAC), stepped along
Q_critic(s, a) * psi(s, a); the critic is linear over 9 tilings of
5 x 5 x 36 x 5 x 30 = 135,000 tiles of (x, y, theta, theta_dot, r), learned by
TD(lambda) (SARSA-style on the actions taken). Acts every 0.6 s with SPEC
section 2's rewards. A baseline of the hierarchy (tag "baseline").

The agent is its Config and a one-node graph of blocks (`blocks.ActorCritic`), which
the open machine (`hierarchy.program`) runs on both paths. Per step, with a = (u, r) drawn from the
actor in s and a' in s': delta = R + Q(s', a') - Q(s, a) (no Q(s', a') at a
terminal state), then `learners.actor_critic.learn`.
"""
import dataclasses

from hpg_mj.agents import _ship
from hpg_mj.agents import hierarchy
from hpg_mj import taskfile
from hpg_mj.taskfile import param
from hpg_mj.agents.ship_flat_pg import actor_coder
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import Primitive, Subtask, TaskGraph
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core as core

def critic_coder(n_tilings=9, tiles=(5, 5, 36, 5, 30)):
  """The critic's CMAC over (x m, y m, heading deg, turning rate deg/s, action r deg/s):
  `n_tilings` tilings of `tiles` tiles along each, the heading wrapping round."""
  return tiles_mod.TileCoder(
      (0.0, 0.0, -180.0, -core.MAX_TURN_RATE, -core.MAX_TURN_RATE),
      (core.FIELD_SIZE, core.FIELD_SIZE, 180.0, core.MAX_TURN_RATE, core.MAX_TURN_RATE),
      tuple(tiles), (False, False, True, False, False), n_tilings)


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
  """The task file's schema: its sections [environment], [actor] and [critic]."""
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)
  actor: Actor = dataclasses.field(default_factory=Actor)
  critic: Critic = dataclasses.field(default_factory=Critic)


class ShipActorCritic(hierarchy.ShipHierarchy):
  """The actor-critic: a one-node graph whose learner is Konda's actor-critic, run by
  the open machine; its state by node name (`policy.actor_w`, `policy.critic_theta`,
  ...), its `parameters()` the actor's weights and the critic's with pending updates
  applied."""

  name = "ship_actor_critic"
  Config = Config
  record_fields = ("passed", "steps", "return")
  tags = ("baseline",)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    actor, critic = self.config.actor, self.config.critic
    self.actor_coder = actor_coder(actor.tilings, actor.tiles)
    self.critic_coder = critic_coder(critic.tilings, critic.tiles)
    self.learner = blocks.ActorCritic(self.actor_coder, self.critic_coder, actor.alpha,
                                      critic.alpha, critic.trace_decay, core.MAX_TURN_RATE)

  def graph(self):
    """One node over the whole task: the actor over the state's tiles, acting every
    0.6 s; the critic over (state, r)."""
    return TaskGraph("policy", [
        Subtask("policy", children=["turn"], learner=self.learner,
                view=blocks.StateTiles(self.actor_coder), termination=blocks.Never()),
        Primitive("turn"),
    ])
