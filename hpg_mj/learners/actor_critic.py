"""Konda's actor-critic (SPEC section 4) as compiled rules over plain arrays, called
by the fused loop and the step-by-step learner alike.

The critic is linear over tiles of (state, action), learned by TD(lambda) on an
Eq. 3-style lazy trace (`eligibility`); the actor is a Gaussian-with-sigmoid
policy over its own tiles (plain weights), stepped along Q(s, a) psi(s, a).

The per-step rules are compiled with numba's `error_model="numpy"`: a division by
zero, which none of them can make, would give inf or nan instead of raising, and
without that raising branch numba drops most of the reference counting (atomic
operations) on the arrays they take. Nothing else changes: the same numbers, faster.
"""
import numba

from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies


@numba.njit(cache=True, error_model="numpy")
def choose(actor_w, actor_tiles, r_max, sample, rng_state):
  """The actor's choice in a state (its active tiles): (m, u, r) with m the mean over
  the tiles, u ~ Normal(m, 1) (u = m without sampling) and r the squashed action."""
  m = policies.tile_mean(actor_w, actor_tiles)
  u = policies.gaussian_draw(m, rng_state) if sample else m
  return m, u, policies.squash(u, r_max)


@numba.njit(cache=True, error_model="numpy", inline="always")
def critic_value(critic, tiles):
  """Q(s, a): the critic's parameters summed over the active tiles of (s, a)."""
  q = 0.0
  for k in range(tiles.shape[0]):
    q += el.parameter(critic, tiles[k])
  return q


@numba.njit(cache=True, error_model="numpy")
def learn(critic, critic_tiles, ones, alpha_critic, delta, trace_decay, actor_w, actor_tiles,
          alpha_actor, q, u, m):
  """One step of both, after the action a = (u, r) drawn around the actor's mean m:
    e <- lambda e + phi(s, a);  w_c <- w_c + alpha_critic * delta * e     (TD(lambda))
    theta <- theta + alpha_actor * Q(s, a) * psi(s, a),  psi = (u - m) phi / sum(phi)
  with delta = R + Q(s', a') - Q(s, a) and Q(s, a) the critic's value before the step."""
  el.add_score(critic, critic_tiles, ones)
  el.learn(critic, alpha_critic, delta, trace_decay)
  step = alpha_actor * q * (u - m) / actor_tiles.shape[0]
  for k in range(actor_tiles.shape[0]):
    actor_w[actor_tiles[k]] += step
