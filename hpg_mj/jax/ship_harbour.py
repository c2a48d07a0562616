"""The harbour in pure JAX (SPEC section 11, `hpg_mj/ShipHarbour-v0`), gymnax's
interface.

The steering task of `hpg_mj.jax.ship` (Equation 1 in still water, `ship/steer`'s
gate and field) among islands and piers, the rules of
`hpg_mj.worlds.ship_harbour_core` written again over jax.numpy: along each sampled
segment in order, a crossing of the gate succeeds (+100), a position off the field
fails (-100) and a segment that touches an obstacle, its boundary included, runs
aground (AGROUND, -3: -100, terminated), the first in time winning; truncated after
5,000 control steps. The observation adds the seven rangefinders
(`ship_harbour_core.BEARINGS_DEG` from the heading, clockwise): the distance to the
first obstacle along each ray, MAX_RANGE_M (150 m) where none is nearer, the way out
from inside one. In float64 the trajectories, rewards and endings equal the numba
world's (tests/jax/test_jax_ladder.py).

The obstacles are the level's, the same at every reset, and are parameters, as the
other ladder tasks' levels: `HarbourParams.islands` (MAX_ISLANDS rows `[x, y,
radius]`) and `piers` (MAX_PIERS rows `[x0, y0, x1, y1, half_width]`, end to end),
each padded with rows of zeros, which are no obstacle. So one compiled step sails
every level (or a harbour of one's own: `params.replace(islands=...)`). The level is
a constructor argument, as the Gymnasium environment's, and gives the defaults.

The start is the steering task's uniform start, drawn again (from the next part of
the key) while its position lies on an obstacle, as the numba world's
(`ship_harbour_core.sample_start`), at most `ship_harbour_core.START_TRIES` times.
`step`'s start (gymnax's auto-reset) is computed only for the copies whose episode
ended (`environment.where_needed`): its rays are most of a step's work.
The numba world skips the obstacles out of a ship's reach by a grid of masks
(`level_cells`); here every obstacle is tested, with the same reach tests after
the grid's, which change no result.
"""
import math

import jax
import jax.numpy as jnp
import numpy as np

from hpg_mj.jax import environment
from hpg_mj.jax import ship
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_harbour_core as harbour_core
from hpg_mj.worlds import ship_task

AGROUND = harbour_core.AGROUND
MAX_ISLANDS = max(len(islands) for islands, _ in harbour_core.LEVELS.values())
MAX_PIERS = max(len(piers) for _, piers in harbour_core.LEVELS.values())
# Each ray's direction from the heading's sine and cosine by the sum formulas, with
# `ship_harbour_core`'s constants (the same expressions, so the same numbers).
_BEARING_SIN = np.array([math.sin(math.radians(b)) for b in harbour_core.BEARINGS_DEG])
_BEARING_COS = np.array([math.cos(math.radians(b)) for b in harbour_core.BEARINGS_DEG])


def level_obstacles(level, who="ShipHarbour"):
  """(islands, piers) of `level` as `HarbourParams` holds them: tuples of MAX_ISLANDS
  rows `[x, y, radius]` and MAX_PIERS rows `[x0, y0, x1, y1, half_width]`, padded with
  rows of zeros; a one-line error for an unknown level."""
  harbour_core.level_obstacles(level, who)
  islands, piers = harbour_core.LEVELS[level]
  return (tuple(islands) + ((0.0, 0.0, 0.0),) * (MAX_ISLANDS - len(islands)),
          tuple(piers) + ((0.0,) * 5,) * (MAX_PIERS - len(piers)))


_EASY = level_obstacles(harbour_core.DEFAULT_LEVEL)


@environment.record
class HarbourParams(ship.EnvParams):
  """The steering task's `EnvParams` and the level's obstacles (SPEC section 11,
  `ship_harbour_core.LEVELS`), in m: islands `[x, y, radius]` and piers `[x0, y0, x1,
  y1, half_width]` (end to end along the centre line), rows of zeros for none.
  Touching one costs `out_of_bounds_reward`."""
  islands: tuple = _EASY[0]
  piers: tuple = _EASY[1]


@environment.record
class Obstacles:
  """A harbour's obstacles as arrays, with what the rules share among them."""
  islands: jax.Array         # (MAX_ISLANDS, 3): [x, y, radius]
  island_live: jax.Array     # (MAX_ISLANDS,): a row that is an island (radius > 0)
  piers: jax.Array           # (MAX_PIERS, 6): [cx, cy, ux, uy, half_length, half_width]
  pier_live: jax.Array       # (MAX_PIERS,): a row that is a pier (length > 0)


