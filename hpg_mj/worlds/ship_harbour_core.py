"""The harbour (SPEC section 11): `ship/steer`'s gate behind obstacles, islands and
piers, that end the episode when touched, and the rangefinders by which the ship sees
them, compiled (numba) and shared by every backend and path. Free of MuJoCo, as
`ship_core` is (SPEC section 9); the ship is the steering ship, the gate its gate.

Obstacles are fixed per level (`LEVELS`), not drawn per episode: a learner may learn the
map (the root of SPEC section 3's hierarchy over its 50 m cells can learn the way round
an island as a route of legs), the planner of the best known bound and the task page's
picture show the very task, and the starts are the steering task's. An *island* is a
circle, row `[x, y, radius]`; a *pier* a rectangle, row `[x0, y0, x1, y1, half_width]`
from one end of its centre line to the other. The compiled rules take them as two
arrays, `islands` (n, 3) and `piers` (m, 6) rows `[cx, cy, ux, uy, half_length,
half_width]` (`pier_frames`: the centre, the unit vector along it, its half sizes).

The rule (`harbour_event`): along each segment between two consecutive sampled
positions, in order, a crossing of the gate (`ship_core.segment_crosses`, SPEC
section 2) succeeds; a position off the field fails (FAILURE); a segment that touches
an obstacle (meets its shape, its boundary included: the ship is a point, as for the
gate and the bounds) runs aground (AGROUND), which ends the episode with the
out-of-bounds penalty. The first event in time wins.

The rangefinders (`ranges_into`): RAYS rays from the ship's position, in the water
plane, at BEARINGS_DEG from its heading (clockwise), each the distance to the first
obstacle along it, MAX_RANGE_M where none lies within MAX_RANGE_M ("nothing seen";
MuJoCo's rangefinder reads -1 there, `seen_ranges` maps it). From inside an obstacle
(the last position of a step that ran aground) a ray reads the way out, as MuJoCo's.
"""
import collections
import functools
import math

import numba
import numpy as np

from hpg_mj.worlds import ship_core as core

# The rays, clockwise from the ship's heading (deg), and how far they see (m): the
# forward half, where a ship that cannot stop or back meets what it hits. 150 m are
# 83 control steps of sailing, time to turn away from anything seen (a full turn
# takes about 24 s with the 5 s lag).
BEARINGS_DEG = (-90.0, -60.0, -30.0, 0.0, 30.0, 60.0, 90.0)
RAYS = len(BEARINGS_DEG)
# Each ray's direction is the heading's turned by its bearing: the sum formulas on the
# heading's one sine and cosine (a ship's step casts seven rays; 14 more sines and
# cosines were most of the batch's step).
_BEARING_SIN = np.array([math.sin(math.radians(b)) for b in BEARINGS_DEG])
_BEARING_COS = np.array([math.cos(math.radians(b)) for b in BEARINGS_DEG])
MAX_RANGE_M = 150.0
# How far behind the ship an obstacle must lie for the rays to skip it (`_behind`), in m.
_BEHIND_MARGIN_M = 1e-6
OBSERVATION_SIZE = 4 + RAYS

