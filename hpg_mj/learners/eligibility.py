"""Equation 3, the paper's policy-gradient rule, with its eligibility trace.

The rule (paper, Eq. 3; Algorithm 1, lines 11-16; SPEC section 3), for a subtask
with parameters theta, trace z, and the reward R + G of each step:

    z <- 0                          when the subtask starts (or on a state of S*)
    z <- gamma z + psi              each step, psi the score of the action taken
    theta <- theta + alpha (R + G) z

`reset` is z <- 0, `add_score` is z <- z + psi, `learn` is the theta update
followed by z <- gamma z (gamma = 1: plain Eq. 3).

The lazy form. Applied literally, each step touches every non-zero of z, which
grows with the episode. Instead, with g_k = gamma^k and D_k = sum_{i<=k} alpha_i
(R + G)_i g_i, the parameters are kept as

    theta_true[i] = theta[i] + zs[i] * D - y[i],  zs = sum_j psi_j / g_j,
                                                 y  = sum_j (psi_j / g_j) D_{j-1},

so that a step touches only the entries of its own score (9 tiles for the CMAC),
and the pending updates are folded into theta when z is reset: amortised O(1)
per step. `parameter(trace, i)` reads theta_true[i].

A `Trace` holds the arrays: theta, zs, y: float64[n]; touched: int64[n] (the
indices with zs != 0 since the last fold, the first count[0] valid); marked:
bool[n]; count: int64[1]; acc: float64[2] = [D, g]. Compiled functions take the
whole trace as one argument.
"""
import collections

import numba
import numpy as np

# Below this trace scale the representation is folded (exactness: values grow as 1/g).
_RESCALE_BELOW = 1e-4
# A discounted trace entry that has decayed below this is dropped at a fold, so the
# list of live entries (and the cost of a fold) stays bounded however long the episode.
_DROP_BELOW = 1e-12

Trace = collections.namedtuple("Trace", ("theta", "zs", "y", "touched", "marked", "count",
                                         "acc"))
Trace.__doc__ = """Eq. 3's parameters and trace in the lazy form (the module
docstring): theta, zs, y float64[n]; touched int64[n]; marked bool[n]; count
int64[1]; acc float64[2] = [D, g]."""


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def trace_of(record):
  """The Trace of a record that holds its fields by name (a learner kind's learned
  arrays: the trace's, and more)."""
  return Trace(record.theta, record.zs, record.y, record.touched, record.marked, record.count,
               record.acc)


def new_trace(n_weights: int, initial=0.0) -> Trace:
  """The trace of a fresh Eq. 3 learner with `n_weights` parameters."""
  return Trace(theta=np.full(n_weights, float(initial)), zs=np.zeros(n_weights),
               y=np.zeros(n_weights), touched=np.zeros(n_weights, dtype=np.int64),
               marked=np.zeros(n_weights, dtype=np.bool_), count=np.zeros(1, dtype=np.int64),
               acc=np.array([0.0, 1.0]))


def parameters(t: Trace) -> np.ndarray:
  """theta with the pending updates applied (a copy); `t` a Trace or any record that
  holds its fields by name."""
  return t.theta + t.zs * t.acc[0] - t.y


@numba.njit(cache=True, inline="always")
def parameter(t, i):
  """The current value of theta_i."""
  return t.theta[i] + t.zs[i] * t.acc[0] - t.y[i]


@numba.njit(cache=True)
def fold(t, keep_trace):
  """Writes the pending updates into theta. With keep_trace the trace z itself
  survives (rescaling for gamma < 1); otherwise z is reset to 0 (Eq. 3, z <- 0)."""
  theta, zs, y, touched, marked, count, acc = t
  d = acc[0]
  g = acc[1]
  n = count[0]
  live = 0
  for k in range(n):
    i = touched[k]
    theta[i] += zs[i] * d - y[i]
    y[i] = 0.0
    if keep_trace:
      zs[i] *= g
      if abs(zs[i]) >= _DROP_BELOW:
        touched[live] = i
        live += 1
        continue
    zs[i] = 0.0
    marked[i] = False
  count[0] = live
  acc[0] = 0.0
  acc[1] = 1.0


@numba.njit(cache=True, inline="always")
def reset(t):
  """z <- 0 (the subtask starts, or a state of S* is reached)."""
  fold(t, False)


@numba.njit(cache=True, inline="always")
def add_score(t, index, psi):
  """z <- z + psi, for a score with non-zeros `psi` at `index`."""
  zs, y, touched, marked, count, acc = t.zs, t.y, t.touched, t.marked, t.count, t.acc
  d = acc[0]
  g = acc[1]
  for k in range(index.shape[0]):
    i = index[k]
    scaled = psi[k] / g
    zs[i] += scaled
    y[i] += scaled * d
    if not marked[i]:
      marked[i] = True
      touched[count[0]] = i
      count[0] += 1


@numba.njit(cache=True, inline="always")
def learn(t, alpha, r_plus_g, gamma):
  """theta <- theta + alpha (R + G) z (Eq. 3), then z <- gamma z for the next step."""
  acc = t.acc
  acc[0] += alpha * r_plus_g * acc[1]
  if gamma != 1.0:
    acc[1] *= gamma
    if acc[1] < _RESCALE_BELOW:
      fold(t, True)
