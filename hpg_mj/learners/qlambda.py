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

The `tiled_*` functions are the same learner with linear function approximation
over binary features (Sutton & Barto 2018, sections 9.5.4 and 12.10): a state is
the list of its active tiles, one per tiling (`tiles.active_tiles`), Q(s, a) is the
sum of the weights q[tile * n_actions + a] over them, and each backup moves every
weight of (s, a) by alpha / n_tilings * delta, so a visited state moves by alpha *
delta, as a table's entry does, and its neighbours, which share some of its tiles,
move part of the way. One tiling of non-overlapping tiles is the table.
"""
import numba
import numpy as np

from hpg_mj.learners import rng

_DROP_BELOW = 1e-12


def new_trace(capacity: int):
  """An empty trace of `capacity` entries: (tr_index, tr_value, tr_count)."""
  return (np.zeros(capacity, dtype=np.int64), np.zeros(capacity),
          np.zeros(1, dtype=np.int64))


@numba.njit(cache=True)
def max_value(q, s, n_actions):
  """max_b Q(s, b) over the table `q`."""
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
  """An action in state s: uniform with probability `epsilon`, else greedy (ties
  broken at random)."""
  if rng.uniform(rng_state) < epsilon:
    return rng.randint(rng_state, n_actions)
  return greedy(q, s, n_actions, rng_state)


@numba.njit(cache=True)
def clear(tr_count):
  """Empties the trace (e <- 0)."""
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
  _set_replacing(tr_index, tr_value, tr_count, s * n_actions, n_actions, entry)
  for k in range(tr_count[0]):
    q[tr_index[k]] += alpha * delta * tr_value[k]
  _carry_trace(tr_index, tr_value, tr_count, next_is_greedy, gamma_tau * lam)
  return delta


# The SMDP step over a table and over tiles: two functions, not one typed by its state
# through an `overload`: numba compiles an overload's implementation on its own, with
# all it calls linked in and optimized again, even where it is inlined (~0.3 s of the
# hybrid's first train, whose root has a table). Inlined: called, each was one more
# library that relinked the learner's code below it (`hierarchy.kinds.base`).

@numba.njit(cache=True, inline="always")
def smdp_step(table, n_actions, s, a, signal, s_next, done, terminal, epsilon, alpha,
              gamma_tau, lam, learn, rng_state):
  """The root's SMDP step (SPEC section 3) when its child returns R = `signal` in s',
  on a table (s, s' integers): unless the call is `done`, the next choice a'
  (epsilon-greedy in s'); then, learning, the backup of (s, a, R, s', a') (`update`),
  and the trace cleared when done. `table` = (q, trace index, trace value, trace
  count). Returns a' (0, and no draw, when done)."""
  q, tr_index, tr_value, tr_count = table
  a_next = 0
  if not done:
    a_next = epsilon_greedy(q, s_next, n_actions, epsilon, rng_state)
  if learn:
    update(q, n_actions, tr_index, tr_value, tr_count, s, a, signal, s_next, a_next, terminal,
           alpha, gamma_tau, lam)
    if done:
      clear(tr_count)
  return a_next


@numba.njit(cache=True, inline="always")
def tiled_smdp_step(table, stride, tiles, a, signal, tiles_next, n_next, done, terminal,
                    epsilon, alpha, gamma_tau, lam, learn, rng_state):
  """`smdp_step` over tiles (s, s' their active tiles, s' offering its first `n_next`
  of the `stride` actions; `tiled_epsilon_greedy`, `tiled_update`)."""
  q, tr_index, tr_value, tr_count = table
  a_next = 0
  if not done:
    a_next = tiled_epsilon_greedy(q, tiles_next, stride, n_next, epsilon, rng_state)
  if learn:
    tiled_update(q, stride, tr_index, tr_value, tr_count, tiles, a, signal, tiles_next, n_next,
                 a_next, terminal, alpha, gamma_tau, lam)
    if done:
      clear(tr_count)
  return a_next


@numba.njit(cache=True, inline="always")
def _carry_trace(tr_index, tr_value, tr_count, next_is_greedy, decay):
  """After a backup: e <- decay * e if a' is greedy in s' (dropping what has decayed
  to nothing), else e <- 0 (Watkins's cut)."""
  if not next_is_greedy:
    tr_count[0] = 0
    return
  n = 0
  for k in range(tr_count[0]):
    v = tr_value[k] * decay
    if v > _DROP_BELOW:
      tr_index[n] = tr_index[k]
      tr_value[n] = v
      n += 1
  tr_count[0] = n


@numba.njit(cache=True, inline="always")
def _set_replacing(tr_index, tr_value, tr_count, base, n_actions, entry):
  """Replacing traces on one state (or tile): e(entry) = 1, its other actions 0."""
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


# ---- over tiles: linear function approximation (see the module's docstring) ----------
# `stride` is the number of actions the weights hold per tile; `n` (<= stride) how
# many of them, the first n, a state offers (an option's initiation set: the others
# are neither chosen nor maximised over there).

@numba.njit(cache=True)
def tiled_value(q, tiles, stride, a):
  """Q(s, a) for the state whose active tiles are `tiles`."""
  v = 0.0
  for k in range(tiles.shape[0]):
    v += q[tiles[k] * stride + a]
  return v


@numba.njit(cache=True)
def tiled_max(q, tiles, stride, n):
  """max_b Q(s, b) over the first `n` actions, for the state whose active tiles are
  `tiles`."""
  best = tiled_value(q, tiles, stride, 0)
  for b in range(1, n):
    v = tiled_value(q, tiles, stride, b)
    if v > best:
      best = v
  return best


@numba.njit(cache=True)
def tiled_greedy(q, tiles, stride, n, rng_state):
  """A greedy action of the first `n`; ties are broken uniformly at random."""
  best = tiled_max(q, tiles, stride, n)
  ties = 0
  for b in range(n):
    if tiled_value(q, tiles, stride, b) == best:
      ties += 1
  pick = rng.randint(rng_state, ties) if ties > 1 else 0
  for b in range(n):
    if tiled_value(q, tiles, stride, b) == best:
      if pick == 0:
        return b
      pick -= 1
  return n - 1


@numba.njit(cache=True)
def tiled_epsilon_greedy(q, tiles, stride, n, epsilon, rng_state):
  """One of the first `n` actions in the state whose active tiles are `tiles`:
  uniform with probability `epsilon`, else greedy."""
  if rng.uniform(rng_state) < epsilon:
    return rng.randint(rng_state, n)
  return tiled_greedy(q, tiles, stride, n, rng_state)


@numba.njit(cache=True)
def tiled_update(q, stride, tr_index, tr_value, tr_count, tiles, a, reward, tiles_next,
                 n_next, a_next, terminal, alpha, gamma_tau, lam):
  """One SMDP Q(lambda) backup over tiles (`update` with Q linear in them, s' offering
  its first `n_next` actions); returns delta. The trace holds weights: each tile of s
  has e(tile, a) = 1 and its other actions 0 (replacing traces per feature)."""
  target = reward
  if not terminal:
    target += gamma_tau * tiled_max(q, tiles_next, stride, n_next)
  next_is_greedy = (not terminal) and tiled_value(q, tiles_next, stride, a_next) == \
      tiled_max(q, tiles_next, stride, n_next)
  delta = target - tiled_value(q, tiles, stride, a)
  for k in range(tiles.shape[0]):
    base = tiles[k] * stride
    _set_replacing(tr_index, tr_value, tr_count, base, stride, base + a)
  step = alpha / tiles.shape[0] * delta
  for k in range(tr_count[0]):
    q[tr_index[k]] += step * tr_value[k]
  _carry_trace(tr_index, tr_value, tr_count, next_is_greedy, gamma_tau * lam)
  return delta