# level -> (islands [x, y, radius], piers [x0, y0, x1, y1, half_width]), in m. The gate
# is ship/steer's, (350, 400) - (450, 400). More and larger obstacles and tighter
# passages at each level.
LEVELS = {
    # Two islands in the way: one before the gate's northern approach, one south-east.
    "easy": (((400.0, 620.0, 60.0), (650.0, 230.0, 60.0)), ()),
    # A harbour mouth: breakwaters prolong the gate's line either way, so that the gate
    # is passed nearly square; four islands, one 150 m before each side of the mouth.
    "medium": (((400.0, 570.0, 60.0), (400.0, 220.0, 60.0), (720.0, 680.0, 70.0),
                (200.0, 780.0, 60.0)),
               ((180.0, 400.0, 340.0, 400.0, 6.0), (460.0, 400.0, 760.0, 400.0, 6.0))),
    # An enclosed harbour whose mouth lies in a walled pocket on either side: breakwaters
    # across the field up to 40 m from either edge, the gate the only way through the
    # middle; 50 m before it on either side a wall 260 m long, the pocket between them
    # closed at one end (the northern pocket is entered from the east, the southern from
    # the west), so the mouth is reached only by a channel and a quarter turn; piers
    # reaching out from the breakwaters, and four islands beyond. The episode also
    # closes (`TIME_LIMITS`).
    "hard": (((760.0, 780.0, 80.0), (180.0, 780.0, 70.0), (780.0, 180.0, 60.0),
              (180.0, 180.0, 60.0)),
             ((40.0, 400.0, 340.0, 400.0, 6.0), (460.0, 400.0, 960.0, 400.0, 6.0),
              (270.0, 450.0, 530.0, 450.0, 6.0), (270.0, 350.0, 530.0, 350.0, 6.0),
              (270.0, 406.0, 270.0, 450.0, 6.0), (530.0, 394.0, 530.0, 350.0, 6.0),
              (220.0, 406.0, 220.0, 560.0, 6.0), (580.0, 394.0, 580.0, 240.0, 6.0))),
}
DEFAULT_LEVEL = "easy"
# level -> the control steps after which the episode is truncated, or None: the
# environment's `max_steps` alone (`episode_steps`). The hard level closes after 1,000
# (10 minutes), as the current's and the regatta's: its pockets alone did not make it
# hard (flat PGRL, memorizing the fixed map, found the mouth on tuning seeds 0-2 after
# about 1,000 control steps and reached 69-76 normalized; the best known takes 284 at
# the median and 523 at most).
TIME_LIMITS = {"easy": None, "medium": None, "hard": 1000}

OUT_OF_BOUNDS_REWARD = core.OUT_OF_BOUNDS_REWARD   # also for touching an obstacle
GATE_REWARD = core.GATE_REWARD

# Event codes: `ship_core`'s, and an obstacle touched.
AGROUND = -3
EVENT_NAMES = {core.NO_EVENT: None, core.SUCCESS: "gate", core.FAILURE: "out_of_bounds",
               AGROUND: "obstacle"}
START_TRIES = 10_000


def level_obstacles(level, who="ship harbour"):
  """(islands, piers) of `level` as float64 arrays (`LEVELS`' rows), or a one-line error."""
  if not isinstance(level, str) or level not in LEVELS:
    raise ValueError(f"{who}: unknown level {level!r}; allowed levels: {list(LEVELS)}")
  islands, piers = LEVELS[level]
  return (np.array(islands, dtype=np.float64).reshape(-1, 3),
          np.array(piers, dtype=np.float64).reshape(-1, 5))



def episode_steps(level, max_steps=None):
  """The control steps a harbour episode at `level` runs at most: `max_steps` (None:
  `ship_core.STEER_MAX_STEPS`), or the level's time limit (`TIME_LIMITS`) where that is
  shorter."""
  level_obstacles(level)              # a one-line error for an unknown level
  return core.limited_steps(TIME_LIMITS[level], max_steps)

def pier_frames(piers):
  """Rows [cx, cy, ux, uy, half_length, half_width] of piers given end to end."""
  piers = np.asarray(piers, dtype=np.float64).reshape(-1, 5)
  out = np.empty((len(piers), 6))
  for k, (x0, y0, x1, y1, half_width) in enumerate(piers):
    length = math.hypot(x1 - x0, y1 - y0)
    out[k] = (0.5 * (x0 + x1), 0.5 * (y0 + y1), (x1 - x0) / length, (y1 - y0) / length,
              0.5 * length, half_width)
  return out


@functools.cache
def level_shapes(level):
  """(islands, pier frames) of `level`, read-only, made once a process."""
  islands, piers = level_obstacles(level)
  frames = pier_frames(piers)
  islands.setflags(write=False)
  frames.setflags(write=False)
  return islands, frames


CELL_M = 25.0                    # the grid of obstacles near each cell (`level_cells`)
CELLS = int(core.FIELD_SIZE / CELL_M)
_TOUCH_REACH_M = 4.0             # > a control step's sailing (1.8 m) and a step off the field


