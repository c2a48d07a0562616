"""The goal's best known score (SPEC sections 7.1 and 11): a planner that sees the
episode's gate (and at `hard` the level's map: `ship_goal_core.OBSTACLES`) and sails the
analytic ship of the batch environments, its arithmetic and the goal's rule to the bit
(`ship_goal_core.step_outcome`), from each start; dispatched from `planners.plan`.

- The line-up helmsman (`goal_rate`), of the observation alone: it makes for the point
  `reach` m before the gate on its line of approach and, once behind the gate inside a
  cone of lateral slope `slope` and heading towards it, for GOAL_PAST_M past its
  centre. The scripted helmsman is the pair (HELMSMAN_REACH, HELMSMAN_SLOPE); it does
  not see obstacles.
- Among obstacles, the field helmsman (`field_rate`): the same line-up, but until it
  is within LINE_UP_M of the line-up point (or inside the cone, at most APPROACH_M
  behind the gate, where the gate's approach is clear) it heads down a distance field
  to that point round the obstacles grown by a safety margin
  (`planners_harbour.distance_field`, seeded at the point), one field per episode for
  each reach of FIELD_REACHES and each margin of FIELD_SAFETY_M (a point too near
  the field's edge to be sailed to is left out).
- The search (`_plan_goal`): the scripted helmsman first, then every (reach, slope) of
  the line-up grid and every (field, slope) without a first turn, then first turns
  (full rudder either way for 2-34 control steps, then the other way for 0 or 6)
  before the GOAL_KEEP best of those; it keeps the fewest control steps to the gate,
  and the scripted helmsman's episode where none passes. In open water there are no
  fields and the search is the line-up grid's alone.
"""
import collections
import math

import numba
import numpy as np

from hpg_mj import planners_harbour
from hpg_mj import planners_shared as shared
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_goal_core as goal_core

GOAL_REACHES = np.array([0.0, 10.0, 20.0, 35.0, 60.0, 100.0, 150.0])   # m before the gate
GOAL_SLOPES = np.array([0.0, 0.2, 0.4, 0.7, 1.0])   # the cone behind the gate: |lateral| <=
GOAL_CONE_M = 40.0                            # GOAL_CONE_M + slope * distance behind
GOAL_PAST_M = 60.0                            # the aim point past the gate's centre
HELMSMAN_REACH, HELMSMAN_SLOPE = 0.0, 0.7     # the scripted helmsman's
GOAL_KEEP = 3                                 # candidates tried after first turns
# Among obstacles: the line-up points the fields lead to (m before the gate; within the
# approach that `ship_goal_core.gate_clear` keeps clear), the obstacles' margins, and
# how near the point the field helmsman turns to line up.
FIELD_REACHES = np.array([30.0, 80.0, 150.0])
FIELD_SAFETY_M = np.array([5.0, 12.0])
LINE_UP_M = 40.0


class GoalRules(collections.namedtuple(
    "GoalRules", "max_steps gate_reward out_of_bounds_reward tolerance islands piers cells")):
  """The goal's step limit, rewards and tolerance, and its obstacles (islands, pier
  frames, cells: `ship_goal_core.level_shapes`), as the compiled planner reads them."""


class GoalSearch(collections.namedtuple("GoalSearch", "reaches slopes firsts backs keep")):
  """The search's line-up grid (reaches, slopes), its first turns (`firsts`, `backs`)
  and how many candidates are tried after them (`keep`)."""


@numba.njit(cache=True, error_model="numpy", inline="always")
def _in_cone(state, desired, slope, behind_m):
  """Whether the ship is behind the gate, at most `behind_m` m, inside the cone
  |lateral| <= GOAL_CONE_M + slope * distance and heading towards the gate line."""
  gx, gy, s, c = desired[0], desired[1], desired[2], desired[3]
  rx, ry = state[0] - gx, state[1] - gy
  forward = rx * s + ry * c
  lateral = rx * c - ry * s
  theta = math.radians(state[2])
  toward = math.sin(theta) * s + math.cos(theta) * c
  return (-behind_m <= forward < 0.0 and abs(lateral) <= GOAL_CONE_M - slope * forward
          and toward > 0.0)


@numba.njit(cache=True, error_model="numpy")
def goal_rate(state, desired, reach, slope):
  """The goal's helmsman, of the observation alone: behind the gate (`desired` [x, y,
  sin, cos]), inside the cone |lateral| <= GOAL_CONE_M + slope * distance and heading
  towards the gate line, it sails for GOAL_PAST_M past the gate's centre; anywhere else
  for the point `reach` m before the gate on its line of approach."""
  gx, gy, s, c = desired[0], desired[1], desired[2], desired[3]
  if _in_cone(state, desired, slope, np.inf):
    return core.pilot_turn_rate(state, gx + GOAL_PAST_M * s, gy + GOAL_PAST_M * c)
  return core.pilot_turn_rate(state, gx - reach * s, gy - reach * c)


