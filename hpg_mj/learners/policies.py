"""The two policy forms of the paper, over Eq. 3 traces (see `eligibility`).

* Tabular softmax (Gibbs), one parameter per (state, child): the taxi's HPG.
* Gaussian with sigmoid over a CMAC (SPEC section 3): m = sum(theta_i phi_i) / sum(phi_i),
  u ~ Normal(m, 1), r = r_max * (2 * sigmoid(u) - 1); score psi = (u - m) * phi / sum(phi);
  optionally with a baseline b(s) linear over the same tiles (`subtract_baseline`).

Each `act` samples an action with the shared generator and adds the action's
score to the trace at once (Algorithm 1, line 14: z <- z + psi(s, a, theta_k)); the
caller then applies R + G with `eligibility.learn` when the child returns. Each
takes the subtask's `eligibility.Trace` as one argument.

The per-step rules are compiled with numba's `error_model="numpy"`: a division by
zero, which none of them can make, would give inf or nan instead of raising, and
without that raising branch numba drops most of the reference counting (atomic
operations) on the arrays they take. Nothing else changes: the same numbers, faster.

The small rules a fused loop calls every step (`subtract_baseline`, `learn_baseline`,
`log_width`) are inlined: a compiled function that calls another, not inlined, one
takes a reference to every array it was given on entry and drops it on return, since
numba cannot prove the call does not raise; for a rule taking two traces that is some
40 atomic operations a step. Measured (perf): 24% of the stand-alone subtask's step
with the learned width; inlined, its steps/s rose ~1.3x, the hybrid's ~1.14x, with the
same numbers bit for bit and no longer compile.
"""
import math

import numba
from numba import types
from numba.extending import overload

from hpg_mj.learners import eligibility as el
from hpg_mj.learners import rng


@numba.njit(cache=True, error_model="numpy", inline="always")
def softmax_probabilities(t, state, n_actions, mask, probs):
  """pi(state, .) over the actions allowed by `mask` (others get probability 0)."""
  base = state * n_actions
  top = -math.inf
  for a in range(n_actions):
    if mask[a]:
      v = el.parameter(t, base + a)
      if v > top:
        top = v
  total = 0.0
  for a in range(n_actions):
    if mask[a]:
      p = math.exp(el.parameter(t, base + a) - top)
      probs[a] = p
      total += p
    else:
      probs[a] = 0.0
  for a in range(n_actions):
    probs[a] /= total


@numba.njit(cache=True, error_model="numpy", inline="always")
def sample_index(probs, u):
  """Inverse-CDF sample from `probs` with a uniform `u`; never an action of probability 0."""
  c = 0.0
  last = -1
  for a in range(probs.shape[0]):
    if probs[a] > 0.0:
      c += probs[a]
      last = a
      if u < c:
        return a
  return last


@numba.njit(cache=True, error_model="numpy", inline="always")
def softmax_act(t, state, n_actions, mask, rng_state, probs, index, psi, score=True):
  """Samples a child from the Gibbs policy and (unless `score` is False) adds its
  score to the trace.

  psi(s, a)[s, b] = 1{b = a} - pi(s, b) for the allowed b (zero elsewhere).
  `probs`, `index`, `psi` are scratch arrays of length n_actions.
  """
  softmax_probabilities(t, state, n_actions, mask, probs)
  a = sample_index(probs, rng.uniform(rng_state))
  if score:
    n = 0
    for b in range(n_actions):
      if mask[b]:
        index[n] = state * n_actions + b
        psi[n] = (1.0 if b == a else 0.0) - probs[b]
        n += 1
    el.add_score(t, index[:n], psi[:n])
  return a


@numba.njit(cache=True, error_model="numpy", inline="always")
def softmax_greedy(t, state, n_actions, mask):
  """The most probable allowed child (lowest index on ties)."""
  best = -1
  top = -math.inf
  for a in range(n_actions):
    if mask[a]:
      v = el.parameter(t, state * n_actions + a)
      if v > top:
        top = v
        best = a
  return best


# The Eq. 3 step of a Gibbs table with its baseline b(s), one value per state (the
# taxi's HPG): what a subtask does when it chooses, and when its child returns R.