def known_obstacles(params):
  """`params`' obstacles as the numba rules take them, (islands, pier frames) without the
  rows of zeros, where their values are known (not under jit or vmap); else None."""
  if not all(environment.is_concrete(v) for v in jax.tree.leaves((params.islands, params.piers))):
    return None
  islands = np.array([row for row in params.islands if row[2] > 0.0]).reshape(-1, 3)
  piers = np.array([row for row in params.piers
                    if math.hypot(row[2] - row[0], row[3] - row[1]) > 0.0]).reshape(-1, 5)
  return islands, harbour_core.pier_frames(piers)


def obstacles_of(params, dtype):
  """`params`' obstacles as arrays of `dtype`: the islands, and the piers' frames
  (`ship_harbour_core.pier_frames`: the centre, the unit vector along, the half
  sizes)."""
  islands = jnp.asarray(params.islands, dtype).reshape(-1, 3)
  x0, y0, x1, y1, half_width = jnp.asarray(params.piers, dtype).reshape(-1, 5).T
  length = jnp.hypot(x1 - x0, y1 - y0)
  live = length > 0.0
  safe = jnp.where(live, length, 1.0)
  frames = jnp.stack([0.5 * (x0 + x1), 0.5 * (y0 + y1), (x1 - x0) / safe, (y1 - y0) / safe,
                      0.5 * length, half_width], axis=-1)
  return Obstacles(islands, islands[:, 2] > 0.0, frames, live)


# ---- geometry: `ship_harbour_core`'s, every obstacle at once -------------------------

def _slab(o, d, half, t0, t1):
  """`ship_harbour_core._slab`: the slab |o + t d| <= half clipping [t0, t1]; empty
  (t0 > t1) when it misses."""
  flat = d == 0.0
  safe = jnp.where(flat, 1.0, d)
  a, b = (-half - o) / safe, (half - o) / safe
  outside = jnp.abs(o) > half
  return (jnp.where(flat, jnp.where(outside, 1.0, t0), jnp.maximum(t0, jnp.minimum(a, b))),
          jnp.where(flat, jnp.where(outside, 0.0, t1), jnp.minimum(t1, jnp.maximum(a, b))))


def _box_hits(px, py, dx, dy, piers, t0, t1):
  """`ship_harbour_core._box_hits` for every pier: `piers`' last axis its frame, its
  columns broadcast against the rays or segments."""
  cx, cy, ux, uy, half_length, half_width = (piers[..., i] for i in range(6))
  rx, ry = px - cx, py - cy
  t0, t1 = _slab(rx * ux + ry * uy, dx * ux + dy * uy, half_length, t0, t1)
  return _slab(rx * uy - ry * ux, dx * uy - dy * ux, half_width, t0, t1)


def _within(x, y, obstacles, reach):
  """`ship_harbour_core._within` for every island and pier: (x, y) within `reach` m of
  it, on squared distances. Rows that are no obstacle are never within reach."""
  islands, piers = obstacles.islands, obstacles.piers
  dx, dy, grown = x - islands[:, 0], y - islands[:, 1], islands[:, 2] + reach
  near_islands = (dx * dx + dy * dy <= grown * grown) & obstacles.island_live
  rx, ry = x - piers[:, 0], y - piers[:, 1]
  qx = jnp.maximum(jnp.abs(rx * piers[:, 2] + ry * piers[:, 3]) - piers[:, 4], 0.0)
  qy = jnp.maximum(jnp.abs(rx * piers[:, 3] - ry * piers[:, 2]) - piers[:, 5], 0.0)
  near_piers = (qx * qx + qy * qy <= reach * reach) & obstacles.pier_live
  return near_islands, near_piers


def segment_touches(p0x, p0y, p1x, p1y, obstacles, margin=0.0):
  """`ship_harbour_core.segment_touches` for each obstacle: (islands, piers) boolean
  arrays, the segment p0-p1 meeting its shape (its boundary included) grown by
  `margin` m."""
  islands, piers = obstacles.islands, obstacles.piers
  dx, dy = p1x - p0x, p1y - p0y
  length2 = dx * dx + dy * dy
  cx, cy = islands[:, 0], islands[:, 1]
  along = ((cx - p0x) * dx + (cy - p0y) * dy) / jnp.where(length2 > 0.0, length2, 1.0)
  s = jnp.where(length2 > 0.0, jnp.minimum(jnp.maximum(along, 0.0), 1.0), 0.0)
  on_islands = jnp.hypot(p0x + s * dx - cx, p0y + s * dy - cy) <= islands[:, 2] + margin
  if margin:
    piers = piers.at[..., 4:6].add(margin)
  t0, t1 = _box_hits(p0x, p0y, dx, dy, piers, 0.0, 1.0)
  return on_islands & obstacles.island_live, (t0 <= t1) & obstacles.pier_live