@functools.cache
def level_cells(level):
  """(2, CELLS, CELLS) int64 bit masks, read-only, of `level`'s obstacles (bit k: the k-th,
  islands first) that a ship in each 25 m cell may see within MAX_RANGE_M ([0]) or touch
  in one control step ([1]): the rays and the rule test those alone (most ships are near
  few obstacles or none). Cells are measured from their centres with the half diagonal
  and 2 m more (the last position of a step off the field lies in an edge cell)."""
  islands, piers = level_shapes(level)
  if len(islands) + len(piers) > 62:
    raise ValueError(f"ship harbour: level {level!r} has more than 62 obstacles")
  out = np.zeros((2, CELLS, CELLS), dtype=np.int64)
  slack = CELL_M * math.sqrt(0.5) + 2.0
  for i in range(CELLS):
    for j in range(CELLS):
      x, y = (i + 0.5) * CELL_M, (j + 0.5) * CELL_M
      for k in range(len(islands) + len(piers)):
        for which, reach in enumerate((MAX_RANGE_M, _TOUCH_REACH_M)):
          if _within(x, y, islands, piers, k, reach + slack):
            out[which, i, j] |= 1 << k
  out.setflags(write=False)
  return out


@numba.njit(cache=True, inline="always")
def _cell_mask(cells, which, x, y):
  """`level_cells`' mask `which` of the cell of (x, y), clamped onto the field's cells."""
  last = cells.shape[1] - 1
  i = min(max(int(math.floor(x / CELL_M)), 0), last)
  j = min(max(int(math.floor(y / CELL_M)), 0), last)
  return cells[which, i, j]


@numba.njit(cache=True, inline="always")
def may_touch(cells, x, y):
  """Whether a ship at (x, y) may touch an obstacle within one control step (its cell's
  mask, `level_cells`): where not, its track need not be looked at."""
  return _cell_mask(cells, 1, x, y) != 0


# ---- geometry: rays and segments against circles and rectangles ---------------------

@numba.njit(cache=True, error_model="numpy", inline="always")
def _circle_hits(px, py, dx, dy, island):
  """(t0, t1) where p + t d meets the circle `island` (|d| = 1), or (inf, inf)."""
  ox, oy = px - island[0], py - island[1]
  b = ox * dx + oy * dy
  c = ox * ox + oy * oy - island[2] * island[2]
  disc = b * b - c
  if disc < 0.0:
    return np.inf, np.inf
  root = math.sqrt(disc)
  return -b - root, -b + root


@numba.njit(cache=True, error_model="numpy", inline="always")
def _slab(o, d, half, t0, t1):
  """The slab |o + t d| <= half clipping [t0, t1]; t0 > t1 when it misses."""
  if d == 0.0:
    if abs(o) > half:
      return 1.0, 0.0
    return t0, t1
  a = (-half - o) / d
  b = (half - o) / d
  if a > b:
    a, b = b, a
  return max(t0, a), min(t1, b)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _box_hits(px, py, dx, dy, pier, t0, t1):
  """[t0, t1] clipped to where p + t d lies in the rectangle `pier` (a frame row);
  empty (t0 > t1) when it misses."""
  rx, ry = px - pier[0], py - pier[1]
  ux, uy = pier[2], pier[3]
  t0, t1 = _slab(rx * ux + ry * uy, dx * ux + dy * uy, pier[4], t0, t1)
  return _slab(rx * uy - ry * ux, dx * uy - dy * ux, pier[5], t0, t1)


@numba.njit(cache=True, error_model="numpy")
def ray_distance(px, py, dx, dy, islands, piers, max_range):
  """The distance along the unit ray p + t d (t >= 0) to the first obstacle, as MuJoCo's
  rangefinder measures it (the first surface crossed, the way out from inside one),
  or `max_range` where none lies within it."""
  best = max_range
  for k in range(islands.shape[0]):
    cx, cy, radius = islands[k, 0], islands[k, 1], islands[k, 2]
    if math.hypot(cx - px, cy - py) - radius >= best:   # too far to be seen
      continue
    t0, t1 = _circle_hits(px, py, dx, dy, islands[k])
    t = t0 if t0 >= 0.0 else t1
    if 0.0 <= t < best:
      best = t
  for k in range(piers.shape[0]):
    pier = piers[k]
    if math.hypot(pier[0] - px, pier[1] - py) - math.hypot(pier[4], pier[5]) >= best:
      continue
    t0, t1 = _box_hits(px, py, dx, dy, pier, -np.inf, np.inf)
    if t0 > t1:
      continue
    t = t0 if t0 >= 0.0 else t1
    if 0.0 <= t < best:
      best = t
  return best


