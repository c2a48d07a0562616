"""What the ladder's planners share (`hpg_mj.planners`, `hpg_mj.planners_harbour`): how
far aim points stay inside a gate's posts, the first turns each search tries before its
helmsman, and the grid stencil of the Dijkstra fields (the current's least time, the
harbour's distance)."""
import math

import numba
import numpy as np

from hpg_mj.worlds import ship_core as core

INSET_M = 2.0                  # aim points stay this far inside a gate's posts
FIRST_TURNS = np.arange(2, 35, 2, dtype=np.int64)   # full rudder one way for 2..34 steps,
BACK_TURNS = np.array([0, 6], dtype=np.int64)       # then the other way for 0 or 6


def stencil(reach=3):
  """Grid steps (dx, dy) with |dx|, |dy| <= reach and no common divisor: 32 headings
  for reach 3, at most 18.4 degrees apart."""
  rows = [(dx, dy) for dx in range(-reach, reach + 1) for dy in range(-reach, reach + 1)
          if (dx, dy) != (0, 0) and math.gcd(abs(dx), abs(dy)) == 1]
  return np.array(rows, dtype=np.int64)


STENCIL = stencil()


@numba.njit(cache=True, inline="always")
def first_turn_rate(steps, sign, first, back):
  """The first turns' r at `steps` (full rudder `sign` for `first` steps, then the other
  way for `back`), or NaN after them."""
  if steps < first:
    return sign * core.MAX_TURN_RATE
  if steps < first + back:
    return -sign * core.MAX_TURN_RATE
  return np.nan


@numba.njit(cache=True, inline="always")
def down_gradient_rate(state, hx, hy, gx, gy):
  """r to head 100 m along (hx, hy), a field's falling gradient at the ship; straight at
  (gx, gy) where that gradient is not defined (zero, or not finite)."""
  norm = math.hypot(hx, hy)
  if norm == 0.0 or not math.isfinite(norm):
    return core.pilot_turn_rate(state, gx, gy)
  x, y = state[0], state[1]
  return core.pilot_turn_rate(state, x + 100.0 * hx / norm, y + 100.0 * hy / norm)