@numba.njit(cache=True, error_model="numpy", inline="always")
def softmax_choose(t, values, state, n_actions, mask, alpha, learn, sample, rng_state, probs,
                   index, psi):
  """A child in `state` among those `mask` allows: learning, drawn with its score
  added to the trace (`softmax_act`), then theta <- theta - alpha b(s) psi(s, a), the
  baseline's part of the update (nothing when b(s) = 0); sampling, drawn; else the
  most probable. `probs`, `index`, `psi`: scratch of n_actions. (Its locals are named
  apart from its callers': numba's inlining once bound a local `n` here to a caller's
  `n` passed as n_actions, and the baseline's loop ran over nothing.)"""
  if learn or sample:
    a = softmax_act(t, state, n_actions, mask, rng_state, probs, index, psi, learn)
    if learn:
      amount = alpha * values[state]
      if amount != 0.0:
        k = 0
        for b in range(n_actions):
          if mask[b]:
            t.theta[index[k]] -= amount * psi[k]
            k += 1
    return a
  return softmax_greedy(t, state, n_actions, mask)


@numba.njit(cache=True, error_model="numpy", inline="always")
def softmax_learn(t, values, state, next_state, alpha, gamma, beta, signal, done):
  """The child chosen in `state` returned R = `signal`: Eq. 3's theta <- theta +
  alpha R z, z <- gamma z, and the baseline's TD(0) step b(s) <- b(s) + beta (R +
  b(s') - b(s)), b(s') = 0 when the call ended."""
  el.learn(t, alpha, signal, gamma)
  if beta != 0.0:
    target = signal
    if not done:
      target += values[next_state]
    values[state] += beta * (target - values[state])


@numba.njit(cache=True, error_model="numpy", inline="always")
def gaussian_mean(t, tiles):
  """m = sum(theta_i phi_i) / sum(phi_i) over the active tiles (phi binary)."""
  total = 0.0
  for k in range(tiles.shape[0]):
    total += el.parameter(t, tiles[k])
  return total / tiles.shape[0]


@numba.njit(cache=True, error_model="numpy", inline="always")
def squash(u, r_max):
  """r = r_max * (2 * sigmoid(u) - 1) = r_max * tanh(u / 2)."""
  return r_max * math.tanh(0.5 * u)


@numba.njit(cache=True, error_model="numpy", inline="always")
def tile_mean(w, tiles):
  """m over the active tiles of plain weights (no pending trace)."""
  total = 0.0
  for k in range(tiles.shape[0]):
    total += w[tiles[k]]
  return total / tiles.shape[0]


@numba.njit(cache=True, error_model="numpy", inline="always")
def gaussian_draw(m, rng_state):
  """u ~ Normal(m, 1)."""
  return m + rng.normal(rng_state)


@numba.njit(cache=True, error_model="numpy", inline="always")
def gaussian_act(t, tiles, r_max, rng_state, psi):
  """Samples u ~ Normal(m, 1), adds psi = (u - m) phi / sum(phi) to the trace,
  and returns the action r. `psi` is scratch of the length of `tiles`. Inlined: its
  caller (the machine's Gaussian choice, compiled once) then reads the trace's rows
  in place; called, it took them as ~60 numbers a step (flat PGRL's machine and
  learner code then took about a quarter more time a step)."""
  m = gaussian_mean(t, tiles)
  u = gaussian_draw(m, rng_state)
  g = (u - m) / tiles.shape[0]
  for k in range(tiles.shape[0]):
    psi[k] = g
  el.add_score(t, tiles, psi)
  return squash(u, r_max)


@numba.njit(cache=True, error_model="numpy")
def gaussian_greedy(t, tiles, r_max):
  """The policy's mode: r at u = m."""
  return squash(gaussian_mean(t, tiles), r_max)


# REINFORCE's baseline for the CMAC policy (Williams 1992; a declared departure from
# Eq. 3, as the taxi's, `softmax_choose`): with the trace discounted by
# gamma, Eq. 3 moves theta along psi_j times the discounted reward-to-go G_j of each
# choice j; the baseline makes that G_j - b(s_j), one extra step at the choice,
# theta <- theta - alpha b(s_j) psi_j. b is linear over the policy's tiles, b(s) = the
# mean of `values` over the active tiles, learned by TD(0) on the subtask's own R + G.
# b(s) does not depend on the action, so the gradient stays unbiased; it removes
# the noise of calls whose reward-to-go is large and of one sign whatever the action.