@numba.njit(cache=True, error_model="numpy", inline="always")
def _touches(p0x, p0y, dx, dy, length2, islands, piers, k, margin):
  """Whether the segment from (p0x, p0y) by (dx, dy) (length2 its squared length) meets
  obstacle k (the islands first, then the piers) grown by `margin` m."""
  if k < islands.shape[0]:
    cx, cy, radius = islands[k, 0], islands[k, 1], islands[k, 2] + margin
    s = 0.0
    if length2 > 0.0:
      s = min(max(((cx - p0x) * dx + (cy - p0y) * dy) / length2, 0.0), 1.0)
    return math.hypot(p0x + s * dx - cx, p0y + s * dy - cy) <= radius
  pier = piers[k - islands.shape[0]]
  rx, ry = p0x - pier[0], p0y - pier[1]
  ux, uy = pier[2], pier[3]
  t0, t1 = _slab(rx * ux + ry * uy, dx * ux + dy * uy, pier[4] + margin, 0.0, 1.0)
  t0, t1 = _slab(rx * uy - ry * ux, dx * uy - dy * ux, pier[5] + margin, t0, t1)
  return t0 <= t1


@numba.njit(cache=True, error_model="numpy")
def segment_touches(p0x, p0y, p1x, p1y, islands, piers, margin):
  """Whether the segment p0-p1 meets an obstacle grown by `margin` m (0: the obstacle
  itself, its boundary included; a rectangle grows by `margin` on every side)."""
  dx, dy = p1x - p0x, p1y - p0y
  length2 = dx * dx + dy * dy
  for k in range(islands.shape[0] + piers.shape[0]):
    if _touches(p0x, p0y, dx, dy, length2, islands, piers, k, margin):
      return True
  return False


# ---- one control step: the rule, and what the ship sees ------------------------------

@numba.njit(cache=True, error_model="numpy", inline="always")
def _within(x, y, islands, piers, k, reach):
  """Whether (x, y) lies within `reach` m of obstacle k (the islands first, then the
  piers), on squared distances (no square root: every ship tests every obstacle at
  every step)."""
  if k < islands.shape[0]:
    dx, dy, grown = x - islands[k, 0], y - islands[k, 1], islands[k, 2] + reach
    return dx * dx + dy * dy <= grown * grown
  pier = piers[k - islands.shape[0]]
  rx, ry = x - pier[0], y - pier[1]
  qx = max(abs(rx * pier[2] + ry * pier[3]) - pier[4], 0.0)
  qy = max(abs(rx * pier[3] - ry * pier[2]) - pier[5], 0.0)
  return qx * qx + qy * qy <= reach * reach


@numba.njit(cache=True, error_model="numpy", inline="always")
def _near(samples, islands, piers, cells):
  """A bit mask of the obstacles within reach of a step's track (those nearer its first
  sample than its farthest sample is): the only ones its segments can touch."""
  candidates = _cell_mask(cells, 1, samples[0, 0], samples[0, 1])
  if candidates == 0:
    return 0
  reach2 = 0.0
  for k in range(1, samples.shape[0]):
    dx, dy = samples[k, 0] - samples[0, 0], samples[k, 1] - samples[0, 1]
    reach2 = max(reach2, dx * dx + dy * dy)
  reach = math.sqrt(reach2) * (1.0 + 1e-9) + 1e-9
  mask = 0
  for k in range(islands.shape[0] + piers.shape[0]):
    if candidates & (1 << k) and _within(samples[0, 0], samples[0, 1], islands, piers, k,
                                         reach):
      mask |= 1 << k
  return mask


