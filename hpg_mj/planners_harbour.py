"""The harbour's best known score (SPEC sections 7.1 and 11): a planner that sees the
level's whole map (its islands and piers are fixed) and sails the analytic ship of the
batch environments, its arithmetic and the harbour's rule to the bit
(`ship_harbour_core.ship_outcome`), from each start; dispatched from `planners.plan`.

- The distance field (`distance_field`): the length of the shortest path to the gate
  (its posts moved in by `shared.INSET_M`) from each node of a 5 m grid, a Dijkstra
  search over `shared.STENCIL`'s 32 headings, as the current's least-time field in
  still water. An edge that meets an obstacle is blocked; one that meets an obstacle
  grown by a safety margin, or that ends within the margin of the field's edge, costs
  PENALTY times its length. So the paths keep the margin wherever the water allows it
  (the ship answers its rudder 5 s late and turns on a radius of about 12 m: a path
  that grazes a pier sinks it), the narrow passages stay open at a price (the hard
  level's 40 m ones at the field's edges), and a ship inside the margin is led out of
  it by the shortest way.
- The helmsman (`harbour_rate`): heads down the field's gradient (the steepest
  descent of the path length) and, within NEAR_GATE_M of the gate's nearest point,
  straight at it; a policy of the observation alone, the map being the level's.
- The search (`_plan_harbour`): from each start the helmsman on each of the margins of
  SAFETY_M (the first is the scripted helmsman's), and before each first turns (full
  rudder either way for 2-34 control steps, then the other way for 0 or 6, as the
  current's planner); it keeps the fewest control steps to the gate, and the scripted
  helmsman's episode where none passes. It is thus never worse than the helmsman.

The reference (`reference_steps`): the same search on the obstacles as they are, with
no margin and no penalty, a point that turns at once: the grid's paths are paths of
the water, so their length is at least the shortest path's and in open water at most
~1.3% above it (the stencil's headings lie at most 18.4 degrees apart).
"""
import functools
import heapq
import math

import numba
import numpy as np

from hpg_mj import planners_shared as shared
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_harbour_core as harbour_core

GRID_M = 5.0                         # the distance field's grid
# The margins the search tries. The scripted helmsman's, the first, is about the ship's
# turning radius (3 m/s at 15 deg/s: 11.5 m); the smaller ones cut corners closer (most
# of the best episodes at medium and hard), the larger keeps clear of a ship's overshoot.
SAFETY_M = (12.0, 3.0, 5.0, 8.0, 20.0)
EDGE_MARGIN_M = 15.0                 # the field's edge is kept this far (as the current's)
PENALTY = 4.0                        # the cost of a metre sailed inside a margin
NEAR_GATE_M = 20.0                   # within this of the gate, straight at it


@numba.njit(cache=True, error_model="numpy")
def _clearance(x, y, islands, piers):
  """The distance from (x, y) to the nearest obstacle (0 on one), as `segment_touches`
  grows them: to a pier the larger of the distances along and across it (a grown pier
  is a rectangle, its corners square)."""
  best = np.inf
  for k in range(islands.shape[0]):
    best = min(best, max(math.hypot(x - islands[k, 0], y - islands[k, 1]) - islands[k, 2], 0.0))
  for k in range(piers.shape[0]):
    rx, ry = x - piers[k, 0], y - piers[k, 1]
    qx = max(abs(rx * piers[k, 2] + ry * piers[k, 3]) - piers[k, 4], 0.0)
    qy = max(abs(rx * piers[k, 3] - ry * piers[k, 2]) - piers[k, 5], 0.0)
    best = min(best, max(qx, qy))
  return best