@numba.njit(cache=True, error_model="numpy")
def field_rate(state, desired, reach, slope, field, spacing):
  """The field helmsman: `goal_rate`'s line-up inside the cone (at most APPROACH_M
  behind the gate) or within LINE_UP_M of the point `reach` m before the gate;
  elsewhere down the gradient of `field`, the distance field to that point."""
  gx, gy, s, c = desired[0], desired[1], desired[2], desired[3]
  if _in_cone(state, desired, slope, goal_core.APPROACH_M):
    return core.pilot_turn_rate(state, gx + GOAL_PAST_M * s, gy + GOAL_PAST_M * c)
  ax, ay = gx - reach * s, gy - reach * c
  x, y = state[0], state[1]
  if math.hypot(ax - x, ay - y) < LINE_UP_M:
    return core.pilot_turn_rate(state, ax, ay)
  h = 0.5 * spacing
  hx = (planners_harbour.distance_at(field, spacing, x - h, y)
        - planners_harbour.distance_at(field, spacing, x + h, y))
  hy = (planners_harbour.distance_at(field, spacing, x, y - h)
        - planners_harbour.distance_at(field, spacing, x, y + h))
  return shared.down_gradient_rate(state, hx, hy, ax, ay)


@numba.njit(cache=True, error_model="numpy")
def _sail_goal(state, desired, reach, slope, field, sign, first, back, cap, rules, samples,
               achieved, actions):
  """One goal episode from `state` (in place): the first turns, then `goal_rate` (or,
  given a `field`, `field_rate`); judged as the batch environment judges
  (`ship_goal_core.step_outcome` at the end of each step). Returns (event, steps,
  return)."""
  steps, total = 0, 0.0
  while True:
    r = shared.first_turn_rate(steps, sign, first, back)
    if math.isnan(r):
      if field.shape[0] > 1:
        r = field_rate(state, desired, reach, slope, field, planners_harbour.GRID_M)
      else:
        r = goal_rate(state, desired, reach, slope)
    if steps < actions.shape[0]:
      actions[steps] = r
    core.euler_control(state, r, samples)
    steps += 1
    theta = math.radians(state[2])
    achieved[0], achieved[1] = state[0], state[1]
    achieved[2], achieved[3] = math.sin(theta), math.cos(theta)
    event, reward = goal_core.step_outcome(samples, achieved, desired, rules.gate_reward,
                                           rules.out_of_bounds_reward, rules.tolerance,
                                           rules.islands, rules.piers, rules.cells)
    total += reward
    if event != core.NO_EVENT or steps >= rules.max_steps or steps >= cap:
      return event, steps, total