@numba.njit(cache=True, error_model="numpy", inline="always")
def _segment_aground(x0, y0, x1, y1, near, islands, piers):
  """Whether the segment (x0, y0)-(x1, y1) touches one of the obstacles of bit mask
  `near` (`_near`; the islands first, then the piers)."""
  dx, dy = x1 - x0, y1 - y0
  length2 = dx * dx + dy * dy
  for k in range(islands.shape[0] + piers.shape[0]):
    if near & (1 << k) and _touches(x0, y0, dx, dy, length2, islands, piers, k, 0.0):
      return True
  return False


@numba.njit(cache=True, error_model="numpy", inline="always")
def track_aground(samples, islands, piers, cells):
  """Whether a segment between two consecutive sampled positions of one control step
  touches an obstacle (the module's rule without the gate and the field: the goal's
  obstacles, `ship_goal_core`)."""
  near = _near(samples, islands, piers, cells)
  if near:
    for k in range(1, samples.shape[0]):
      if _segment_aground(samples[k - 1, 0], samples[k - 1, 1], samples[k, 0], samples[k, 1],
                          near, islands, piers):
        return True
  return False


# Inlined, as `track_aground`: called for each ship of a batch, a compiled call took the
# ship's row of samples as a view, 30 ns a ship (the batch's judgement 2.5x slower).
@numba.njit(cache=True, error_model="numpy", inline="always")
def harbour_event(samples, islands, piers, cells):
  """(event, k) of one control step's sampled positions (the module's rule): SUCCESS at
  the gate, FAILURE off the field, AGROUND on touching an obstacle, the first in time;
  k the sample at which it happened (NO_EVENT, 0 when none)."""
  gate = core.GATE
  near = _near(samples, islands, piers, cells)   # mostly none: no segment tests at all
  for k in range(1, samples.shape[0]):
    x0, y0, x1, y1 = samples[k - 1, 0], samples[k - 1, 1], samples[k, 0], samples[k, 1]
    if core.segment_crosses(x0, y0, x1, y1, gate[0, 0], gate[0, 1], gate[1, 0], gate[1, 1]):
      return core.SUCCESS, k
    if x1 < 0.0 or x1 > core.FIELD_SIZE or y1 < 0.0 or y1 > core.FIELD_SIZE:
      return core.FAILURE, k
    if near and _segment_aground(x0, y0, x1, y1, near, islands, piers):
      return AGROUND, k
  return core.NO_EVENT, 0


@numba.njit(cache=True, error_model="numpy", inline="always")
def ship_outcome(samples, islands, piers, cells, steps, max_steps, gate_reward,
                 out_of_bounds_reward):
  """(event, reward, terminated, truncated) of one ship's control step, `steps` control
  steps in (this one counted): -1, `gate_reward` more at the gate,
  `out_of_bounds_reward` more off the field or on an obstacle; truncated after
  `max_steps`."""
  event, _ = harbour_event(samples, islands, piers, cells)
  reward = core.STEP_REWARD
  if event == core.SUCCESS:
    reward += gate_reward
  elif event != core.NO_EVENT:
    reward += out_of_bounds_reward
  terminated = event != core.NO_EVENT
  return event, reward, terminated, not terminated and steps >= max_steps


@numba.njit(cache=True, error_model="numpy")
def step_batch(states, r_deg, active, samples, steps, integrate, islands, piers, cells,
               max_steps, gate_reward, out_of_bounds_reward, outcome):
  """One control step of every `active` ship of a batch. With `integrate` the ships sail
  Equation 1 here (`ship_core.sail_batch`); without it `samples` and `states` already
  hold the step (the MuJoCo ships). Each active ship's `steps` grows by one and
  `outcome` = (event, reward, terminated, truncated) is filled by `ship_outcome`."""
  event, reward, terminated, truncated = outcome
  if integrate:
    core.sail_batch(states, r_deg, active, samples)
  for i in range(states.shape[0]):
    if not active[i]:
      continue
    steps[i] += 1
    event[i], reward[i], terminated[i], truncated[i] = ship_outcome(
        samples[i], islands, piers, cells, steps[i], max_steps, gate_reward,
        out_of_bounds_reward)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _nearest(t0, t1, best):
  """The first crossing t0, else t1 from inside, where it is nearer than `best`."""
  t = t0 if t0 >= 0.0 else t1
  return t if 0.0 <= t < best else best


