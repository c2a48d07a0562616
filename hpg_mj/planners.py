"""The best known scores of the task ladder (SPEC sections 7.1 and 11): planners that see
the whole map (the water's field, the episode's gate, the whole course) and sail the
analytic ship of the batch environments, its arithmetic to the bit, from each start
(`plan`); and the scripted helmsmen they build on, as policies of the observation
alone (`Helmsman`).

- current: the least time to the gate of a ship that turns at once, over the whole
  field in the level's water (Zermelo's navigation problem: a Dijkstra search on a 5 m
  grid whose edges are sailed at 3 m/s through the water, `time_field`). The helmsman
  heads down its gradient (the heading through the water that minimizes the time is
  -grad T, whatever the current) and, within 20 m of the gate, crabs straight at the
  gate's nearest point (`current_rate`). The planner also tries first turns (full
  rudder either way, then back) before it, as the steering task's search does, and
  keeps the fewest control steps to the gate (`_plan_current`).
- goal: the episode's gate known, a helmsman that makes for the point `reach` m before
  the gate on its line of approach and, once behind the gate inside a cone of lateral
  slope `slope` and heading towards it, for 60 m past its centre (`goal_rate`); the
  planner tries a grid of reaches and slopes (at `hard`, among the obstacles, also
  helmsmen down distance fields to the line-up points), then first turns before the
  best three, and keeps the fewest control steps to the gate
  (`hpg_mj.planners_goal`, its own module).
- regatta: the course known, Bertsekas's rollout of the scripted helmsman gate by gate
  (`_plan_regatta`): at each gate every way of taking it (`regatta_rate`'s candidates:
  the helmsman's, the nearest point, points across the gate, lined up with it, the
  shortest legs towards points of the gate after it, turning for the gate after at
  other distances; at the first, also first turns) is sailed to the finish with the
  helmsman taking the gates after it; the best is kept up to that gate's pass. With
  the helmsman among the candidates, a rollout is never worse than the helmsman (its
  cost improvement), and each gate's choice sees the whole rest of the course.
- harbour: the level's fixed map known, a helmsman down a distance field to the gate
  round the obstacles grown by a safety margin, and first turns before it
  (`hpg_mj.planners_harbour`, its own module).

`plan` returns per start the outcome of the chosen episode, the numbers the
benchmark's records hold, and, asked, the turning rates it sailed (to replay on the
environments); `reference_steps` a ship that turns at once, below them.
"""
import collections
import functools
import heapq
import math

import numba
import numpy as np

from hpg_mj import planners_goal
from hpg_mj import planners_harbour
from hpg_mj import planners_shared as shared
from hpg_mj.planners_shared import BACK_TURNS, FIRST_TURNS, INSET_M, STENCIL  # noqa: F401
from hpg_mj.planners_shared import first_turn_rate as _turn
from hpg_mj.planners_goal import HELMSMAN_SLOPE, goal_rate
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_current_core as current_core
from hpg_mj.worlds import ship_goal_core as goal_core
from hpg_mj.worlds import ship_regatta_core as regatta_core
from hpg_mj.worlds import ship_ladder

# ---- current -------------------------------------------------------------------------

GRID_M = 5.0                   # the time field's grid
MARGIN_M = 15.0                # its paths keep this far inside the field
NEAR_GATE_M = 20.0             # within this of the gate the helmsman crabs straight at it


@numba.njit(cache=True, error_model="numpy")
def _edge_seconds(dx, dy, cx, cy):
  """Seconds to make the ground displacement (dx, dy) at SPEED through water moving at
  (cx, cy) (slower than the ship): the positive root t of |d - c t| = V t, that is of
  a t^2 + 2 b t - |d|^2 = 0 with a = V^2 - |c|^2, b = d.c (in the form without
  cancellation)."""
  a = core.SPEED * core.SPEED - (cx * cx + cy * cy)
  b = dx * cx + dy * cy
  dd = dx * dx + dy * dy
  root = math.sqrt(b * b + a * dd)
  return dd / (b + root) if b >= 0.0 else (root - b) / a


