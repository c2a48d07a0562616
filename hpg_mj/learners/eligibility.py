"""Equation 3 with a lazily applied eligibility trace.

The rule (paper, Eq. 3; Algorithm 1 lines 11-16; SPEC section 3):
    z <- 0 when the subtask starts (or on a state of S*)
    z <- gamma * z + psi                      each step
    w <- w + alpha * (R + G) * z              each step

Applied literally, every step touches every non-zero of z, which grows with the
episode. Instead, with g_k = gamma^k and D_k = sum_{i<=k} alpha_i R_i g_i, the
weights are kept as
    w_true[i] = w[i] + zs[i] * D - y[i],   zs = sum_j psi_j / g_j,
                                          y  = sum_j (psi_j / g_j) * D_{j-1},
so a step touches only the entries of its own score (9 tiles for the CMAC),
and the trace is folded into w when it is reset: amortised O(1) per step.

A trace is a set of arrays (see `new_trace`):
  w, zs, y: float64[n]; touched: int64[n] (indices with zs != 0 since the last
  fold, the first `count[0]` valid); marked: bool[n]; count: int64[1];
  acc: float64[2] = [D, g].
"""
import numba
import numpy as np

# Below this trace scale the representation is folded (exactness: values grow as 1/g).
_RESCALE_BELOW = 1e-4
# A discounted trace entry that has decayed below this is dropped at a fold, so the
# list of live entries (and the cost of a fold) stays bounded however long the episode.
_DROP_BELOW = 1e-12


def new_trace(n_weights: int, initial=0.0):
  """Arrays of a fresh Eq. 3 learner with `n_weights` parameters."""
  return {
      "w": np.full(n_weights, float(initial)),
      "zs": np.zeros(n_weights),
      "y": np.zeros(n_weights),
      "touched": np.zeros(n_weights, dtype=np.int64),
      "marked": np.zeros(n_weights, dtype=np.bool_),
      "count": np.zeros(1, dtype=np.int64),
      "acc": np.array([0.0, 1.0]),
  }


@numba.njit(cache=True, inline="always")
def weight(w, zs, y, acc, i):
  """The current value of parameter i."""
  return w[i] + zs[i] * acc[0] - y[i]


@numba.njit(cache=True)
def fold(w, zs, y, touched, marked, count, acc, keep_trace):
  """Writes the pending updates into w. With keep_trace the trace z itself
  survives (rescaling for gamma < 1); otherwise z is reset to 0 (Eq. 3, z <- 0)."""
  d = acc[0]
  g = acc[1]
  n = count[0]
  live = 0
  for k in range(n):
    i = touched[k]
    w[i] += zs[i] * d - y[i]
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
def reset(w, zs, y, touched, marked, count, acc):
  """z <- 0 (the subtask starts, or a state of S* is reached)."""
  fold(w, zs, y, touched, marked, count, acc, False)


@numba.njit(cache=True, inline="always")
def add_score(zs, y, touched, marked, count, acc, index, psi):
  """z <- z + psi, for a score with non-zeros `psi` at `index`."""
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
def reward(w, zs, y, touched, marked, count, acc, alpha, signal, gamma):
  """w <- w + alpha * signal * z, then discount the trace by gamma for the next step."""
  acc[0] += alpha * signal * acc[1]
  if gamma != 1.0:
    acc[1] *= gamma
    if acc[1] < _RESCALE_BELOW:
      fold(w, zs, y, touched, marked, count, acc, True)