@numba.njit(cache=True, error_model="numpy", inline="always")
def subtract_baseline(theta, values, tiles, alpha, psi):
  """theta <- theta - alpha b(s) psi for the choice just made in s (tiles, psi as
  left by `gaussian_act`). Nothing when b(s) = 0."""
  amount = alpha * tile_mean(values, tiles)
  if amount != 0.0:
    for k in range(tiles.shape[0]):
      theta[tiles[k]] -= amount * psi[k]


@numba.njit(cache=True, error_model="numpy", inline="always")
def learn_baseline(values, tiles, beta, signal, gamma, next_value):
  """TD(0): b(s) <- b(s) + beta (signal + gamma b(s') - b(s)); next_value = b(s'),
  0 when the call ended. Each active tile moves by beta * delta, so b(s) does too."""
  delta = signal + gamma * next_value - tile_mean(values, tiles)
  for k in range(tiles.shape[0]):
    values[tiles[k]] += beta * delta


# The Eq. 3 step of a subtask over a CMAC, with its baseline (SPEC section 3): what a
# subtask does when it chooses, and when its child returns R + G. Every path that
# runs such a subtask calls these two.

def _no_width(width):
  """Whether a width argument is absent (None, or left out): typed at compile time."""
  return isinstance(width, (types.NoneType, types.Omitted))


def _width_draw(t, width, tiles, r_max, log_sigma_low, log_sigma_high, rng_state, psi,
                psi_width):
  """u ~ Normal(m, sigma(s)^2) with a learned width (`gaussian_width_act`); returns r.
  Typed by the width: without one (never called then) a stand-in. `gaussian_act` is
  not in here but in `gaussian_choose`: numba compiles an overload's code on its own as
  well, and the inlined `gaussian_act` cost ~1 s of the hybrid's first compile so."""


@overload(_width_draw, inline="always")
def _width_draw_typed(t, width, tiles, r_max, log_sigma_low, log_sigma_high, rng_state, psi,
                      psi_width):
  if _no_width(width):
    return lambda t, width, tiles, r_max, log_sigma_low, log_sigma_high, rng_state, psi, \
        psi_width: 0.0
  return lambda t, width, tiles, r_max, log_sigma_low, log_sigma_high, rng_state, psi, \
      psi_width: gaussian_width_act(t, width, tiles, r_max, log_sigma_low, log_sigma_high,
                                    rng_state, psi, psi_width)


def _width_baseline(width, values, tiles, width_alpha, psi_width):
  """The baseline's step on a learned width (`subtract_baseline`); nothing without one."""


@overload(_width_baseline, inline="always")
def _width_baseline_typed(width, values, tiles, width_alpha, psi_width):
  if _no_width(width):
    return lambda width, values, tiles, width_alpha, psi_width: None

  def step(width, values, tiles, width_alpha, psi_width):
    if width_alpha != 0.0:
      subtract_baseline(width.theta, values, tiles, width_alpha, psi_width)
  return step


def _width_learn(width, width_alpha, signal, gamma):
  """Eq. 3 on a learned width's trace; nothing without one."""


@overload(_width_learn, inline="always")
def _width_learn_typed(width, width_alpha, signal, gamma):
  if _no_width(width):
    return lambda width, width_alpha, signal, gamma: None

  def learn(width, width_alpha, signal, gamma):
    if width_alpha != 0.0:
      el.learn(width, width_alpha, signal, gamma)
  return learn


# Both inlined (the width's parts chosen by type, above): called, each took ~15 arrays
# and counted a reference to each, on every step of every Gaussian subtask; inlined
# into the machine (compiled without reference counting), flat PGRL's steps/s rose
# ~1.2x with the same numbers bit for bit.