@numba.njit(cache=True, error_model="numpy", inline="always")
def _behind(px, py, sin, cos, islands, piers, k):
  """Whether obstacle k lies wholly behind the ship at (px, py) heading (sin, cos): no
  ray (all point into the forward half-plane; the two abeam by the rounding of
  cos 90 deg, well inside the margin) can meet it. Skipping it changes no reading."""
  if k < islands.shape[0]:
    ahead = (islands[k, 0] - px) * sin + (islands[k, 1] - py) * cos + islands[k, 2]
  else:
    pier = piers[k - islands.shape[0]]
    ahead = ((pier[0] - px) * sin + (pier[1] - py) * cos
             + pier[4] * abs(pier[2] * sin + pier[3] * cos)
             + pier[5] * abs(pier[3] * sin - pier[2] * cos))
  return ahead < -_BEHIND_MARGIN_M


@numba.njit(cache=True, error_model="numpy", inline="always")
def ranges_into(state, islands, piers, cells, out, at):
  """The rangefinders' readings of the ship at `state` into out[at:at + RAYS]: for each
  obstacle within MAX_RANGE_M, each ray's first crossing of it (`ray_distance`'s
  arithmetic, with what each obstacle shares among the rays worked out once and the
  rays' directions by the sum formulas)."""
  px, py = state[0], state[1]
  for j in range(RAYS):
    out[at + j] = MAX_RANGE_M
  candidates = _cell_mask(cells, 0, px, py)
  if candidates == 0:
    return
  rad = math.radians(state[2])
  sin, cos = math.sin(rad), math.cos(rad)
  n = islands.shape[0]
  for k in range(n + piers.shape[0]):
    if not candidates & (1 << k) or not _within(px, py, islands, piers, k, MAX_RANGE_M) \
        or _behind(px, py, sin, cos, islands, piers, k):
      continue
    if k < n:
      ox, oy = px - islands[k, 0], py - islands[k, 1]
      c = ox * ox + oy * oy - islands[k, 2] * islands[k, 2]
      for j in range(RAYS):
        dx = sin * _BEARING_COS[j] + cos * _BEARING_SIN[j]
        dy = cos * _BEARING_COS[j] - sin * _BEARING_SIN[j]
        b = ox * dx + oy * dy
        disc = b * b - c
        if disc < 0.0 or (c > 0.0 and b > 0.0):      # missed, or outside and moving away
          continue
        root = math.sqrt(disc)
        out[at + j] = _nearest(-b - root, -b + root, out[at + j])
    else:
      pier = piers[k - n]
      ox, oy = pier[0] - px, pier[1] - py
      for j in range(RAYS):
        dx = sin * _BEARING_COS[j] + cos * _BEARING_SIN[j]
        dy = cos * _BEARING_COS[j] - sin * _BEARING_SIN[j]
        # The rectangle wholly to one side of the ray's line (its centre farther off
        # the line than its half extent across it, with a margin): a miss.
        if abs(ox * dy - oy * dx) > (pier[4] * abs(pier[2] * dy - pier[3] * dx)
                                     + pier[5] * abs(pier[3] * dy + pier[2] * dx)
                                     + _BEHIND_MARGIN_M):
          continue
        t0, t1 = _box_hits(px, py, dx, dy, pier, -np.inf, np.inf)
        if t0 <= t1:
          out[at + j] = _nearest(t0, t1, out[at + j])


@numba.njit(cache=True, error_model="numpy")
def observe_batch(states, islands, piers, cells, out):
  """Each ship's observation, its state then its ranges, into the rows of `out`."""
  for i in range(states.shape[0]):
    for j in range(4):
      out[i, j] = states[i, j]
    ranges_into(states[i], islands, piers, cells, out[i], 4)


@numba.njit(cache=True, error_model="numpy")
def ranges_batch(states, islands, piers, cells, out):
  """Each ship's ranges alone into the rows of `out` (RAYS columns)."""
  for i in range(states.shape[0]):
    ranges_into(states[i], islands, piers, cells, out[i], 0)