@numba.njit(cache=True)
def _candidate(q, reaches, slopes, fields, field_reaches):
  """Candidate q of the search: (reach, slope, field index or -1): the line-up grid's
  pairs first, then each field with each slope."""
  n_pairs = reaches.shape[0] * slopes.shape[0]
  if q < n_pairs:
    return reaches[q // slopes.shape[0]], slopes[q % slopes.shape[0]], -1
  q -= n_pairs
  f = q // slopes.shape[0]
  return field_reaches[f], slopes[q % slopes.shape[0]], f


@numba.njit(cache=True)
def _plan_goal(starts, gates, fields, usable, field_reaches, search, rules, best, choice,
               actions):
  """The module's search for one start per row: best[i] = (passed, steps, return),
  choice[i] = (reach, slope, field or -1, sign, first, back); `fields` (n, k, m, m): the
  start's k fields, `usable` (n, k) those of a point that can be sailed to,
  `field_reaches` (k,). The scripted helmsman first, then every candidate without a
  first turn, then every first turn before the `keep` best of those (a later episode
  kept only if it passes in fewer steps)."""
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  state = np.empty(4)
  achieved = np.empty(4)
  none = np.empty(0)
  no_field = np.zeros((1, 1))
  reaches, slopes, firsts, backs, keep = (search.reaches, search.slopes, search.firsts,
                                          search.backs, search.keep)
  max_steps = rules.max_steps
  n_candidates = reaches.shape[0] * slopes.shape[0] + fields.shape[1] * slopes.shape[0]
  plain = np.empty(n_candidates)
  for i in range(starts.shape[0]):
    desired = gates[i]
    state[:] = starts[i]
    event, steps, total = _sail_goal(state, desired, HELMSMAN_REACH, HELMSMAN_SLOPE, no_field,
                                     1.0, 0, 0, max_steps, rules, samples, achieved, none)
    passed = event == core.SUCCESS
    best[i, 0], best[i, 1], best[i, 2] = passed, steps, total
    choice[i, 0], choice[i, 1], choice[i, 2] = HELMSMAN_REACH, HELMSMAN_SLOPE, -1
    choice[i, 3], choice[i, 4], choice[i, 5] = 1.0, 0, 0
    for stage in range(2):
      order = np.argsort(plain, kind="mergesort") if stage == 1 else np.arange(n_candidates)
      for k in range(n_candidates if stage == 0 else min(keep, n_candidates)):
        q = order[k]
        reach, slope, f = _candidate(q, reaches, slopes, fields[i], field_reaches)
        if f >= 0 and not usable[i, f]:
          plain[q] = np.inf          # a point that cannot be sailed to: no field
          continue
        field = no_field if f < 0 else fields[i, f]
        for sign in (1.0, -1.0):
          for t in range(firsts.shape[0] + 1):
            first = 0 if t == 0 else firsts[t - 1]
            for back in backs:
              if (stage == 0) != (first == 0) or (first == 0 and (back > 0 or sign < 0)):
                continue          # stage 0: no first turn (once); stage 1: first turns
              cap = best[i, 1] if best[i, 0] else max_steps
              state[:] = starts[i]
              event, steps, total = _sail_goal(state, desired, reach, slope, field, sign,
                                               first, back, cap, rules, samples, achieved,
                                               none)
              if stage == 0:
                plain[q] = steps if event == core.SUCCESS else np.inf
              if event == core.SUCCESS and (steps < cap or not best[i, 0]):
                best[i, 0], best[i, 1], best[i, 2] = 1.0, steps, total
                choice[i, 0], choice[i, 1], choice[i, 2] = reach, slope, f
                choice[i, 3], choice[i, 4], choice[i, 5] = sign, first, back
    if actions.shape[0] > 0:
      f = int(choice[i, 2])
      state[:] = starts[i]
      _sail_goal(state, desired, choice[i, 0], choice[i, 1], no_field if f < 0 else fields[i, f],
                 choice[i, 3], int(choice[i, 4]), int(choice[i, 5]), max_steps, rules,
                 samples, achieved, actions[i])


def target_fields(desired, islands, piers):
  """The distance fields (len(FIELD_REACHES) * len(FIELD_SAFETY_M), m, m) of one
  episode's gate `desired` [x, y, sin, cos]: to each line-up point of FIELD_REACHES,
  round the obstacles grown by each margin of FIELD_SAFETY_M; all inf for a point
  within the field's edge margin (not sailed to)."""
  n = int(round(core.FIELD_SIZE / planners_harbour.GRID_M)) + 1
  out = np.full((len(FIELD_REACHES) * len(FIELD_SAFETY_M), n, n), np.inf)
  low, high = planners_harbour.EDGE_MARGIN_M, core.FIELD_SIZE - planners_harbour.EDGE_MARGIN_M
  for a, reach in enumerate(FIELD_REACHES):
    ax, ay = desired[0] - reach * desired[2], desired[1] - reach * desired[3]
    if not (low <= ax <= high and low <= ay <= high):
      continue
    i, j = (int(round(v / planners_harbour.GRID_M)) for v in (ax, ay))
    for b, safety in enumerate(FIELD_SAFETY_M):
      planners_harbour.distance_field_into(islands, piers, np.array([i * n + j]), float(safety),
                                           out[a * len(FIELD_SAFETY_M) + b])
  return out


def plan(level, states, gates, max_steps, gate_reward, out_of_bounds_reward, actions):
  """`planners.plan` for the goal at `level` from `states` (n, 4) through `gates` (n, 3)
  rows [x, y, heading_deg]: (outcome rows (passed, steps, return), choice rows (reach,
  slope, field or -1, sign, first, back), the turning rates (n, max_steps), NaN after
  each episode's end, or an empty array)."""
  desired = np.array([goal_core.check_gate(g, "ship_goal", level) for g in gates],
                     dtype=np.float64).reshape(-1, 4)
  islands, piers, cells = goal_core.level_shapes(level)
  n = len(states)
  rates = np.full((n, max_steps) if actions else (0, 0), np.nan)
  outcome, choice = np.zeros((n, 3)), np.zeros((n, 6))
  k = len(FIELD_REACHES) * len(FIELD_SAFETY_M) if goal_core.OBSTACLES[level] else 0
  field_reaches = np.repeat(FIELD_REACHES, len(FIELD_SAFETY_M))[:k]
  states = np.ascontiguousarray(states, dtype=np.float64)
  search = GoalSearch(GOAL_REACHES, GOAL_SLOPES, shared.FIRST_TURNS, shared.BACK_TURNS,
                      GOAL_KEEP)
  rules = GoalRules(int(max_steps), float(gate_reward), float(out_of_bounds_reward),
                    goal_core.level_tolerance(level), islands, piers, cells)
  for i in range(n):       # one start at a time: its fields are 0.3 MB each
    fields = target_fields(desired[i], islands, piers)[None, :k] if k else np.zeros((1, 0, 1, 1))
    usable = np.isfinite(fields).any(axis=(2, 3))
    _plan_goal(states[i:i + 1], desired[i:i + 1], fields, usable, field_reaches, search, rules,
               outcome[i:i + 1], choice[i:i + 1], rates[i:i + 1] if actions else rates)
  return outcome, choice, rates


@numba.njit(cache=True, error_model="numpy")
def helmsman_batch(states, desired, out):
  """The scripted helmsman's turning rates (`goal_rate`) for rows of ships and gates."""
  for i in range(states.shape[0]):
    out[i] = goal_rate(states[i], desired[i], HELMSMAN_REACH, HELMSMAN_SLOPE)
