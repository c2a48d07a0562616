"""The route past the paper (SPEC section 8) as compiled rules and a fused loop:
its root's tiles and choices, the targets they steer to, the aim subtask's view and
end, and `train`, every episode of the route on Equation 1. The agent, its
configuration and its step-by-step graph are `hpg_mj.agents.ship_beyond` (whose
docstring says what the route is and why); the scorer's helmsman
(`hpg_mj.benchmark`) steers to the same targets.
"""
import collections
import math

import numba
import numpy as np

from hpg_mj.hierarchy import ship_rules
from hpg_mj.learners import arrays
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import qlambda
from hpg_mj.learners import schedules
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core as core

PASSED, STEPS, CALLS, AIM_RUNS, AIM_SUCCESS, RETURN = range(6)
N_RECORD = 6
GATE_X = 0.5 * (core.GATE[0, 0] + core.GATE[1, 0])
GATE_Y = core.GATE[0, 1]
GATE_WIDTH = core.GATE[1, 0] - core.GATE[0, 0]
APPROACH_DX = (-100.0, 0.0, 100.0)   # approach points: x of the gate's middle + these
DISTANCE_CLIP = 400.0                # the aim state's distance saturates here (m)
# The shipped route's targets (its Config's defaults): the gate's posts moved in by
# INSET_M, the approach points APPROACH_M before its line, a call ended within RADIUS_M.
INSET_M, APPROACH_M, RADIUS_M = 2.0, 80.0, 15.0

Settings = collections.namedtuple("Settings", (
    "root_alpha", "root_trace_decay", "root_epsilon_threshold", "root_epsilon_every",
    "root_epsilon_divisor", "root_inset_m", "root_approach_within_m",
    "root_approach_m",
    "alpha", "trace_gamma", "baseline", "max_steps", "width_alpha", "log_sigma_low",
    "log_sigma_high", "radius_m", "shaping",
    "sqrt_error", "reflect_at",
    "environment_max_steps", "environment_gate_reward", "environment_out_of_bounds_reward"))
RootTable = collections.namedtuple("RootTable", ("q", "index", "value", "count"))
# What `target_of` and a call's end read of the settings, at the shipped values (the
# scorer's helmsman steers to the same targets).
Targets = collections.namedtuple("Targets", ("root_inset_m", "root_approach_m", "radius_m"))
SHIPPED_TARGETS = Targets(INSET_M, APPROACH_M, RADIUS_M)


def settings(config):
  root, low, env = config.root, config.low_level, config.environment
  return Settings(float(root.alpha), float(root.trace_decay), float(root.epsilon_threshold),
                  int(root.epsilon_every), float(root.epsilon_divisor), float(root.inset_m),
                  float(root.approach_within_m), float(root.approach_m),
                  float(low.alpha), float(low.trace_gamma), float(low.baseline),
                  int(low.max_steps), float(low.width_alpha), math.log(low.sigma_low),
                  math.log(low.sigma_high), float(low.radius_m), float(low.shaping),
                  low.error_scale == "sqrt", error_coordinate(low.reflect_deg, low.error_scale),
                  int(env.max_steps), float(env.gate_reward), float(env.out_of_bounds_reward))


def root_coder(root):
  """The root's tiles over (x, y, heading): `cell_m` squares and `headings` sectors
  (the first centred on north), `tilings` of them offset along SPEC section 3's
  displacement. One tiling is the table of cells and sectors."""
  grid = int(math.ceil(core.FIELD_SIZE / root.cell_m))
  half = 180.0 / root.headings
  side = grid * root.cell_m
  return tiles_mod.TileCoder((0.0, 0.0, -half), (side, side, 360.0 - half),
                             (grid, grid, int(root.headings)), (False, False, True),
                             int(root.tilings))


# ---- the rules, one implementation for both paths ---------------------------------

@numba.njit(cache=True)
def root_tiles(state, tiling, view, out):
  """The root's state: the active tiles (one per tiling, into `out`) of the ship's
  position and heading (`view`: scratch for the three)."""
  view[0] = state[0]
  view[1] = state[1]
  view[2] = state[2]
  tiles_mod.active_tiles(view, tiling, out)


@numba.njit(cache=True)
def n_targets(s):
  return 1 + len(APPROACH_DX)