@numba.njit(cache=True, error_model="numpy")
def seen_ranges(readings, out, at):
  """MuJoCo's rangefinder readings as the module's ranges into out[at:]: -1 (no surface
  on the ray) and anything beyond MAX_RANGE_M read MAX_RANGE_M."""
  for j in range(readings.shape[0]):
    r = readings[j]
    out[at + j] = MAX_RANGE_M if r < 0.0 or r > MAX_RANGE_M else r


@numba.njit(cache=True, error_model="numpy")
def inside(x, y, islands, piers):
  """Whether the point (x, y) lies on an obstacle (its boundary included)."""
  return segment_touches(x, y, x, y, islands, piers, 0.0)


@numba.njit(cache=True, error_model="numpy")
def start_of(draws, size, islands, piers, state):
  """The start of `draws`, four uniforms on [0, 1) for the steering task's theta_deg,
  theta_dot_deg, x and y in its order, scaled as numpy's `uniform` scales them (`low +
  (high - low) * u`, to the bit), into `state` [x, y, theta_deg, theta_dot_deg]; False
  where its position lies on an obstacle."""
  theta = -180.0 + 360.0 * draws[0]
  state[3] = -core.MAX_TURN_RATE + (2.0 * core.MAX_TURN_RATE) * draws[1]
  state[0] = 0.0 + size * draws[2]
  state[1] = 0.0 + size * draws[3]
  state[2] = core.wrap_deg(theta)
  return not inside(state[0], state[1], islands, piers)


@functools.cache
def _start_entry():
  """`start_of`'s entry point for one start's arrays (a batch resets a few copies every
  step; numba's dispatcher would type the arguments again at each)."""
  f64 = numba.float64
  return start_of.compile((f64[::1], f64, f64[:, ::1], f64[:, ::1], f64[::1]))


def sample_start(rules, random, islands, piers):
  """The steering task's uniform start (`rules.sample_start`: the same draws, to the bit,
  from one call of the generator: its four `uniform`s cost a reset most of its time),
  drawn again while its position lies on an obstacle; `random` a Generator or
  RandomState."""
  entry, state, size = _start_entry(), np.empty(4), float(rules.size)
  for _ in range(START_TRIES):
    if entry(random.random(4), size, islands, piers, state):
      return state
  raise RuntimeError("ship harbour: no start off the obstacles in 10,000 draws")


def check_start(rules, state, islands, piers, who):
  """A start given by a user (`rules.check_state`), refused in one line on an obstacle."""
  state = rules.check_state(state, who)
  if inside(state[0], state[1], islands, piers):
    raise ValueError(f"{who}: start position ({float(state[0])!r}, {float(state[1])!r}) lies on an "
                     "obstacle; allowed: any position on the field off the harbour's islands "
                     "and piers")
  return state


@functools.cache
def _one_ship():
  """`ship_outcome`'s and `ranges_into`'s entry points for one ship's arrays: numba's
  dispatcher would type their arguments again at each step (most of the call)."""
  f64, i64 = numba.float64, numba.int64
  cells = i64[:, :, ::1]
  step = ship_outcome.compile((f64[:, ::1], f64[:, ::1], f64[:, ::1], cells, i64, i64, f64, f64))
  seen = ranges_into.compile((f64[::1], f64[:, ::1], f64[:, ::1], cells, f64[::1], i64))
  return step, seen


class OneShip:
  """The harbour's rule and observation for the single environments (Gymnasium's and
  dm_control's): one ship among one level's obstacles."""

  def __init__(self, level, max_steps, gate_reward=GATE_REWARD,
               out_of_bounds_reward=OUT_OF_BOUNDS_REWARD):
    self.islands, self.piers = level_shapes(level)
    self.cells = level_cells(level)
    self.max_steps = int(max_steps)
    self.rewards = (float(gate_reward), float(out_of_bounds_reward))
    self._step, self._ranges = _one_ship()

  def __call__(self, samples, steps):
    """(event, reward, terminated, truncated) after a control step that sampled `samples`
    (float64, C order), `steps` control steps in (this one counted)."""
    return self._step(samples, self.islands, self.piers, self.cells, steps, self.max_steps,
                      *self.rewards)

  def observe(self, state, readings=None):
    """The observation (a new array): `state` (float64, C order), then the ranges, the
    analytic ones or, given, MuJoCo's rangefinder `readings` (`seen_ranges`)."""
    out = np.empty(OBSERVATION_SIZE)
    out[:4] = state
    if readings is None:
      self._ranges(state, self.islands, self.piers, self.cells, out, 4)
    else:
      seen_ranges(readings, out, 4)
    return out