@numba.njit(cache=True, error_model="numpy", inline="always")
def gaussian_choose(t, values, tiles, psi, alpha, beta, r_max, learn, sample, rng_state,
                    width=None, psi_width=None, width_alpha=0.0, log_sigma_low=0.0,
                    log_sigma_high=0.0):
  """Algorithm 1, choose a: u ~ Normal(m, 1) with its score added to z
  (`gaussian_act`) and, with a baseline (beta != 0) while learning, theta <- theta -
  alpha b(s) psi; without sampling, the mode. Returns the action r. With a learned
  width (its trace `width`, scratch `psi_width`, width_alpha != 0): u ~ Normal(m,
  sigma(s)^2) (`gaussian_width_act`), and the baseline's step on the width too."""
  if sample:
    if width is None or width_alpha == 0.0:
      r = gaussian_act(t, tiles, r_max, rng_state, psi)
    else:
      r = _width_draw(t, width, tiles, r_max, log_sigma_low, log_sigma_high, rng_state, psi,
                      psi_width)
    if learn and beta != 0.0:
      subtract_baseline(t.theta, values, tiles, alpha, psi)
      _width_baseline(width, values, tiles, width_alpha, psi_width)
    return r
  return gaussian_greedy(t, tiles, r_max)


@numba.njit(cache=True, error_model="numpy", inline="always")
def gaussian_learn(t, values, tiles, next_tiles, alpha, gamma, beta, signal, done, width=None,
                   width_alpha=0.0):
  """Algorithm 1, the child returned R + G = `signal`: Eq. 3 (theta <- theta + alpha
  (R + G) z, then z <- gamma z; the same on a learned width's trace) and the
  baseline's TD(0) step with b(s') over `next_tiles` (0 when the call is `done`)."""
  el.learn(t, alpha, signal, gamma)
  _width_learn(width, width_alpha, signal, gamma)
  if beta != 0.0:
    next_value = 0.0 if done else tile_mean(values, next_tiles)
    learn_baseline(values, tiles, beta, signal, gamma, next_value)


# A learned exploration width (SPEC section 8, the paper's future work; a new rule
# beside `gaussian_act`, which stays the paper's sigma = 1). The width is linear in
# log space over the same tiles: log sigma(s) = the mean of `width.theta` over the
# active tiles, clipped to [log_sigma_low, log_sigma_high], and learned by Eq. 3 on
# its own trace `width` with the score of log N(u; m, sigma) (Williams 1992):
#   d/dtheta_i   log pi = (u - m) / sigma^2 * phi_i / sum(phi)
#   d/dwidth_i   log pi = ((u - m)^2 / sigma^2 - 1) * phi_i / sum(phi)
# (0 where the clip is active: the clipped width does not move with width_i).
# At width weights 0 and a clip around 0, sigma = 1 and the mean's score is the
# paper's psi exactly.

@numba.njit(cache=True, error_model="numpy", inline="always")
def log_width(width, tiles, log_sigma_low, log_sigma_high):
  """(log sigma(s), whether the clip is inactive) over the active tiles."""
  v = gaussian_mean(width, tiles)
  if v < log_sigma_low:
    return log_sigma_low, False
  if v > log_sigma_high:
    return log_sigma_high, False
  return v, True


@numba.njit(cache=True, error_model="numpy")
def gaussian_width_act(t, width, tiles, r_max, log_sigma_low, log_sigma_high, rng_state, psi,
                       psi_width):
  """Samples u ~ Normal(m, sigma(s)^2); adds the mean's score to the trace `t` and
  log sigma's score to the trace `width` (see above); returns the action r.
  `psi`, `psi_width` are scratch of the length of `tiles` (left holding the scores)."""
  m = gaussian_mean(t, tiles)
  ls, free = log_width(width, tiles, log_sigma_low, log_sigma_high)
  sigma = math.exp(ls)
  u = m + sigma * rng.normal(rng_state)
  z = (u - m) / sigma
  n = tiles.shape[0]
  g = z / sigma / n
  h = (z * z - 1.0) / n if free else 0.0
  for k in range(n):
    psi[k] = g
    psi_width[k] = h
  el.add_score(t, tiles, psi)
  el.add_score(width, tiles, psi_width)
  return squash(u, r_max)