@numba.njit(cache=True)
def offered(state, s):
  """How many of the root's choices start here (their initiation sets, Sutton, Precup
  & Singh 1999): the gate everywhere, the approach points within
  `root_approach_within_m` of the gate line."""
  return n_targets(s) if abs(state[1] - GATE_Y) <= s.root_approach_within_m else 1


@numba.njit(cache=True)
def side_of(y):
  """Which side of the gate line a height lies on (the line itself counts as north)."""
  return 1.0 if y >= GATE_Y else -1.0


@numba.njit(cache=True)
def target_of(action, state, side, s):
  """The point the root's `action` steers to now. Action 0, *gate*: the point of
  the gate (its posts moved in by `root_inset_m`) nearest the ship, followed as
  the ship moves (a continuous target). Actions 1-3, *approach*: fixed points
  `root_approach_m` before the gate line on the side `side` of the call's start,
  at the gate's middle x + APPROACH_DX."""
  if action == 0:
    low = core.GATE[0, 0] + s.root_inset_m
    high = core.GATE[1, 0] - s.root_inset_m
    return min(max(state[0], low), high), GATE_Y
  return GATE_X + APPROACH_DX[action - 1], GATE_Y + side * s.root_approach_m


def error_coordinate(e_deg, error_scale):
  """A heading error's coordinate on the aim tiles."""
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
def aim_outcome(samples, state, action, tx, ty, steps_in_call, global_event, s):
  """After one control step inside an aim call: (local event, G). SUCCESS through
  the gate, or (approach) within `radius_m` of the target; FAILURE off the field,
  after `max_steps`, or (gate) across the gate line beside the gate; G = the
  heading shaping towards the target (SPEC section 3's G, times `shaping`), +100 / -100."""
  event = core.NO_EVENT
  if global_event == core.SUCCESS:
    event = core.SUCCESS
  elif global_event == core.FAILURE:
    event = core.FAILURE
  else:
    for k in range(1, samples.shape[0]):
      if action == 0:
        if (samples[k - 1, 1] - GATE_Y) * (samples[k, 1] - GATE_Y) < 0.0:
          event = core.FAILURE                           # crossed the line, missed the gate
          break
      elif math.hypot(samples[k, 0] - tx, samples[k, 1] - ty) <= s.radius_m:
        event = core.SUCCESS
        break
    if event == core.NO_EVENT and steps_in_call >= s.max_steps:
      event = core.FAILURE
  internal = s.shaping * core.shaping_reward(state[0], state[1], state[2], tx, ty)
  if event == core.SUCCESS:
    internal += core.GATE_REWARD
  elif event == core.FAILURE:
    internal += core.OUT_OF_BOUNDS_REWARD
  return event, internal


@numba.njit(cache=True)
def run_aim(state, action, trace, width, values, tiling, s, learn, sample, rng_state,
            steps_before, scratch):
  """One call of the aim subtask for the root's `action` from `state` (in place).
  Returns (global event, local event, reward to the root, control steps)."""
  tiles, next_tiles, psi, psi_width, samples, view = scratch
  el.reset(trace)                                       # Eq. 3: z <- 0
  el.reset(width)
  reward_root = 0.0
  k = 0
  side = side_of(state[1])
  tx, ty = target_of(action, state, side, s)
  while True:
    reflected = aim_view(state, tx, ty, view, s.sqrt_error, s.reflect_at)
    tiles_mod.active_tiles(view, tiling, tiles)
    r = policies.gaussian_choose(trace, values, tiles, psi, s.alpha, s.baseline,
                                 core.MAX_TURN_RATE, learn, sample, rng_state, width, psi_width,
                                 s.width_alpha, s.log_sigma_low, s.log_sigma_high)
    r *= reflected                                       # the reflection's r -> -r
    core.euler_control(state, r, samples)
    k += 1
    global_event, reward = core.global_outcome(samples, s.environment_gate_reward,
                                               s.environment_out_of_bounds_reward)
    reward_root += reward
    tx, ty = target_of(action, state, side, s)           # the target after the step
    local_event, internal = aim_outcome(samples, state, action, tx, ty, k, global_event, s)
    ended = (global_event != core.NO_EVENT or local_event != core.NO_EVENT
             or steps_before + k >= s.environment_max_steps)
    if learn:
      if not ended:
        aim_view(state, tx, ty, view, s.sqrt_error, s.reflect_at)
        tiles_mod.active_tiles(view, tiling, next_tiles)
      policies.gaussian_learn(trace, values, tiles, next_tiles, s.alpha, s.trace_gamma,
                              s.baseline, core.STEP_REWARD + internal, ended, width,
                              s.width_alpha)
    if ended:
      return global_event, local_event, reward_root, k