def inside(x, y, obstacles):
  """Whether the point (x, y) lies on an obstacle, its boundary included
  (`ship_harbour_core.inside`)."""
  on_islands, on_piers = segment_touches(x, y, x, y, obstacles)
  return on_islands.any() | on_piers.any()


def segments_aground(positions, obstacles):
  """(xs, ys, aground) of one control step's sampled positions (the start first): their
  coordinates, and for each segment between two of them whether it touches an obstacle
  (`ship_harbour_core._segment_aground`). Only the obstacles within the step's reach
  of its start are tested (`_near`, whose reach tests these are)."""
  xs = jnp.stack([x for x, _ in positions])
  ys = jnp.stack([y for _, y in positions])
  reach2 = jnp.max((xs[1:] - xs[0]) ** 2 + (ys[1:] - ys[0]) ** 2)
  near_islands, near_piers = _within(xs[0], ys[0], obstacles,
                                     jnp.sqrt(reach2) * (1.0 + 1e-9) + 1e-9)
  # Every segment at once (the leading axis).
  on_islands, on_piers = segment_touches(xs[:-1, None], ys[:-1, None], xs[1:, None],
                                         ys[1:, None], obstacles)
  aground = (on_islands & near_islands).any(axis=1) | (on_piers & near_piers).any(axis=1)
  return xs, ys, aground


def harbour_event(positions, obstacles):
  """`ship_harbour_core.harbour_event`'s event of one control step's sampled positions
  (the start first): SUCCESS at the gate, FAILURE off the field, AGROUND on touching
  an obstacle, the first in time; NO_EVENT when none."""
  xs, ys, aground = segments_aground(positions, obstacles)
  px, py, x, y = xs[:-1, None], ys[:-1, None], xs[1:, None], ys[1:, None]
  (g0x, g0y), (g1x, g1y) = core.GATE.tolist()
  crossed = ship.segment_crosses(px, py, x, y, g0x, g0y, g1x, g1y)[:, 0]
  left = ((x < 0.0) | (x > core.FIELD_SIZE) | (y < 0.0) | (y > core.FIELD_SIZE))[:, 0]
  events = jnp.where(crossed, core.SUCCESS, jnp.where(left, core.FAILURE, jnp.where(
      aground, AGROUND, core.NO_EVENT)))
  return events[jnp.argmax(events != core.NO_EVENT)].astype(jnp.int32)


def ranges(x, y, theta_deg, obstacles):
  """The rangefinders' readings (RAYS,) of the ship at (x, y) heading `theta_deg`
  (`ship_harbour_core.ranges_into`): along each ray the first crossing of an
  obstacle within MAX_RANGE_M of the ship (the way out from inside one), MAX_RANGE_M
  where none is nearer."""
  dtype = x.dtype
  rad = jnp.radians(theta_deg)
  s, c = jnp.sin(rad), jnp.cos(rad)
  bearing_sin, bearing_cos = (jnp.asarray(a, dtype) for a in (_BEARING_SIN, _BEARING_COS))
  dx = s * bearing_cos + c * bearing_sin              # (RAYS,)
  dy = c * bearing_cos - s * bearing_sin
  seen_islands, seen_piers = _within(x, y, obstacles, harbour_core.MAX_RANGE_M)
  far = jnp.asarray(harbour_core.MAX_RANGE_M, dtype)
  islands = obstacles.islands
  ox, oy = (x - islands[:, 0])[:, None], (y - islands[:, 1])[:, None]
  cc = ox * ox + oy * oy - (islands[:, 2] * islands[:, 2])[:, None]
  b = ox * dx + oy * dy                               # (islands, RAYS)
  disc = b * b - cc
  missed = (disc < 0.0) | ((cc > 0.0) & (b > 0.0))    # missed, or outside and moving away
  root = jnp.sqrt(jnp.where(missed, 0.0, disc))
  t = jnp.where(-b - root >= 0.0, -b - root, -b + root)   # `_nearest`'s choice
  hits = ~missed & seen_islands[:, None] & (t >= 0.0)
  best = jnp.min(jnp.where(hits, t, far), axis=0, initial=far)
  t0, t1 = _box_hits(x, y, dx, dy, obstacles.piers[:, None, :], -jnp.inf, jnp.inf)
  t = jnp.where(t0 >= 0.0, t0, t1)
  hits = (t0 <= t1) & seen_piers[:, None] & (t >= 0.0)
  return jnp.minimum(best, jnp.min(jnp.where(hits, t, far), axis=0, initial=far))