@numba.njit(cache=True)
def _time_field_into(field, spacing, margin, stencil, out):
  """`time_field` into `out` (n, n), out[i, j] at (i, j) * spacing."""
  n = out.shape[0]
  out[:, :] = np.inf
  heap = [(0.0, 0)]
  heap.pop()
  j0 = int(round(core.GATE[0, 1] / spacing))
  for i in range(n):
    x = i * spacing
    if core.GATE[0, 0] + INSET_M <= x <= core.GATE[1, 0] - INSET_M:
      out[i, j0] = 0.0
      heapq.heappush(heap, (0.0, i * n + j0))
  low, high = margin, core.FIELD_SIZE - margin
  while len(heap) > 0:
    t, k = heapq.heappop(heap)
    i, j = k // n, k % n
    if t > out[i, j]:
      continue
    for d in range(stencil.shape[0]):
      pi, pj = i - stencil[d, 0], j - stencil[d, 1]
      if pi < 0 or pj < 0 or pi >= n or pj >= n:
        continue
      px, py = pi * spacing, pj * spacing
      if px < low or px > high or py < low or py > high:
        continue
      dx, dy = stencil[d, 0] * spacing, stencil[d, 1] * spacing
      cx, cy = current_core.current_at(field, px + 0.5 * dx, py + 0.5 * dy)
      tt = t + _edge_seconds(dx, dy, cx, cy)
      if tt < out[pi, pj]:
        out[pi, pj] = tt
        heapq.heappush(heap, (tt, pi * n + pj))


def time_field(field, spacing=GRID_M, margin=MARGIN_M):
  """T (s): the least time to the gate (its posts moved in by INSET_M) of a ship that
  sails at 3 m/s through the water of `field` and turns at once, from each node of a
  `spacing` grid over the field, on paths that keep `margin` inside it (a Dijkstra
  search over 32 headings: a path's time is at most ~1.3% over the continuous one)."""
  n = int(round(core.FIELD_SIZE / spacing)) + 1
  out = np.empty((n, n))
  _time_field_into(np.asarray(field, dtype=np.float64), float(spacing), float(margin),
                   STENCIL, out)
  return out


@functools.cache
def level_time_field(level):
  """`time_field` of a current level's water (computed once a process)."""
  out = time_field(current_core.level_field(level))
  out.setflags(write=False)
  return out


@numba.njit(cache=True, error_model="numpy", inline="always")
def _time_at(t_field, spacing, margin, x, y):
  """T at (x, y), bilinear, the point first clamped into the margin."""
  high = core.FIELD_SIZE - margin
  x = min(max(x, margin), high) / spacing
  y = min(max(y, margin), high) / spacing
  last = int(high / spacing) - 1       # the cells whose four nodes lie inside the margin
  i = min(int(x), last)
  j = min(int(y), last)
  fx, fy = x - i, y - j
  return ((1.0 - fx) * ((1.0 - fy) * t_field[i, j] + fy * t_field[i, j + 1])
          + fx * ((1.0 - fy) * t_field[i + 1, j] + fy * t_field[i + 1, j + 1]))


@numba.njit(cache=True, error_model="numpy")
def current_rate(state, field, t_field, spacing, margin):
  """The current's helmsman: r (deg/s) to head down T's gradient; within NEAR_GATE_M of
  the gate's nearest point, to crab straight at it (the heading whose velocity through
  the water plus the current points there)."""
  x, y = state[0], state[1]
  gx = min(max(x, core.GATE[0, 0] + INSET_M), core.GATE[1, 0] - INSET_M)
  gy = core.GATE[0, 1]
  dx, dy = gx - x, gy - y
  d = math.hypot(dx, dy)
  hx, hy = 0.0, 0.0
  if d < NEAR_GATE_M and d > 0.0:
    ux, uy = dx / d, dy / d
    cx, cy = current_core.current_at(field, x, y)
    along = cx * ux + cy * uy
    px, py = cx - along * ux, cy - along * uy
    across = px * px + py * py
    if across < core.SPEED * core.SPEED:
      k = math.sqrt(core.SPEED * core.SPEED - across)
      hx, hy = k * ux - px, k * uy - py
    else:
      hx, hy = -px, -py
  elif d > 0.0:
    h = 0.5 * spacing
    hx = _time_at(t_field, spacing, margin, x - h, y) - _time_at(t_field, spacing, margin, x + h, y)
    hy = _time_at(t_field, spacing, margin, x, y - h) - _time_at(t_field, spacing, margin, x, y + h)
  return shared.down_gradient_rate(state, hx, hy, gx, gy)


