"""Watkins's Q(lambda) with replacing traces, as an SMDP (SPEC section 3).

Q is a float64[n_states * n_actions] table. The trace is a short list of
(entry, value) pairs: `tr_index` int64[cap], `tr_value` float64[cap],
`tr_count` int64[1]. On a transition (s, a, R, s', a') where R is the reward
summed over the child's run and a' the next choice (Sutton & Barto, Watkins's
Q(lambda)):
    delta = R + gamma_tau * max_b Q(s', b) - Q(s, a)      (no bootstrap if terminal)
    e(s, b) = 0 for b != a, e(s, a) = 1                   (replacing traces)
    Q += alpha * delta * e
    e *= gamma_tau * lambda if a' is greedy in s', else e = 0.
"""
import numba
import numpy as np

from hpg_mj.learners import rng

_DROP_BELOW = 1e-12


def new_trace(capacity: int):
  return (np.zeros(capacity, dtype=np.int64), np.zeros(capacity),
          np.zeros(1, dtype=np.int64))


@numba.njit(cache=True)
def max_value(q, s, n_actions):
  base = s * n_actions
  best = q[base]
  for b in range(1, n_actions):
    if q[base + b] > best:
      best = q[base + b]
  return best


@numba.njit(cache=True)
def greedy(q, s, n_actions, rng_state):
  """A greedy action; ties are broken uniformly at random."""
  best = max_value(q, s, n_actions)
  ties = 0
  for b in range(n_actions):
    if q[s * n_actions + b] == best:
      ties += 1
  pick = rng.randint(rng_state, ties) if ties > 1 else 0
  for b in range(n_actions):
    if q[s * n_actions + b] == best:
      if pick == 0:
        return b
      pick -= 1
  return n_actions - 1


@numba.njit(cache=True)
def epsilon_greedy(q, s, n_actions, epsilon, rng_state):
  if rng.uniform(rng_state) < epsilon:
    return rng.randint(rng_state, n_actions)
  return greedy(q, s, n_actions, rng_state)


@numba.njit(cache=True)
def clear(tr_count):
  tr_count[0] = 0


@numba.njit(cache=True)
def update(q, n_actions, tr_index, tr_value, tr_count, s, a, reward, s_next, a_next,
           terminal, alpha, gamma_tau, lam):
  """One SMDP Q(lambda) backup; returns delta."""
  target = reward
  if not terminal:
    target += gamma_tau * max_value(q, s_next, n_actions)
  # Is a' greedy in s'? (Decided on Q before this backup, as in Watkins's Q(lambda).)
  next_is_greedy = (not terminal) and q[s_next * n_actions + a_next] == max_value(
      q, s_next, n_actions)
  entry = s * n_actions + a
  delta = target - q[entry]
  # Replacing traces: this state's other actions are cleared, (s, a) set to 1.
  base = s * n_actions
  found = False
  for k in range(tr_count[0]):
    i = tr_index[k]
    if i == entry:
      tr_value[k] = 1.0
      found = True
    elif base <= i < base + n_actions:
      tr_value[k] = 0.0
  if not found:
    if tr_count[0] == tr_index.shape[0]:
      raise ValueError("Q(lambda): trace capacity exceeded")
    tr_index[tr_count[0]] = entry
    tr_value[tr_count[0]] = 1.0
    tr_count[0] += 1
  for k in range(tr_count[0]):
    q[tr_index[k]] += alpha * delta * tr_value[k]
  if not next_is_greedy:
    tr_count[0] = 0
    return delta
  decay = gamma_tau * lam
  n = 0
  for k in range(tr_count[0]):
    v = tr_value[k] * decay
    if v > _DROP_BELOW:
      tr_index[n] = tr_index[k]
      tr_value[n] = v
      n += 1
  tr_count[0] = n
  return delta