@numba.njit(cache=True)
def train(n_episodes, learn, sample, rng_state, root, root_tiling, schedule, trace, width,
          values, tiling, s, record, fixed_start):
  """`n_episodes` episodes of the full task (Algorithm 1 over this graph); with
  learn=False only the policy runs, sampled or greedy (epsilon 0, u = m)."""
  eps_state, outcomes, counts = schedule
  state = np.empty(4)
  n = tiling.offsets.shape[0]
  scratch = (np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64), np.empty(n),
             np.empty(n), np.empty((core.SAMPLES_PER_CONTROL + 1, 2)), np.empty(3))
  n_actions = n_targets(s)
  n_root = root_tiling.offsets.shape[0]
  here = np.empty(n_root, dtype=np.int64)              # the root's tiles now
  there = np.empty(n_root, dtype=np.int64)             # and after the call
  root_view = np.empty(3)
  for episode in range(n_episodes):
    if fixed_start.shape[0] == 4:
      arrays.copy_into(state, fixed_start)
    else:
      ship_rules.sample_start(rng_state, state)
    qlambda.clear(root.count)
    steps = 0
    total = 0.0
    root_tiles(state, root_tiling, root_view, here)
    epsilon = eps_state[0] if sample else 0.0
    a = qlambda.tiled_epsilon_greedy(root.q, here, n_actions, offered(state, s), epsilon,
                                     rng_state)
    row = record[episode]
    row[:] = 0.0
    while True:
      g_event, l_event, reward, k = run_aim(state, a, trace, width, values, tiling, s,
                                            learn, sample, rng_state, steps, scratch)
      if steps + k < s.environment_max_steps and (g_event == core.NO_EVENT
                                                   or g_event == core.SUCCESS):
        success = l_event == core.SUCCESS
        row[AIM_RUNS] += 1
        row[AIM_SUCCESS] += success
        if learn:
          schedules.record_run(outcomes, counts, 0, success)
          schedules.record_run(outcomes, counts, 1, success)
      steps += k
      total += reward
      row[CALLS] += 1
      terminal = g_event != core.NO_EVENT
      truncated = (not terminal) and steps >= s.environment_max_steps
      root_tiles(state, root_tiling, root_view, there)
      n_there = offered(state, s)
      if terminal or truncated:
        if learn:
          qlambda.tiled_update(root.q, n_actions, root.index, root.value, root.count, here, a,
                               reward, there, n_there, 0, terminal, s.root_alpha, 1.0,
                               s.root_trace_decay)
          qlambda.clear(root.count)
        break
      a_next = qlambda.tiled_epsilon_greedy(root.q, there, n_actions, n_there, epsilon,
                                            rng_state)
      if learn:
        qlambda.tiled_update(root.q, n_actions, root.index, root.value, root.count, here, a,
                             reward, there, n_there, a_next, False, s.root_alpha, 1.0,
                             s.root_trace_decay)
      arrays.copy_into(here, there)
      a = a_next
    row[PASSED] = g_event == core.SUCCESS
    row[STEPS] = steps
    row[RETURN] = total
    if learn:
      schedules.end_episode(eps_state, outcomes, counts, s.root_epsilon_threshold,
                            s.root_epsilon_every, s.root_epsilon_divisor)


def aim_coder(low):
  reflected = low.reflect_deg < 180.0
  low_error = -error_coordinate(low.reflect_deg, low.error_scale)
  return tiles_mod.TileCoder((low_error, -core.MAX_TURN_RATE, 0.0),
                             (180.0, core.MAX_TURN_RATE, DISTANCE_CLIP), tuple(low.tiles),
                             (not reflected, False, False), low.tilings)