@numba.njit(cache=True, error_model="numpy")
def _sail_current(state, field, t_field, spacing, margin, sign, first, back, cap, max_steps,
                  gate_reward, out_of_bounds_reward, samples, actions):
  """One episode in the current from `state` (changed in place): the first turns, then
  `current_rate`; stops at the gate, off the field, at `max_steps` or `cap` steps.
  Returns (event, steps, return); the turning rates into `actions` (as far as it goes)."""
  steps, total = 0, 0.0
  while True:
    r = _turn(steps, sign, first, back)
    if math.isnan(r):
      r = current_rate(state, field, t_field, spacing, margin)
    if steps < actions.shape[0]:
      actions[steps] = r
    current_core.drift_control(state, r, samples, field)
    steps += 1
    event, _ = core.steer_event(samples, core.GATE, core.FIELD_SIZE)
    total += core.STEP_REWARD
    if event == core.SUCCESS:
      total += gate_reward
    elif event == core.FAILURE:
      total += out_of_bounds_reward
    if event != core.NO_EVENT or steps >= max_steps or steps >= cap:
      return event, steps, total


@numba.njit(cache=True)
def _plan_current(starts, field, t_field, spacing, margin, firsts, backs, max_steps,
                  gate_reward, out_of_bounds_reward, best, choice, actions):
  """`plan_current`'s search: best[i] = (passed, steps, return), choice[i] = (sign,
  first, back); the chosen episode's turning rates into actions[i]."""
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  state = np.empty(4)
  none = np.empty(0)
  for i in range(starts.shape[0]):
    state[:] = starts[i]
    event, steps, total = _sail_current(state, field, t_field, spacing, margin, 1.0, 0, 0,
                                        max_steps, max_steps, gate_reward,
                                        out_of_bounds_reward, samples, none)
    passed = event == core.SUCCESS
    best[i, 0], best[i, 1], best[i, 2] = passed, steps, total
    choice[i, 0], choice[i, 1], choice[i, 2] = 1.0, 0, 0
    cap = steps if passed else max_steps
    for sign in (1.0, -1.0):
      for first in firsts:
        for back in backs:
          state[:] = starts[i]
          event, steps, total = _sail_current(state, field, t_field, spacing, margin, sign,
                                              first, back, cap, max_steps, gate_reward,
                                              out_of_bounds_reward, samples, none)
          if event == core.SUCCESS and (steps < cap or not best[i, 0]):
            best[i, 0], best[i, 1], best[i, 2] = 1.0, steps, total
            choice[i, 0], choice[i, 1], choice[i, 2] = sign, first, back
            cap = steps
    if actions.shape[0] > 0:
      state[:] = starts[i]
      _sail_current(state, field, t_field, spacing, margin, choice[i, 0], int(choice[i, 1]),
                    int(choice[i, 2]), max_steps, max_steps, gate_reward,
                    out_of_bounds_reward, samples, actions[i])


# ---- regatta ---------------------------------------------------------------------------

SHORTCUT_POINTS = 21           # points across a gate the scripted helmsman weighs
TURN_EARLY_M = 12.0            # it turns for the gate after once this near its aim point
NEAREST = 1                    # candidate 1: the gate's nearest point
REGATTA_POINTS = 5             # candidates 2..6: fixed points spread across the gate
LINED_UP = NEAREST + REGATTA_POINTS + 1   # 7 and 8: lined up with it, along or against
TOWARDS = LINED_UP + 2         # 9..13: the two legs through it to a point of the gate after
EARLY = TOWARDS + REGATTA_POINTS          # 14..19: the scripted helmsman turning for the
EARLY_M = np.array([0.0, 4.0, 8.0, 16.0, 20.0, 30.0])    # gate after at these distances
N_REGATTA_CANDIDATES = EARLY + len(EARLY_M)


@numba.njit(cache=True, error_model="numpy")
def _nearest_point(x, y, ax, ay, ex, ey):
  """The point of the gate from (ax, ay) to (ax + ex, ay + ey), its posts moved in by
  INSET_M, nearest (x, y)."""
  width = math.hypot(ex, ey)
  low = INSET_M / width
  u = min(max(((x - ax) * ex + (y - ay) * ey) / (width * width), low), 1.0 - low)
  return ax + u * ex, ay + u * ey


