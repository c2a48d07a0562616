"""The ship hierarchies' pieces as compiled functions: the paper's root's abstract
state (its 50 m cell, SPEC section 3), which shared subtask sails a direction, the
starts; and the route's targets, the aim subtask's state and its end (SPEC section
8, `agents.ship_beyond`), which the machine's ship blocks (`blocks.AimTiles`,
`blocks.TargetReached`) and the scorer's helmsman (`hpg_mj.benchmark`) run. The
full task's outcomes are the world's (`worlds.ship_core`).
"""
import collections
import math

import numba
import numpy as np

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


# ---- the patrol's root (SPEC section 8) ----------------------------------------------

@numba.njit(cache=True)
def n_root_cells(near_gate_m, near_gate_cell_m):
  """How many places the root tells apart: the 20 x 20 grid's 50 m cells, then,
  with `near_gate_m` > 0, the finer cells of the square of that half-width about
  the gate's centre (`root_state`)."""
  if near_gate_m <= 0.0:
    return ROOT_GRID ** 2
  side = int(round(2.0 * near_gate_m / near_gate_cell_m))
  return ROOT_GRID ** 2 + side * side


@numba.njit(cache=True)
def root_state(state, heading_sectors, near_gate_m=0.0, near_gate_cell_m=25.0):
  """The root's abstract state: where the ship is and, with `heading_sectors`
  n > 1, its heading in n equal sectors counted clockwise, sector 0 centred on
  south (-180 deg): place * n + sector. The place is the 50 m cell of (x, y)
  (`ship_root_cell`) or, inside the square of half-width `near_gate_m`
  about the gate's centre, a cell of `near_gate_cell_m` there (numbered after
  the 400 coarse ones): how far the ship is from a post decides whether a
  U-turn passes the gate again. n = 1 and `near_gate_m` 0 is the hybrid's root."""
  cell = root_cell(state[0], state[1])
  if near_gate_m > 0.0:
    x0 = 0.5 * (core.GATE[0, 0] + core.GATE[1, 0]) - near_gate_m
    y0 = 0.5 * (core.GATE[0, 1] + core.GATE[1, 1]) - near_gate_m
    side = int(round(2.0 * near_gate_m / near_gate_cell_m))
    i = int(np.floor((state[0] - x0) / near_gate_cell_m))
    j = int(np.floor((state[1] - y0) / near_gate_cell_m))
    if 0 <= i < side and 0 <= j < side:
      cell = ROOT_GRID ** 2 + i * side + j
  if heading_sectors == 1:
    return cell
  width = 360.0 / heading_sectors
  sector = int((core.wrap_deg(state[2] + 0.5 * width) + 180.0) // width) % heading_sectors
  return cell * heading_sectors + sector



# ---- the route's targets and its aim subtask (SPEC section 8) -----------------------

GATE_X = 0.5 * (core.GATE[0, 0] + core.GATE[1, 0])
GATE_Y = core.GATE[0, 1]
APPROACH_DX = (-100.0, 0.0, 100.0)   # approach points: x of the gate's middle + these
N_TARGETS = 1 + len(APPROACH_DX)     # the gate, then the approach points
DISTANCE_CLIP = 400.0                # the aim state's distance saturates here (m)
Targets = collections.namedtuple("Targets", ("inset_m", "approach_m", "radius_m"))
Targets.__doc__ = """The route's targets: the gate's posts moved in by `inset_m`, the
approach points `approach_m` before its line, a call ended within `radius_m` of its
target (all in m)."""
SHIPPED_TARGETS = Targets(2.0, 80.0, 15.0)


@numba.njit(cache=True)
def side_of(y):
  """Which side of the gate line a height lies on (the line itself counts as north)."""
  return 1.0 if y >= GATE_Y else -1.0


@numba.njit(cache=True)
def target_of(target, state, side, inset_m, approach_m):
  """The point that target number `target` is now. 0, *gate*: the point of the
  gate (its posts moved in by `inset_m`) nearest the ship, followed as the ship
  moves (a continuous target). 1-3, *approach*: fixed points `approach_m` before
  the gate line on the side `side` (of the call's start), at the gate's middle x +
  APPROACH_DX."""
  if target == 0:
    low = core.GATE[0, 0] + inset_m
    high = core.GATE[1, 0] - inset_m
    return min(max(state[0], low), high), GATE_Y
  return GATE_X + APPROACH_DX[target - 1], GATE_Y + side * approach_m


def error_coordinate(e_deg, error_scale):
  """A heading error's coordinate on the aim tiles ("sqrt" or "linear" scale)."""
  return 180.0 * math.sqrt(e_deg / 180.0) if error_scale == "sqrt" else float(e_deg)


@numba.njit(cache=True)
def aim_view(state, tx, ty, out, sqrt_error=False, reflect_at=180.0):
  """The aim subtask's state: heading error e to the target (deg, wrapped; with
  `sqrt_error` as 180 sign(e) sqrt(|e| / 180), still in [-180, 180], so that the
  tiles are finer near e = 0, where the ship holds its course), turning rate,
  distance (clipped at DISTANCE_CLIP). Returns the side, 1 or -1: with the error's
  coordinate below -`reflect_at`, the state is reflected about the line to the
  target, (e, turning rate) -> (-e, -turning rate), and the side is -1. Equation 1
  is symmetric under the reflection with r -> -r, so the policy's r times the side
  steers both sides of a large error with one set of tiles, each learning from
  the starts of both (the ship must turn the short way round; near e = 0, where
  it holds its course, both sides keep their own tiles: no fold there)."""
  e = core.wrap_deg(state[2] - core.bearing_deg(state[0], state[1], tx, ty))
  q = math.copysign(180.0 * math.sqrt(abs(e) / 180.0), e) if sqrt_error else e
  side = -1.0 if q < -reflect_at else 1.0
  out[0] = side * q
  out[1] = side * state[3]
  out[2] = min(math.hypot(tx - state[0], ty - state[1]), DISTANCE_CLIP)
  return side


@numba.njit(cache=True)
def aim_outcome(samples, state, target, tx, ty, steps_in_call, max_steps, radius_m, shaping):
  """After one control step inside an aim call towards target number `target` at
  (tx, ty): (event, G). SUCCESS through the gate, or (an approach point) within
  `radius_m` of it; FAILURE off the field, after `max_steps`, or (the gate) across
  the gate line beside the gate; G = the heading shaping towards the target (SPEC
  section 3's G, times `shaping`), +100 / -100."""
  event, _ = core.steer_event(samples, core.GATE, core.FIELD_SIZE)
  if event == core.NO_EVENT:
    for k in range(1, samples.shape[0]):
      if target == 0:
        if (samples[k - 1, 1] - GATE_Y) * (samples[k, 1] - GATE_Y) < 0.0:
          event = core.FAILURE                           # crossed the line, missed the gate
          break
      elif math.hypot(samples[k, 0] - tx, samples[k, 1] - ty) <= radius_m:
        event = core.SUCCESS
        break
    if event == core.NO_EVENT and steps_in_call >= max_steps:
      event = core.FAILURE
  internal = shaping * core.shaping_reward(state[0], state[1], state[2], tx, ty)
  if event == core.SUCCESS:
    internal += core.GATE_REWARD
  elif event == core.FAILURE:
    internal += core.OUT_OF_BOUNDS_REWARD
  return event, internal