@numba.njit(cache=True, error_model="numpy")
def _distance_field_into(islands, piers, seeds, spacing, safety, edge_margin, penalty, stencil,
                         out):
  """`distance_field` into `out` (n, n), out[i, j] at (i, j) * spacing, from the nodes
  `seeds` (flat indices i * n + j, at distance 0); inf where no unblocked path reaches
  them."""
  n = out.shape[0]
  out[:, :] = np.inf
  heap = [(0.0, 0)]
  heap.pop()
  for k in seeds:
    out[k // n, k % n] = 0.0
    heapq.heappush(heap, (0.0, k))
  low, high = edge_margin, core.FIELD_SIZE - edge_margin
  clear = np.empty((n, n))          # each node's distance to the nearest obstacle: an edge
  for i in range(n):                # from a node clearer than its length and the margin
    for j in range(n):              # needs no test against the obstacles
      clear[i, j] = _clearance(i * spacing, j * spacing, islands, piers)
  while len(heap) > 0:
    t, k = heapq.heappop(heap)
    i, j = k // n, k % n
    if t > out[i, j]:
      continue
    x, y = i * spacing, j * spacing
    for d in range(stencil.shape[0]):
      pi, pj = i - stencil[d, 0], j - stencil[d, 1]
      if pi < 0 or pj < 0 or pi >= n or pj >= n:
        continue
      px, py = pi * spacing, pj * spacing
      length = spacing * math.hypot(stencil[d, 0], stencil[d, 1])
      near = clear[i, j] <= length + safety
      if near and harbour_core.segment_touches(px, py, x, y, islands, piers, 0.0):
        continue                                        # blocked: it meets an obstacle
      if (penalty != 1.0 and (px < low or px > high or py < low or py > high
                              or x < low or x > high or y < low or y > high
                              or (near and safety > 0.0 and harbour_core.segment_touches(
                                  px, py, x, y, islands, piers, safety)))):
        length *= penalty
      tt = t + length
      if tt < out[pi, pj]:
        out[pi, pj] = tt
        heapq.heappush(heap, (tt, pi * n + pj))


def gate_seeds(islands, piers, n, spacing=GRID_M):
  """The nodes (flat indices) on the steering task's gate line between its posts moved in
  by `shared.INSET_M`, off the obstacles: where the harbour's fields are 0."""
  j0 = int(round(core.GATE[0, 1] / spacing))
  return np.array([i * n + j0 for i in range(n)
                   if core.GATE[0, 0] + shared.INSET_M <= i * spacing <= core.GATE[1, 0]
                   - shared.INSET_M and not harbour_core.inside(i * spacing, j0 * spacing,
                                                                 islands, piers)],
                  dtype=np.int64)


def distance_field_into(islands, piers, seeds, safety, out, edge_margin=EDGE_MARGIN_M,
                        penalty=PENALTY):
  """D (m) into `out` (n, n) over the GRID_M grid: the length of the shortest path to the
  nodes `seeds` (flat indices) among the obstacles `islands` and pier frames `piers`,
  over 32 headings; edges that meet an obstacle are blocked, those that meet it grown by
  `safety` m or end within `edge_margin` of the field's edge cost `penalty` times their
  length."""
  _distance_field_into(islands, piers, np.asarray(seeds, dtype=np.int64), float(GRID_M),
                       float(safety), float(edge_margin), float(penalty), shared.STENCIL, out)
  return out


def distance_field(level, safety, spacing=GRID_M, edge_margin=EDGE_MARGIN_M, penalty=PENALTY):
  """D (m): the length of the shortest path to the gate from each node of a `spacing`
  grid over the field among `level`'s obstacles, over 32 headings; edges that meet an
  obstacle are blocked, those that meet it grown by `safety` m or end within
  `edge_margin` of the field's edge cost `penalty` times their length."""
  islands, piers = harbour_core.level_shapes(level)
  n = int(round(core.FIELD_SIZE / spacing)) + 1
  out = np.empty((n, n))
  _distance_field_into(islands, piers, gate_seeds(islands, piers, n, spacing), float(spacing),
                       float(safety), float(edge_margin), float(penalty), shared.STENCIL, out)
  return out


@functools.cache
def level_fields(level):
  """The distance fields of `level` at each margin of SAFETY_M, (k, n, n), read-only,
  computed once a process."""
  out = np.stack([distance_field(level, safety) for safety in SAFETY_M])
  out.setflags(write=False)
  return out


@numba.njit(cache=True, error_model="numpy", inline="always")
def distance_at(field, spacing, x, y):
  """D at (x, y): bilinear over the nodes of its cell that a path leaves (those inside
  an obstacle, inf, left out and the weights of the rest renormalized); inf where none
  of the four does."""
  last = field.shape[0] - 1
  x = min(max(x, 0.0), last * spacing) / spacing
  y = min(max(y, 0.0), last * spacing) / spacing
  i = min(int(x), last - 1)
  j = min(int(y), last - 1)
  fx, fy = x - i, y - j
  total, weight = 0.0, 0.0
  for di in range(2):
    for dj in range(2):
      value = field[i + di, j + dj]
      if math.isfinite(value):
        w = (fx if di else 1.0 - fx) * (fy if dj else 1.0 - fy)
        total += w * value
        weight += w
  return total / weight if weight > 0.0 else np.inf


@numba.njit(cache=True, error_model="numpy")
def harbour_rate(state, field, spacing):
  """The harbour's helmsman: r (deg/s) to head down the gradient of the distance field
  `field` (aiming 100 m along it); within NEAR_GATE_M of the gate's nearest point (the
  posts moved in by INSET_M), or where the gradient is not defined, straight at it."""
  x, y = state[0], state[1]
  gx = min(max(x, core.GATE[0, 0] + shared.INSET_M), core.GATE[1, 0] - shared.INSET_M)
  gy = core.GATE[0, 1]
  if math.hypot(gx - x, gy - y) < NEAR_GATE_M:
    return core.pilot_turn_rate(state, gx, gy)
  h = 0.5 * spacing
  hx = distance_at(field, spacing, x - h, y) - distance_at(field, spacing, x + h, y)
  hy = distance_at(field, spacing, x, y - h) - distance_at(field, spacing, x, y + h)
  return shared.down_gradient_rate(state, hx, hy, gx, gy)


@numba.njit(cache=True, error_model="numpy")
def _sail_harbour(state, field, spacing, islands, piers, cells, sign, first, back, cap,
                  max_steps, gate_reward, out_of_bounds_reward, samples, actions):
  """One harbour episode from `state` (changed in place): the first turns, then
  `harbour_rate` on `field`; judged by the harbour's rule. Stops at its end, at
  `max_steps` or at `cap` steps. Returns (event, steps, return); the turning rates
  into `actions` (as far as it goes)."""
  steps, total = 0, 0.0
  while True:
    r = shared.first_turn_rate(steps, sign, first, back)
    if math.isnan(r):
      r = harbour_rate(state, field, spacing)
    if steps < actions.shape[0]:
      actions[steps] = r
    core.euler_control(state, r, samples)
    steps += 1
    event, reward, terminated, truncated = harbour_core.ship_outcome(
        samples, islands, piers, cells, steps, max_steps, gate_reward, out_of_bounds_reward)
    total += reward
    if terminated or truncated or steps >= cap:
      return event, steps, total


@numba.njit(cache=True)
def _plan_harbour(starts, fields, spacing, islands, piers, cells, firsts, backs, max_steps,
                  gate_reward, out_of_bounds_reward, best, choice, actions):
  """The module's search: best[i] = (passed, steps, return), choice[i] = (field, sign,
  first, back); the chosen episode's turning rates into actions[i]. The scripted
  helmsman (field 0, no turn) first; a later episode is kept only if it passes in
  fewer control steps."""
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  state = np.empty(4)
  none = np.empty(0)
  for i in range(starts.shape[0]):
    state[:] = starts[i]
    event, steps, total = _sail_harbour(state, fields[0], spacing, islands, piers, cells, 1.0,
                                        0, 0, max_steps, max_steps, gate_reward,
                                        out_of_bounds_reward, samples, none)
    passed = event == core.SUCCESS
    best[i, 0], best[i, 1], best[i, 2] = passed, steps, total
    choice[i, 0], choice[i, 1], choice[i, 2], choice[i, 3] = 0, 1.0, 0, 0
    for f in range(fields.shape[0]):
      for sign in (1.0, -1.0):
        for t in range(firsts.shape[0] + 1):
          first = 0 if t == 0 else firsts[t - 1]
          for back in backs:
            if first == 0 and (back > 0 or sign < 0 or f == 0):
              continue                  # the plain helmsmen once each, the scripted one done
            cap = int(best[i, 1]) if best[i, 0] else max_steps
            state[:] = starts[i]
            event, steps, total = _sail_harbour(state, fields[f], spacing, islands, piers,
                                                cells, sign, first, back, cap, max_steps,
                                                gate_reward, out_of_bounds_reward, samples,
                                                none)
            if event == core.SUCCESS and (steps < cap or not best[i, 0]):
              best[i, 0], best[i, 1], best[i, 2] = 1.0, steps, total
              choice[i, 0], choice[i, 1], choice[i, 2], choice[i, 3] = f, sign, first, back
    if actions.shape[0] > 0:
      state[:] = starts[i]
      _sail_harbour(state, fields[int(choice[i, 0])], spacing, islands, piers, cells,
                    choice[i, 1], int(choice[i, 2]), int(choice[i, 3]), max_steps, max_steps,
                    gate_reward, out_of_bounds_reward, samples, actions[i])


def plan(level, states, max_steps, gate_reward, out_of_bounds_reward, actions):
  """`planners.plan` for the harbour at `level` from `states` (n, 4): (outcome rows
  (passed, steps, return), choice rows (field, sign, first, back), the turning rates
  (n, max_steps), NaN after each episode's end, or an empty array)."""
  islands, piers = harbour_core.level_shapes(level)
  n = len(states)
  rates = np.full((n, max_steps) if actions else (0, 0), np.nan)
  outcome, choice = np.zeros((n, 3)), np.zeros((n, 4))
  _plan_harbour(np.ascontiguousarray(states, dtype=np.float64), level_fields(level), GRID_M,
                islands, piers, harbour_core.level_cells(level), shared.FIRST_TURNS,
                shared.BACK_TURNS, int(max_steps), float(gate_reward),
                float(out_of_bounds_reward), outcome, choice, rates)
  return outcome, choice, rates


@functools.cache
def _reference_field(level):
  out = distance_field(level, 0.0, edge_margin=0.0, penalty=1.0)
  out.setflags(write=False)
  return out


def reference_steps(level, states):
  """Per start, the control steps of a point that turns at once on the shortest grid
  path to the gate among the obstacles as they are (no margin: the distance field at
  the start over 1.8 m a step): at least the continuous shortest path's, in open water
  within ~1.3% of it."""
  field = _reference_field(level)
  states = np.asarray(states, dtype=np.float64).reshape(-1, 4)
  return np.array([distance_at(field, GRID_M, s[0], s[1]) for s in states]) \
      / (core.SPEED * core.CONTROL_INTERVAL)


@numba.njit(cache=True, error_model="numpy")
def _helmsman_batch(obs, field, out):
  for i in range(obs.shape[0]):
    out[i] = harbour_rate(obs[i, :4], field, GRID_M)


def helmsman(level, obs):
  """The scripted helmsman's turning rates for a batch of observations (n, 11) at
  `level` (the field of SAFETY_M[0]): a policy of the observation alone."""
  obs = np.ascontiguousarray(obs, dtype=np.float64).reshape(-1, harbour_core.OBSERVATION_SIZE)
  out = np.empty(len(obs))
  _helmsman_batch(obs, level_fields(level)[0], out)
  return out