@numba.njit(cache=True, error_model="numpy")
def shortcut_point(x, y, ax, ay, ex, ey, nx, ny):
  """The point of the gate from (ax, ay) to (ax + ex, ay + ey) (its posts moved in by
  INSET_M) on the shortest two legs from (x, y) through it to (nx, ny): the best of
  SHORTCUT_POINTS evenly spread."""
  width = math.hypot(ex, ey)
  low = INSET_M / width
  best, bx, by = np.inf, ax, ay
  for k in range(SHORTCUT_POINTS):
    u = low + (1.0 - 2.0 * low) * k / (SHORTCUT_POINTS - 1)
    px, py = ax + u * ex, ay + u * ey
    length = math.hypot(px - x, py - y) + math.hypot(nx - px, ny - py)
    if length < best:
      best, bx, by = length, px, py
  return bx, by


@numba.njit(cache=True, error_model="numpy")
def scripted_target(x, y, gate, after, centre_after, early_m):
  """The scripted helmsman's aim point: the point of `gate` (posts, rows (x, y)) on the
  shortest two legs through it to `centre_after`, the centre of the gate after it; once
  within `early_m` of that point, the point of the gate after (`after[0]`'s posts)
  nearest the ship, as the ship, answering its rudder 5 s late, still sails through. At
  the last gate (`after` of no gates) the gate's nearest point."""
  ax, ay = gate[0, 0], gate[0, 1]
  ex, ey = gate[1, 0] - ax, gate[1, 1] - ay
  if after.shape[0] == 0:
    return _nearest_point(x, y, ax, ay, ex, ey)
  tx, ty = shortcut_point(x, y, ax, ay, ex, ey, centre_after[0], centre_after[1])
  if math.hypot(tx - x, ty - y) >= early_m:
    return tx, ty
  bx, by = after[0, 0, 0], after[0, 0, 1]
  return _nearest_point(x, y, bx, by, after[0, 1, 0] - bx, after[0, 1, 1] - by)


@numba.njit(cache=True, error_model="numpy")
def regatta_rate(state, course, posts, gate, mode, reach):
  """The regatta's helmsmen for gate `gate`: mode 0, the scripted helmsman
  (`scripted_target` with TURN_EARLY_M); NEAREST for the gate's nearest point;
  NEAREST + j (j = 1..REGATTA_POINTS) for the j-th of points spread evenly across it;
  LINED_UP and LINED_UP + 1 line up with the gate along its heading or against it
  (`goal_rate` with `reach` and HELMSMAN_SLOPE); TOWARDS + j for the gate's point on
  the two shortest legs to the j-th point across the gate after it; EARLY + k the
  scripted helmsman turning for the gate after at EARLY_M[k]. Aim points stay INSET_M
  inside the posts; at the last gate, TOWARDS.. and EARLY.. are the nearest point."""
  x, y = state[0], state[1]
  ax, ay = posts[gate, 0, 0], posts[gate, 0, 1]
  ex, ey = posts[gate, 1, 0] - ax, posts[gate, 1, 1] - ay
  last = gate + 1 >= course.shape[0]
  if mode == 0 or mode >= EARLY:
    early = TURN_EARLY_M if mode == 0 else EARLY_M[mode - EARLY]
    after = posts[gate + 1:gate + 2]
    tx, ty = scripted_target(x, y, posts[gate], after, course[min(gate + 1, course.shape[0] - 1)],
                             early)
  elif mode == NEAREST or (mode >= TOWARDS and last):
    tx, ty = _nearest_point(x, y, ax, ay, ex, ey)
  elif mode < LINED_UP:
    u = (mode - NEAREST - 0.5) / REGATTA_POINTS
    tx, ty = ax + u * ex, ay + u * ey
  elif mode < TOWARDS:
    rad = math.radians(course[gate, 2])
    way = 1.0 if mode == LINED_UP else -1.0
    desired = np.empty(4)
    desired[0], desired[1] = course[gate, 0], course[gate, 1]
    desired[2], desired[3] = way * math.sin(rad), way * math.cos(rad)
    return goal_rate(state, desired, reach, HELMSMAN_SLOPE)
  else:
    u = (mode - TOWARDS + 0.5) / REGATTA_POINTS
    nx = posts[gate + 1, 0, 0] + u * (posts[gate + 1, 1, 0] - posts[gate + 1, 0, 0])
    ny = posts[gate + 1, 0, 1] + u * (posts[gate + 1, 1, 1] - posts[gate + 1, 0, 1])
    tx, ty = shortcut_point(x, y, ax, ay, ex, ey, nx, ny)
  return core.pilot_turn_rate(state, tx, ty)