class ShipHarbour(ship.ShipSteering):
  """`hpg_mj/ShipHarbour-v0` as a gymnax environment: the steering task among the
  obstacles of `level` ("easy", "medium" or "hard"; they give the default
  `HarbourParams`). Observation `[x, y, theta_deg, theta_dot_deg]` and the seven
  ranges (m), in the default float dtype; action the turning rate r in deg/s, shape
  (1,) (or ()), clipped to [-15, 15]. `info`: `terminated`, `truncated`, `event` (1
  the gate, -1 off the field, -3 an obstacle touched) and `discount`. The manual is
  `hpg_mj.envs.ship_harbour.ShipHarbourEnv`'s.
  """

  def __init__(self, level=harbour_core.DEFAULT_LEVEL, env_id=None):
    self.level = level
    self.obstacles = level_obstacles(level, env_id or "ShipHarbour")
    self.time_limit = harbour_core.TIME_LIMITS[level]
    super().__init__("steer", env_id or f"ShipHarbour({level})")
    self._reset_where = environment.where_needed(self.reset_env)

  @property
  def default_params(self):
    islands, piers = self.obstacles
    return HarbourParams(max_steps_in_episode=harbour_core.episode_steps(self.level),
                         islands=islands, piers=piers)

  def observation_space(self, params=None):
    # `hpg_mj.envs.ship_harbour.spaces_of`: the ship's state, then the ranges.
    state = super().observation_space(params)
    rays = harbour_core.RAYS
    return environment.Box(jnp.concatenate([state.low, jnp.zeros(rays)]),
                           jnp.concatenate([state.high,
                                            jnp.full(rays, harbour_core.MAX_RANGE_M)]),
                           (harbour_core.OBSERVATION_SIZE,), environment.float_dtype())

  def get_obs(self, state, params=None, key=None):
    params = self.default_params if params is None else params
    seen = ranges(state.x, state.y, state.theta_deg, obstacles_of(params, state.x.dtype))
    return jnp.concatenate([jnp.stack([state.x, state.y, state.theta_deg,
                                       state.theta_dot_deg]), seen])

  # ---- starts -------------------------------------------------------------------

  def reset_env(self, key, params):
    """The steering task's uniform start, drawn again from the next part of `key` while
    its position lies on an obstacle (`ship_harbour_core.sample_start`)."""
    obstacles = obstacles_of(params, environment.float_dtype())

    def on_obstacle(carry):
      _, tries, state = carry
      return inside(state.x, state.y, obstacles) & (tries < harbour_core.START_TRIES)

    def draw(carry):
      key, tries, _ = carry
      key, ship_key = jax.random.split(key)
      return key, tries + 1, self._draw_start(ship_key)

    _, _, state = jax.lax.while_loop(on_obstacle, draw, draw((key, jnp.int32(0), None)))
    return self.get_obs(state, params), state

  def auto_reset(self, key, params, done):
    """`reset_env`'s start, computed only where `done` (`environment.where_needed`):
    its rays and its draws off the obstacles are most of a step's work, and few
    copies end at a step."""
    return self._reset_where(done, key, jax.tree.map(jnp.asarray, params))

  def reset_to(self, ship_state, params=None):
    """`(obs, state)` starting exactly at `ship_state` = `[x, y, theta_deg,
    theta_dot_deg]` (the Gymnasium environment's `reset(options={"state": ...})`).
    Checked as there where its values and the obstacles are known (not under jit or
    vmap): on the field, off the obstacles."""
    params = self.default_params if params is None else params
    arr = jnp.asarray(ship_state)
    if arr.shape != (4,):
      raise ValueError(f"{self.env_id}: reset_to takes a ship state [x, y, theta_deg, "
                       f"theta_dot_deg] of shape (4,), got shape {arr.shape}")
    obstacles = known_obstacles(params)
    if environment.is_concrete(arr) and obstacles is not None:
      harbour_core.check_start(ship_task.ShipRules("steer"), np.asarray(arr, np.float64),
                               *obstacles, self.env_id)
    return self._start_at(arr, params)

  # ---- one control step ---------------------------------------------------------

  def step_env(self, key, state, action, params):
    r = self._turn_rate(action, state.x.dtype)
    x, y, theta, rate, positions = self._sail(state, r, params)
    time = state.time + 1
    event = harbour_event(positions, obstacles_of(params, x.dtype))
    # `ship_harbour_core.ship_outcome`'s sums in its order.
    reward = jnp.asarray(core.STEP_REWARD, x.dtype)
    reward = reward + jnp.where(event == core.SUCCESS, params.gate_reward, 0.0).astype(x.dtype)
    reward = reward + jnp.where((event == core.FAILURE) | (event == AGROUND),
                                params.out_of_bounds_reward, 0.0).astype(x.dtype)
    end = ship.EnvState(x, y, theta, rate, time, event)
    terminated = event != core.NO_EVENT
    truncated = ~terminated & (time >= self.closes(params))
    info = {"terminated": terminated, "truncated": truncated, "event": event,
            "discount": jnp.where(terminated, 0.0, 1.0).astype(x.dtype)}
    return self.get_obs(end, params), end, reward, terminated | truncated, info