def pilot_target(state, phase):
  """The steering task's scripted helmsman (`ship_core.gate_pilot_target`), blind to the
  obstacles: for checks and pictures; the planners' helmsman goes round them."""
  return core.gate_pilot_target(state, phase)


# ---- the world as pure functions over a state and its parameters -------------------
# (gymnax's shape; the open machine's fused loop, `hierarchy.algorithm.run_world`,
# calls them, and they step as the Gymnasium environment's analytic backend does.)

EnvParams = collections.namedtuple("EnvParams", ("islands", "piers", "cells", "rewards",
                                                 "max_steps"))
EnvParams.__doc__ = """The harbour's task: the level's islands and pier frames
(`level_shapes`) and its cells (`level_cells`), [gate reward, out-of-bounds reward], the
control steps before truncation."""
EnvState = collections.namedtuple("EnvState", ("ship", "draws"))
EnvState.__doc__ = """The world's state: the ship's [x, y, theta_deg, theta_dot_deg];
`draws`, scratch for one try at a start (`start_of`)."""
START_SIZE = 4                # an episode's start: the ship's state


def env_params(level, gate_reward=GATE_REWARD, out_of_bounds_reward=OUT_OF_BOUNDS_REWARD,
               max_steps=core.STEER_MAX_STEPS):
  """The `EnvParams` of `level` with the environment's rewards and step limit (the level's
  time limit where shorter: `episode_steps`)."""
  islands, piers = level_shapes(level)
  return EnvParams(islands, piers, level_cells(level),
                   np.array([gate_reward, out_of_bounds_reward], dtype=np.float64),
                   np.int64(episode_steps(level, max_steps)))


def env_state(params):
  """A fresh `EnvState` (the fused loop's scratch)."""
  return EnvState(np.zeros(4), np.zeros(4))


@numba.njit(cache=True, error_model="numpy")
def observe_into(params, ship, obs):
  """The observation of `ship` into `obs` (11): its state, then the ranges."""
  for j in range(4):
    obs[j] = ship[j]
  ranges_into(ship, params.islands, params.piers, params.cells, obs, 4)


@numba.njit(cache=True, error_model="numpy")
def env_reset(params, state, start, obs):
  """An episode from `start` (the ship's state, off the obstacles; its heading wrapped as
  the environment's `reset(options={"state": ...})` wraps it); its observation into
  `obs`."""
  ship = state.ship
  core.place(ship, start)
  observe_into(params, ship, obs)


@numba.njit(cache=True, error_model="numpy")
def env_step(params, state, r_deg, samples, obs, steps):
  """One control step at turning rate `r_deg` (clipped to [-15, 15] deg/s), `steps`
  control steps in (this one counted): the positions sampled into `samples`, the
  observation into `obs`; returns (event, reward, terminated, truncated) as
  `ShipHarbourEnv.step` (`ship_outcome`)."""
  r = core.clipped(r_deg)
  core.euler_control(state.ship, r, samples, core.SPEED, core.TIME_CONSTANT,
                     core.SAMPLING_INTERVAL)
  event, reward, terminated, truncated = ship_outcome(
      samples, params.islands, params.piers, params.cells, steps, params.max_steps,
      params.rewards[0], params.rewards[1])
  observe_into(params, state.ship, obs)
  return event, reward, terminated, truncated


@numba.njit(cache=True, error_model="numpy")
def env_end(params, state, event):
  """An ended episode's (passed the gate: 1 or 0, 0)."""
  return (1.0 if event == core.SUCCESS else 0.0), 0.0