class RegattaRules(collections.namedtuple(
    "RegattaRules", "max_steps gate_reward finish_reward out_of_bounds_reward reach")):
  """The regatta's step limit and rewards, and the lined-up helmsmen's reach (m), as the
  compiled planner reads them."""


@numba.njit(cache=True, error_model="numpy")
def _sail_regatta(state, course, posts, next_gate, steps, total, mode, sign, first, stop,
                  cap, rules, samples, actions):
  """Sails on from `state` (in place), `steps` control steps and `total` reward into the
  episode with `next_gate` to pass: the first turns (counted from the episode's start),
  then helmsman `mode` for that gate, then the scripted helmsman (mode 0) for the rest,
  or, with `stop`, a stop once that gate is passed. Ends at the finish, off the field,
  at the step limit or `cap` steps (`rules`: a `RegattaRules`). Returns (event, next
  gate, steps, return)."""
  gate = next_gate
  event = core.NO_EVENT
  while True:
    r = _turn(steps, sign, first, 0)
    if math.isnan(r):
      r = regatta_rate(state, course, posts, next_gate, mode if next_gate == gate else 0,
                       rules.reach)
    if steps < actions.shape[0]:
      actions[steps] = r
    core.euler_control(state, r, samples)
    steps += 1
    event, reward, next_gate = regatta_core.course_outcome(
        samples, posts, next_gate, rules.gate_reward, rules.finish_reward,
        rules.out_of_bounds_reward)
    total += reward
    if (event == core.SUCCESS or event == core.FAILURE or steps >= rules.max_steps
        or steps >= cap):
      return event, next_gate, steps, total
    if stop and next_gate != gate:
      return event, next_gate, steps, total


