"""The ActorCritic kind: Konda's actor-critic (SPEC section 4). The actor is a
Gaussian-with-sigmoid policy over a CMAC of the node's features (plain weights),
stepped along Q(s, a) psi(s, a); the critic is linear over a CMAC of (the features,
the action r), learned by TD(lambda) on the actions taken (`learners.actor_critic`).
Its node's one child is a continuous primitive, whose value it draws.

Per step, a = (u, r) drawn in s and a' in s': delta = R + Q(s', a') - Q(s, a), with
no Q(s', a') at a terminal s' (a call cut short bootstraps from its s'); the next
step's a is that a'."""
import collections
import math

import numba
import numpy as np

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base
from hpg_mj.learners import actor_critic
from hpg_mj.learners import arrays
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import tiles as tiles_mod

Settings = collections.namedtuple("Settings", ("alpha_actor", "alpha_critic", "trace_decay",
                                               "r_max", "actor", "critic"))
Settings.__doc__ = """An ActorCritic's settings `P`: its step sizes, the critic's trace
decay, the largest action r_max, and `actor`, `critic` the coders' arrays
(`TileCoder.arrays`)."""
CRITIC_FIELDS = tuple(f"critic_{field}" for field in el.Trace._fields)
Learned = collections.namedtuple("Learned", ("actor_w",) + CRITIC_FIELDS)
Learned.__doc__ = """What an ActorCritic learns, saved by these names: the actor's
weights, and the critic's weights with their TD(lambda) trace in its lazy form
(`learners.eligibility`)."""
Scratch = collections.namedtuple("Scratch", ("tiles", "critic_tiles", "ones", "sa", "drawn"))
Scratch.__doc__ = """A node's scratch: the actor's active tiles of s (row 0) and s'
(row 1); the critic's of (s, a) and (s', a'); phi(s, a) of the critic's tiles (ones);
the critic's input (the features, then r); [m, u] of the action drawn in s."""


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _critic(L):
  return el.Trace(L.critic_theta, L.critic_zs, L.critic_y, L.critic_touched, L.critic_marked,
                  L.critic_count, L.critic_acc)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _draw(P, L, N, x, row, sample, rng):
  """a = (u, r) drawn in the state of features x: the actor's tiles into tiles[row],
  the critic's of (x, r) into critic_tiles[row]; returns (m, u, r)."""
  tiles_mod.active_tiles(x, P.actor, N.tiles[row])
  m, u, r = actor_critic.choose(L.actor_w, N.tiles[row], P.r_max, sample, rng)
  n = N.sa.shape[0] - 1
  for i in range(n):
    N.sa[i] = x[i]
  N.sa[n] = r
  tiles_mod.active_tiles(N.sa, P.critic, N.critic_tiles[row])
  return m, u, r


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def start(P, L, N):
  """A call begins: the critic's trace is cleared."""
  el.reset(_critic(L))                           # the critic's e <- 0


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def choose(P, L, N, x, n, rng, learn, sample):
  """The action r drawn from the actor in the state of features x (its mean when not
  `sample`), in [-r_max, r_max]."""
  m, u, r = _draw(P, L, N, x, 0, sample, rng)
  N.drawn[0] = m
  N.drawn[1] = u
  return r


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def observe(P, L, N, x, signal, done, terminal, n, rng, learn, sample):
  """The primitive returned R = signal in s' (features x): a' drawn in s' (none where
  s' is terminal), then, when learning, the critic's TD(lambda) step on delta =
  R + Q(s', a') - Q(s, a) and the actor's step along Q(s, a) psi(s, a). Returns a'
  (0 when `done`)."""
  critic = _critic(L)
  q = actor_critic.critic_value(critic, N.critic_tiles[0])
  target = signal
  m, u, r = 0.0, 0.0, 0.0
  if not terminal:
    m, u, r = _draw(P, L, N, x, 1, sample, rng)
    target += actor_critic.critic_value(critic, N.critic_tiles[1])
  if learn:
    actor_critic.learn(critic, N.critic_tiles[0], N.ones, P.alpha_critic, target - q,
                       P.trace_decay, L.actor_w, N.tiles[0], P.alpha_actor, q, N.drawn[1],
                       N.drawn[0])
  if done:
    return 0.0
  arrays.copy_into(N.tiles[0], N.tiles[1])
  arrays.copy_into(N.critic_tiles[0], N.critic_tiles[1])
  N.drawn[0] = m
  N.drawn[1] = u
  return r


class ActorCriticKind(base.LearnerKind):
  """Runs an `ActorCritic` block: a features learner drawing its node's one continuous
  primitive."""
  block = blocks.ActorCritic
  reads = "features"
  continuous = True

  def check(self, name, block, n_children, view_size):
    n = len(block.actor_coder.low)
    if view_size is not None and view_size != n:
      raise GraphError(f"subtask {name!r}: its view gives {view_size} numbers, its "
                       f"ActorCritic's actor_coder tiles {n}")
    if len(block.critic_coder.low) != n + 1:
      raise GraphError(f"subtask {name!r}: an ActorCritic's critic_coder tiles "
                       f"{len(block.critic_coder.low)} numbers; it must tile {n + 1}: the "
                       f"{n} the actor_coder tiles, then the action r")

  def size(self, block):
    return len(block.actor_coder.low)

  def settings(self, name, block, schedule=None):
    for field in ("alpha_actor", "alpha_critic", "trace_decay", "r_max"):
      value = getattr(block, field)
      if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
        raise GraphError(f"subtask {name!r}: ActorCritic.{field} = {value!r}: must be a "
                         "finite number >= 0")
    return Settings(float(block.alpha_actor), float(block.alpha_critic),
                    float(block.trace_decay), float(block.r_max), block.actor_coder.arrays(),
                    block.critic_coder.arrays())

  def learned(self, block, n_children):
    return Learned(np.zeros(block.actor_coder.size), *el.new_trace(block.critic_coder.size))

  def parameters(self, learned):
    """The actor's weights; the critic's with its pending TD(lambda) updates applied."""
    return {"actor_w": learned.actor_w.copy(), "critic_theta": el.parameters(_critic(learned))}

  def scratch(self, block, n_children):
    k, kc = block.actor_coder.n_tilings, block.critic_coder.n_tilings
    return Scratch(np.zeros((2, k), dtype=np.int64), np.zeros((2, kc), dtype=np.int64),
                   np.ones(kc), np.zeros(len(block.critic_coder.low)), np.zeros(2))

  start, choose, observe = staticmethod(start), staticmethod(choose), staticmethod(observe)
