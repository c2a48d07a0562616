"""The ship hierarchy's pieces as compiled functions (SPEC section 3): the root's
abstract state (its 50 m cell) and which shared subtask sails a direction.

Shared by the step-by-step graph (hpg_mj.hierarchy.ship) and the hybrid's fused
compiled loop (hpg_mj.agents.ship_hybrid), so both see the same numbers. The
subtasks' and the full task's outcomes are the world's (`worlds.ship_core`).
"""
import numba

from hpg_mj.learners import rng
from hpg_mj.worlds import ship_core as core

ROOT_CELL_M = 50.0            # the root's 20 x 20 grid of 50 m cells
ROOT_GRID = 20
N_DIRECTIONS = 8
DIAGONAL = 0                  # low-level subtask ids
STRAIGHT = 1
R_MAX = core.MAX_TURN_RATE


@numba.njit(cache=True)
def root_cell(x, y):
  """The root's abstract state: the 50 m cell of (x, y), clamped to the field."""
  i = min(max(int(x // ROOT_CELL_M), 0), ROOT_GRID - 1)
  j = min(max(int(y // ROOT_CELL_M), 0), ROOT_GRID - 1)
  return i * ROOT_GRID + j


@numba.njit(cache=True)
def sample_start(rng_state, out):
  """A start of the full task (SPEC section 2), drawn in the order x, y, theta, theta_dot."""
  out[0] = rng.uniform_range(rng_state, 0.0, core.FIELD_SIZE)
  out[1] = rng.uniform_range(rng_state, 0.0, core.FIELD_SIZE)
  out[2] = core.wrap_deg(rng.uniform_range(rng_state, -180.0, 180.0))
  out[3] = rng.uniform_range(rng_state, -core.MAX_TURN_RATE, core.MAX_TURN_RATE)


@numba.njit(cache=True)
def sample_local_start(rng_state, direction, out):
  """A stand-alone call of the subtask of `direction` (SPEC section 8): at its local
  start, the heading and the turning rate uniform, drawn in that order."""
  out[0], out[1] = core.local_start(direction)
  out[2] = core.wrap_deg(rng.uniform_range(rng_state, -180.0, 180.0))
  out[3] = rng.uniform_range(rng_state, -core.MAX_TURN_RATE, core.MAX_TURN_RATE)


@numba.njit(cache=True)
def subtask_of(direction):
  """Which shared low-level subtask sails `direction` (0..7 = N..NW)."""
  return DIAGONAL if direction % 2 == 1 else STRAIGHT