@numba.njit(cache=True)
def _plan_regatta(starts, courses, modes, firsts, rules, best, choice, actions):
  """`plan_regatta`'s rollout: best[i] = (finished, gates passed, steps, return),
  choice[i, k] the candidate taken at gate k (-1: never reached), choice[i, -1] the first
  turn (sign times its steps). The first `modes` of `regatta_rate`'s candidates are
  tried (1: the scripted helmsman alone, with the first turns)."""
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  state = np.empty(4)
  trial = np.empty(4)
  none = np.empty(0)
  gates = courses.shape[1]
  posts = np.empty((gates, 2, 2))
  for i in range(starts.shape[0]):
    course = courses[i]
    regatta_core.posts_into(course, posts)
    row = actions[i] if actions.shape[0] > 0 else none
    state[:] = starts[i]
    next_gate, steps, total = 0, 0, 0.0
    event = core.NO_EVENT
    choice[i, :] = -1
    sign, first = 1.0, 0           # the first turn, chosen at the first gate
    while True:
      # The candidates for gate `next_gate`, each sailed to the end; candidate 0 (the
      # scripted helmsman) first, a later one kept only if strictly better: a finish
      # beats none, then the greater return (among finishes, the fewer steps).
      best_total, best_mode, best_sign, best_first = -np.inf, 0, sign, first
      best_finished = False
      cap = rules.max_steps
      n_first = firsts.shape[0] if steps == 0 else 0
      for c in range(modes + 2 * n_first):
        mode, c_sign, c_first = c, sign, first
        if c >= modes:
          mode = 0
          c_sign = 1.0 if (c - modes) % 2 == 0 else -1.0
          c_first = firsts[(c - modes) // 2]
        trial[:] = state
        e, g, s, t = _sail_regatta(trial, course, posts, next_gate, steps, total, mode, c_sign,
                                   c_first, False, cap, rules, samples, none)
        finished = e == core.SUCCESS
        if (finished and not best_finished) or (finished == best_finished and t > best_total):
          best_total, best_mode, best_sign, best_first = t, mode, c_sign, c_first
          best_finished = finished
          if finished:
            cap = s
      if steps == 0:
        sign, first = best_sign, best_first
        choice[i, gates] = sign * first
      choice[i, next_gate] = best_mode
      gate = next_gate
      event, next_gate, steps, total = _sail_regatta(
          state, course, posts, next_gate, steps, total, best_mode, sign, first, True,
          rules.max_steps, rules, samples, row)
      if (event == core.SUCCESS or event == core.FAILURE or steps >= rules.max_steps
          or next_gate == gate):
        break
    best[i, 0] = event == core.SUCCESS
    best[i, 1], best[i, 2], best[i, 3] = next_gate, steps, total


# ---- the scripted helmsmen as policies of the observation ----------------------------

@numba.njit(cache=True, error_model="numpy")
def _current_batch(obs, field, t_field, out):
  for i in range(obs.shape[0]):
    out[i] = current_rate(obs[i, :4], field, t_field, GRID_M, MARGIN_M)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _seen_at(x, y, sin, cos, ahead, starboard):
  """The point `ahead` m ahead of and `starboard` m to the starboard of a ship at (x, y)
  heading (sin, cos) (`ship_regatta_core`'s view, inverted)."""
  return x + ahead * sin + starboard * cos, y + ahead * cos - starboard * sin


@numba.njit(cache=True, error_model="numpy")
def _regatta_batch(obs, out):
  gate, after, centre = np.empty((2, 2)), np.empty((1, 2, 2)), np.empty(2)
  for i in range(obs.shape[0]):
    x, y, theta = obs[i, 0], obs[i, 1], obs[i, 2]
    rad = math.radians(theta)
    sin, cos = math.sin(rad), math.cos(rad)
    gx, gy = _seen_at(x, y, sin, cos, obs[i, 4], obs[i, 5])
    heading = math.radians(theta + obs[i, 6])
    goal_core.posts_into(gx, gy, math.sin(heading), math.cos(heading), gate)
    centre[0], centre[1] = _seen_at(x, y, sin, cos, obs[i, 7], obs[i, 8])
    heading = math.radians(theta + obs[i, 9])
    goal_core.posts_into(centre[0], centre[1], math.sin(heading), math.cos(heading), after[0])
    tx, ty = scripted_target(x, y, gate, after[:1] if obs[i, 10] > 1.0 else after[:0], centre,
                             TURN_EARLY_M)
    out[i] = core.pilot_turn_rate(obs[i, :4], tx, ty)


class Helmsman:
  """The scripted helmsman of a ladder task at a level (the planner's first candidate),
  a batched policy of the environment's observation alone (`hpg_mj.benchmark.evaluate`
  scores it): the current's heads down the level's time field (`current_rate`), the
  goal's lines up with the episode's gate (`planners_goal.goal_rate`, reach
  HELMSMAN_REACH, slope HELMSMAN_SLOPE; blind to the hard level's obstacles), the
  regatta's sails for the next gate's point on the shortest two legs towards the gate
  after it, turning for that one early (`scripted_target`), the harbour's heads down its
  level's distance field round the obstacles (`planners_harbour.harbour_rate`)."""

  batched = True

  def __init__(self, name, level):
    if name not in ("ship_current", "ship_goal", "ship_regatta", "ship_harbour"):
      raise ValueError(f"no ladder helmsman for task {name!r}; allowed: ship_current, "
                       "ship_goal, ship_regatta, ship_harbour")
    self.name, self.level = name, level
    if name == "ship_harbour":
      planners_harbour.level_fields(level)
    elif name == "ship_current":
      self.field = current_core.level_field(level)
      self.t_field = level_time_field(level)
    elif name == "ship_goal":
      goal_core.level_range(level)
    else:
      regatta_core.level_layout(level)

  def __call__(self, obs):
    if self.name == "ship_harbour":
      return planners_harbour.helmsman(self.level, obs)
    if self.name == "ship_goal":
      states = np.ascontiguousarray(obs["observation"], dtype=np.float64).reshape(-1, 4)
      desired = np.ascontiguousarray(obs["desired_goal"], dtype=np.float64).reshape(-1, 4)
      out = np.empty(len(states))
      planners_goal.helmsman_batch(states, desired, out)
      return out
    width = 6 if self.name == "ship_current" else regatta_core.OBSERVATION_SIZE
    obs = np.ascontiguousarray(obs, dtype=np.float64).reshape(-1, width)
    out = np.empty(len(obs))
    if self.name == "ship_current":
      _current_batch(obs, self.field, self.t_field, out)
    else:
      _regatta_batch(obs, out)
    return out


# ---- the plans, from the benchmark's fixed starts --------------------------------------

def plan(name, level, starts, max_steps=core.STEER_MAX_STEPS, gate_reward=core.GATE_REWARD,
         out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD, actions=False):
  """The best known episode from each start of a ladder task (`hpg_mj.benchmark`'s
  `fixed_starts` dictionary: "state", and "gate" or "course"; the goal's from
  `planners_goal`, the harbour's from `planners_harbour`). Returns (outcome,
  choice, turning rates or None): outcome rows (passed, steps, return), on the regatta
  (finished, gates passed, steps, return); with `actions` the turning rates of each
  chosen episode, (n, max_steps), NaN after its end."""
  states = np.ascontiguousarray(starts["state"], dtype=np.float64).reshape(-1, 4)
  n = len(states)
  if name in ship_ladder.TASKS:       # the level's time limit, where shorter
    max_steps = int(ship_ladder.episode_steps(name, level, max_steps))
  rates = np.full((n, max_steps) if actions else (0, 0), np.nan)
  if name == "ship_current":
    outcome, choice = np.zeros((n, 3)), np.zeros((n, 3))
    _plan_current(states, current_core.level_field(level), level_time_field(level), GRID_M,
                  MARGIN_M, FIRST_TURNS, BACK_TURNS, max_steps, float(gate_reward),
                  float(out_of_bounds_reward), outcome, choice, rates)
  elif name == "ship_goal":
    outcome, choice, rates = planners_goal.plan(level, states, starts["gate"], max_steps,
                                                gate_reward, out_of_bounds_reward, actions)
  elif name == "ship_regatta":
    gates, spacing, _, _ = regatta_core.level_layout(level)
    courses = np.ascontiguousarray(starts["course"], dtype=np.float64).reshape(-1, gates, 3)
    outcome, choice = np.zeros((n, 4)), np.zeros((n, gates + 1))
    rules = RegattaRules(max_steps, float(gate_reward),
                         regatta_core.FINISH_REWARD,
                         float(out_of_bounds_reward), 0.5 * spacing)
    _plan_regatta(states, courses, N_REGATTA_CANDIDATES, FIRST_TURNS, rules, outcome, choice,
                  rates)
  elif name == "ship_harbour":
    outcome, choice, rates = planners_harbour.plan(level, states, max_steps, gate_reward,
                                                   out_of_bounds_reward, actions)
  else:
    raise ValueError(f"no ladder planner for task {name!r}; allowed: ship_current, ship_goal, "
                     "ship_regatta, ship_harbour")
  return outcome, choice, (rates if actions else None)


def reference_steps(name, level, starts):
  """Per start, the control steps of a ship that turns at once (a reference below the
  best known, what the gap to it is measured against): in the current, the time field
  at the start over 0.6 s (the grid's paths, within ~1.3% of the continuous least
  time); to the goal's gate, the straight line to it over 1.8 m a step (a lower
  bound); round the regatta, the shortest polyline from the start through its gates
  in order (over 101 points across each, less the 2 m a gate their spacing may add:
  a lower bound) over 1.8 m a step; in the harbour, the shortest grid path round the
  obstacles (`planners_harbour.reference_steps`)."""
  states = np.asarray(starts["state"], dtype=np.float64).reshape(-1, 4)
  step_m = core.SPEED * core.CONTROL_INTERVAL
  if name == "ship_harbour":
    return planners_harbour.reference_steps(level, states)
  if name == "ship_current":
    t_field = level_time_field(level)
    return np.array([_time_at(t_field, GRID_M, MARGIN_M, s[0], s[1]) for s in states]) \
        / core.CONTROL_INTERVAL
  if name == "ship_goal":
    out = []
    for state, gate in zip(states, starts["gate"]):
      a, b = goal_core.gate_posts(goal_core.check_gate(gate, "ship_goal", level),
                                  goal_core.TOLERANCES[level][0])
      t = np.clip((state[:2] - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
      out.append(np.linalg.norm(state[:2] - a - t * (b - a)) / step_m)
    return np.array(out)
  u = np.linspace(0.0, 1.0, 101)[:, None]
  out = []
  for state, course in zip(states, starts["course"]):
    posts = regatta_core.posts_of(course)
    length, previous = None, None
    for k in range(len(course)):
      points = posts[k, 0] + u * (posts[k, 1] - posts[k, 0])
      if previous is None:
        length = np.linalg.norm(points - state[:2], axis=1)
      else:
        length = np.min(length[:, None] + np.linalg.norm(
            previous[:, None, :] - points[None, :, :], axis=2), axis=0)
      previous = points
    out.append((length.min() - 2.0 * len(course)) / step_m)
  return np.array(out)
