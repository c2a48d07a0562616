"""The goal-conditioned ship (SPEC section 11): a gate whose place and heading are drawn
each episode, and the rule that says when the ship has passed it, written on goals
alone so that Hindsight Experience Replay can ask it of any achieved and desired goal.
Free of MuJoCo (SPEC section 9); the ship itself is `ship_core`'s.

Goals are float64 `[x, y, sin(heading), cos(heading)]`: the *achieved goal* is the
ship's position and direction of travel at the end of a control step, the *desired
goal* the gate's centre and the heading to pass it with (its normal, clockwise from
north as every heading here). The gate is 100 m wide, as `ship/steer`'s, across that
heading: its posts stand 50 m either side of the centre.

A goal is *reached* when, in the gate's frame, the ship's position lies between the
posts (|lateral| <= 50 m), at most one control step of sailing past the gate line
(0 <= forward < 3 m/s * 0.6 s = 1.8 m), and its heading within 45 degrees of the
gate's. A ship sails at most 1.8 m in a control step, so one that crosses the line
between the posts heading with the gate ends that step inside the window: the pass is
seen at the end of the step that crosses the line, from the goals alone.

At `hard` the goal is also reached more exactly (`TOLERANCES`): a gate 50 m wide (posts
25 m either side) and the heading within 30 degrees. Drawing the gate anywhere with any
heading did not make the level hard: the steering hierarchy carried to the goal (its
medium-tuned values, tuning seed 0) passed 77% of its gates at hard, 79 normalized; with
these tolerances it passed 14% where the best known still reaches 98.7% of the bounds'
starts (measured on 300 of them) in 273 control steps at the median against 262. Nor did
the tolerances: the designed hierarchy that lines up with the gate (`ship_ladder_waypoints`)
still reached 99 normalized. So at `hard` the water also holds obstacles (`OBSTACLES`: the
harbour's `medium` islands and breakwaters, `ship_harbour_core`), which end the episode
when the sampled track touches one (AGROUND, the out-of-bounds penalty), and every gate
is drawn again until it stands clear of them (`gate_clear`). A helmsman that lines up
with the gate but does not see the obstacles passed 58% of such gates (a prototype, 300
gates). The ship sees them through the harbour's rangefinders, a fourth key of the
observation (`ranges`, at every level: 150 m, nothing seen, in open water); the goals and
`compute_reward`, which read goals alone, are the same at every level, and a step that
ran aground says so in its info, which `compute_reward` reads.
"""
import collections
import functools
import math

import numba
import numpy as np

from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_harbour_core as harbour_core

HALF_WIDTH = 50.0                                   # m, posts either side of the centre
WINDOW = core.SPEED * core.CONTROL_INTERVAL         # 1.8 m: one control step of sailing
HEADING_TOLERANCE_DEG = 45.0
# level -> (half the gate's width in m, the heading's tolerance in deg) of `reached`.
TOLERANCES = {
    "easy": (HALF_WIDTH, HEADING_TOLERANCE_DEG),
    "medium": (HALF_WIDTH, HEADING_TOLERANCE_DEG),
    "hard": (25.0, 30.0),             # a gate half as wide, the heading within 30 degrees
}

# level -> (lowest and highest centre coordinate in m, largest heading in deg): the
# centre uniform on [low, high]^2, the heading uniform on [-largest, largest).
LEVELS = {
    "easy": (300.0, 500.0, 30.0),     # near ship/steer's gate (400, 400), heading north +-30
    "medium": (200.0, 800.0, 90.0),   # the middle 600 m, any heading with a northward part
    "hard": (100.0, 900.0, 180.0),    # anywhere its posts stay on the field, any heading
}
DEFAULT_LEVEL = "easy"
# level -> the control steps after which the episode is truncated, or None: the
# environment's `max_steps` alone (`episode_steps`).
TIME_LIMITS = {"easy": None, "medium": None, "hard": None}
# level -> the harbour level whose obstacles stand in the water (`ship_harbour_core.LEVELS`),
# or None: open water.
OBSTACLES = {"easy": None, "medium": None, "hard": "medium"}
# A gate stands clear of the obstacles when its posts' line (HALF_WIDTH either side of
# the centre, at every level) and the APPROACH_M before its centre keep CLEARANCE_M from
# every one: a ship lined up with it has room to pass.
CLEARANCE_M = 10.0
APPROACH_M = 150.0
GATE_TRIES = harbour_core.START_TRIES
# Event codes: `ship_core`'s, and an obstacle touched (the harbour's).
AGROUND = harbour_core.AGROUND
EVENT_NAMES = harbour_core.EVENT_NAMES
RAYS = harbour_core.RAYS


def level_range(level, who="ship goal"):
  """(low, high, largest heading) of `level`, or a one-line error."""
  if not isinstance(level, str) or level not in LEVELS:
    raise ValueError(f"{who}: unknown level {level!r}; allowed levels: {list(LEVELS)}")
  return LEVELS[level]


def level_tolerance(level, who="ship goal"):
  """`reached`'s tolerance at `level` as float64 [half the gate's width in m, the cosine of
  the heading's tolerance], or a one-line error."""
  level_range(level, who)
  half_width, degrees = TOLERANCES[level]
  return np.array([half_width, math.cos(math.radians(degrees))])


def episode_steps(level, max_steps=None):
  """The control steps a goal episode at `level` runs at most: `max_steps` (None:
  `ship_core.STEER_MAX_STEPS`), or the level's time limit (`TIME_LIMITS`) where that is
  shorter (`ship_core.limited_steps`)."""
  level_range(level)                  # a one-line error for an unknown level
  return core.limited_steps(TIME_LIMITS[level], max_steps)


STEER_TOLERANCE = level_tolerance(DEFAULT_LEVEL)  # ship/steer's gate: 50 m, 45 degrees


@functools.cache
def level_shapes(level):
  """(islands, pier frames, cells) of the obstacles in the water at `level` (`OBSTACLES`:
  `ship_harbour_core.level_shapes` and `level_cells` of a harbour level; none, and cells
  that mask nothing, in open water), read-only, made once a process."""
  level_range(level)                  # a one-line error for an unknown level
  if OBSTACLES[level] is not None:
    return (*harbour_core.level_shapes(OBSTACLES[level]),
            harbour_core.level_cells(OBSTACLES[level]))
  shapes = (np.zeros((0, 3)), np.zeros((0, 6)),
            np.zeros((2, harbour_core.CELLS, harbour_core.CELLS), dtype=np.int64))
  for array in shapes:
    array.setflags(write=False)
  return shapes


@numba.njit(cache=True, error_model="numpy")
def gate_clear(x, y, s, c, islands, piers):
  """Whether the gate at (x, y) with heading sine and cosine (s, c) stands clear of the
  obstacles: its posts' line and the APPROACH_M before its centre at least CLEARANCE_M
  from each (always, in open water)."""
  if islands.shape[0] + piers.shape[0] == 0:
    return True
  if harbour_core.segment_touches(x - HALF_WIDTH * c, y + HALF_WIDTH * s, x + HALF_WIDTH * c,
                                  y - HALF_WIDTH * s, islands, piers, CLEARANCE_M):
    return False
  return not harbour_core.segment_touches(x, y, x - APPROACH_M * s, y - APPROACH_M * c,
                                          islands, piers, CLEARANCE_M)


@numba.njit(cache=True, error_model="numpy")
def gate_of(draws, low, high, largest, islands, piers, gate):
  """The gate [x, y, heading_deg] of `draws`, three uniforms on [0, 1), scaled as numpy's
  `uniform` scales them (`low + (high - low) * u`, to the bit) onto the centre's square
  and the heading's range, into `gate`; False where it does not stand clear of the
  obstacles (`gate_clear`)."""
  gate[0] = low + (high - low) * draws[0]
  gate[1] = low + (high - low) * draws[1]
  gate[2] = -largest + (2.0 * largest) * draws[2]
  heading = math.radians(gate[2])
  return gate_clear(gate[0], gate[1], math.sin(heading), math.cos(heading), islands, piers)


@functools.cache
def _gate_entry():
  """`gate_of`'s entry point for one gate's arrays (a batch resets a few copies every
  step; numba's dispatcher would type the arguments again at each)."""
  f64 = numba.float64
  return gate_of.compile((f64[::1], f64, f64, f64, f64[:, ::1], f64[:, ::1], f64[::1]))


def draw_gate(random, level):
  """A gate [x, y, heading_deg] of `level` from `random` (a Generator or RandomState):
  the centre uniform on the level's square, the heading on its range (the draws of three
  `uniform`s, to the bit, from one call of the generator), drawn again until it stands
  clear of the level's obstacles (`gate_of`; the first try, in open water)."""
  low, high, largest = level_range(level)
  islands, piers, _ = level_shapes(level)
  entry, gate = _gate_entry(), np.empty(3)
  for _ in range(GATE_TRIES):
    if entry(random.random(3), low, high, largest, islands, piers, gate):
      return gate
  raise RuntimeError(f"ship goal: no gate clear of the obstacles of {level!r} in "
                     f"{GATE_TRIES:,} draws")


def sample_gate(random, level):
  """A desired goal [x, y, sin, cos] of `level` drawn from `random` (`draw_gate`)."""
  x, y, heading_deg = draw_gate(random, level)
  heading = math.radians(heading_deg)
  return np.array([x, y, math.sin(heading), math.cos(heading)])


def sample_start(rules, random, level):
  """The ship's start at `level`: the steering task's uniform start, drawn again while it
  lies on an obstacle (`ship_harbour_core.sample_start`: the same draws, to the bit, in
  open water)."""
  islands, piers, _ = level_shapes(level)
  return harbour_core.sample_start(rules, random, islands, piers)


def check_start(rules, state, level, who):
  """A start given by a user (`rules.check_state`), refused in one line on an obstacle."""
  islands, piers, _ = level_shapes(level)
  return harbour_core.check_start(rules, state, islands, piers, who)


def goal_of(state):
  """The achieved goal of a ship state [x, y, theta_deg, theta_dot_deg]."""
  theta = math.radians(state[2])
  return np.array([state[0], state[1], math.sin(theta), math.cos(theta)])


def gate_heading_deg(desired):
  """The heading (deg, clockwise from north) of a desired goal."""
  return math.degrees(math.atan2(desired[2], desired[3]))


@numba.njit(cache=True, error_model="numpy", inline="always")
def posts_into(x, y, s, c, out):
  """The posts of the gate at (x, y) with heading sine and cosine (s, c) into `out`, rows
  (x, y): left, then right of a ship passing it (compiled, for the regatta's courses)."""
  out[0, 0] = x - HALF_WIDTH * c
  out[0, 1] = y + HALF_WIDTH * s
  out[1, 0] = x + HALF_WIDTH * c
  out[1, 1] = y - HALF_WIDTH * s


def gate_posts(desired, half_width=HALF_WIDTH):
  """The gate's two posts, rows (x, y): left, then right of a ship passing it,
  `half_width` m either side of its centre."""
  x, y, s, c = (float(v) for v in desired)
  return np.array([[x - half_width * c, y + half_width * s],
                   [x + half_width * c, y - half_width * s]])


@numba.njit(cache=True, error_model="numpy", inline="always")
def reached(ax, ay, asin, acos, dx, dy, dsin, dcos, tolerance):
  """Whether the achieved goal (ax, ay, asin, acos) reaches the desired (module's rule;
  `tolerance` a level's, `level_tolerance`)."""
  rx = ax - dx
  ry = ay - dy
  forward = rx * dsin + ry * dcos
  lateral = rx * dcos - ry * dsin
  return (0.0 <= forward < WINDOW and abs(lateral) <= tolerance[0]
          and asin * dsin + acos * dcos >= tolerance[1])


@numba.njit(cache=True, error_model="numpy", inline="always")
def outcome_of(a, d, gate_reward, out_of_bounds_reward, tolerance):
  """(event, reward) of an achieved goal `a` for the desired `d` (`tolerance` the level's):
  SUCCESS and -1 + `gate_reward` at the gate; FAILURE and -1 + `out_of_bounds_reward`
  off the field (its position at the end of the control step); else NO_EVENT and -1."""
  if reached(a[0], a[1], a[2], a[3], d[0], d[1], d[2], d[3], tolerance):
    return core.SUCCESS, core.STEP_REWARD + gate_reward
  if a[0] < 0.0 or a[0] > core.FIELD_SIZE or a[1] < 0.0 or a[1] > core.FIELD_SIZE:
    return core.FAILURE, core.STEP_REWARD + out_of_bounds_reward
  return core.NO_EVENT, core.STEP_REWARD


@numba.njit(cache=True, error_model="numpy", inline="always")
def step_outcome(samples, a, d, gate_reward, out_of_bounds_reward, tolerance, islands, piers,
                 cells):
  """(event, reward) of a control step that sampled the positions `samples` and ended at
  the achieved goal `a`: AGROUND and -1 + `out_of_bounds_reward` where its track touched
  an obstacle (`ship_harbour_core.track_aground`), else `outcome_of`'s."""
  if harbour_core.track_aground(samples, islands, piers, cells):
    return AGROUND, core.STEP_REWARD + out_of_bounds_reward
  return outcome_of(a, d, gate_reward, out_of_bounds_reward, tolerance)


@numba.njit(cache=True, error_model="numpy")
def goal_rewards(achieved, desired, aground, gate_reward, out_of_bounds_reward, tolerance,
                 reward, event):
  """`outcome_of` for rows of achieved and desired goals (n, 4), into `reward`, `event`;
  AGROUND where `aground`."""
  for i in range(achieved.shape[0]):
    if aground[i]:
      event[i], reward[i] = AGROUND, core.STEP_REWARD + out_of_bounds_reward
    else:
      event[i], reward[i] = outcome_of(achieved[i], desired[i], gate_reward,
                                       out_of_bounds_reward, tolerance)


def compute_reward(achieved_goal, desired_goal, gate_reward, out_of_bounds_reward,
                   tolerance=STEER_TOLERANCE, aground=False):
  """Rewards of any shape of goals (..., 4): a float for one pair, else an array
  (`tolerance`: a level's, `level_tolerance`; default easy's and medium's). `aground`
  (broadcast to the goals' batch shape): the steps whose track touched an obstacle, -1
  and the out-of-bounds penalty whatever the goals."""
  achieved = np.asarray(achieved_goal, dtype=np.float64)
  desired = np.asarray(desired_goal, dtype=np.float64)
  if achieved.shape[-1:] != (4,) or desired.shape[-1:] != (4,):
    raise ValueError("compute_reward: goals are [x, y, sin(heading), cos(heading)] "
                     f"(last axis 4), got shapes {achieved.shape} and {desired.shape}")
  achieved, desired = np.broadcast_arrays(achieved, desired)
  shape = achieved.shape[:-1]
  a = np.ascontiguousarray(achieved.reshape(-1, 4))
  d = np.ascontiguousarray(desired.reshape(-1, 4))
  on = np.ascontiguousarray(np.broadcast_to(np.asarray(aground, dtype=np.bool_), shape).reshape(-1))
  reward = np.empty(len(a))
  goal_rewards(a, d, on, float(gate_reward), float(out_of_bounds_reward),
               np.asarray(tolerance, dtype=np.float64), reward, np.empty(len(a), dtype=np.int64))
  return float(reward[0]) if shape == () else reward.reshape(shape)


@numba.njit(cache=True)
def pilot_target(state, phase, desired, reach=150.0):
  """Waypoints of a scripted helmsman for a gate anywhere: first the point `reach` m
  before the gate on its line of approach (phase 0, until within 40 m), then 60 m
  past its centre (phase 1). Returns (x, y, phase). Used for pictures and checks,
  not learned."""
  if phase == 0:
    ax = desired[0] - reach * desired[2]
    ay = desired[1] - reach * desired[3]
    if math.hypot(state[0] - ax, state[1] - ay) >= 40.0:
      return ax, ay, 0
  return desired[0] + 60.0 * desired[2], desired[1] + 60.0 * desired[3], 1


@numba.njit(cache=True, error_model="numpy")
def judge_batch(states, samples, active, steps, desired, max_steps, gate_reward,
                out_of_bounds_reward, tolerance, islands, piers, cells, achieved, outcome):
  """After a control step of every `active` ship (its `steps` already counted; its
  sampled positions in `samples`): the achieved goals into `achieved`, and `outcome` =
  (event, reward, terminated, truncated) by the module's rule (`tolerance` the level's,
  the obstacles its `level_shapes`): AGROUND where the track touched an obstacle,
  SUCCESS at the gate, FAILURE off the field (the position at the end of the step),
  truncated after `max_steps`."""
  event, reward, terminated, truncated = outcome
  for i in range(states.shape[0]):
    if not active[i]:
      continue
    theta = math.radians(states[i, 2])
    a = achieved[i]
    a[0] = states[i, 0]
    a[1] = states[i, 1]
    a[2] = math.sin(theta)
    a[3] = math.cos(theta)
    # `step_outcome`, its branch written out: as one inlined call the batch ran 1.3-1.9x
    # slower (interleaved, 1,024 ships). The track is looked at only in a cell near an
    # obstacle: taking every ship's row of `samples` (a view) cost 28 ns a ship, more than
    # the rest of the judgement (23 ns).
    if harbour_core.may_touch(cells, samples[i, 0, 0], samples[i, 0, 1]) and \
        harbour_core.track_aground(samples[i], islands, piers, cells):
      event[i], reward[i] = AGROUND, core.STEP_REWARD + out_of_bounds_reward
    else:
      event[i], reward[i] = outcome_of(a, desired[i], gate_reward, out_of_bounds_reward,
                                       tolerance)
    terminated[i] = event[i] != core.NO_EVENT
    truncated[i] = not terminated[i] and steps[i] >= max_steps


@numba.njit(cache=True, error_model="numpy")
def step_batch(states, r_deg, active, samples, steps, integrate, desired, params, achieved,
               outcome):
  """One control step of every `active` ship of a batch (`params` the level's `EnvParams`):
  with `integrate` the ships sail Equation 1 here (`ship_core.sail_batch`; without it
  `samples` and `states` already hold the step: the MuJoCo ships); each active ship's
  `steps` grows by one and `judge_batch` fills `achieved` and `outcome`."""
  if integrate:
    core.sail_batch(states, r_deg, active, samples)
  for i in range(states.shape[0]):
    if active[i]:
      steps[i] += 1
  judge_batch(states, samples, active, steps, desired, params.max_steps, params.rewards[0],
              params.rewards[1], params.tolerance, params.islands, params.piers, params.cells,
              achieved, outcome)


@numba.njit(cache=True, error_model="numpy")
def place_batch(states, gates, indices, desired, achieved):
  """For the copies `indices` of a batch (its resets), the desired goals of `gates` (a row
  [x, y, heading_deg] each, in `indices`' order: `check_gate`'s arithmetic) and the
  achieved goals of `states` (`goal_of`'s)."""
  for k in range(indices.shape[0]):
    i = indices[k]
    heading = math.radians(gates[k, 2])
    desired[i, 0] = gates[k, 0]
    desired[i, 1] = gates[k, 1]
    desired[i, 2] = math.sin(heading)
    desired[i, 3] = math.cos(heading)
    theta = math.radians(states[i, 2])
    achieved[i, 0] = states[i, 0]
    achieved[i, 1] = states[i, 1]
    achieved[i, 2] = math.sin(theta)
    achieved[i, 3] = math.cos(theta)


@functools.cache
def entries():
  """Entry points of `judge_batch` (for a batch of ships, or one ship's arrays as a row
  each), `ranges_into` (one ship) and `harbour_core.ranges_batch` (a batch): numba's
  dispatcher would type their arguments again at each step, much of the call."""
  f64, i64, b1 = numba.float64, numba.int64, numba.boolean
  judge = judge_batch.compile((f64[:, ::1], f64[:, :, ::1], b1[::1], i64[::1], f64[:, ::1], i64,
                               f64, f64, f64[::1], f64[:, ::1], f64[:, ::1], i64[:, :, ::1],
                               f64[:, ::1], numba.types.Tuple((i64[::1], f64[::1], b1[::1],
                                                               b1[::1]))))
  seen = harbour_core.ranges_into.compile((f64[::1], f64[:, ::1], f64[:, ::1], i64[:, :, ::1],
                                           f64[::1], i64))
  seen_batch = harbour_core.ranges_batch.compile((f64[:, ::1], f64[:, ::1], f64[:, ::1],
                                                  i64[:, :, ::1], f64[:, ::1]))
  return judge, seen, seen_batch


class OneShip:
  """`judge_batch` and the ranges for the single environments (Gymnasium's and
  dm_control's): one ship on `rules` (a `ShipRules` of "steer": the step limit and the
  two rewards) at `level` (its tolerance and its obstacles), its arrays made once."""

  def __init__(self, rules, level):
    self.rules = rules
    self.tolerance = level_tolerance(level)
    self.islands, self.piers, self.cells = level_shapes(level)
    self._active, self._steps = np.ones(1, np.bool_), np.zeros(1, np.int64)
    self._achieved = np.zeros((1, 4))
    self._outcome = (np.zeros(1, np.int64), np.zeros(1), np.zeros(1, np.bool_),
                     np.zeros(1, np.bool_))
    self._judge, self._ranges, _ = entries()

  def __call__(self, samples, state, steps, desired):
    """(event, reward, terminated, truncated, event name) after a control step that
    sampled `samples` (float64, C order) and ended at `state`, `steps` control steps in."""
    self._steps[0] = steps
    rules = self.rules
    self._judge(state[None, :], samples[None], self._active, self._steps, desired[None, :],
                rules.max_steps, rules.success_reward, rules.failure_reward, self.tolerance,
                self.islands, self.piers, self.cells, self._achieved, self._outcome)
    events, rewards, terminated, truncated = self._outcome
    event = int(events[0])
    return event, float(rewards[0]), bool(terminated[0]), bool(truncated[0]), EVENT_NAMES[event]

  def ranges(self, state, readings=None):
    """The ranges (a new array of RAYS) of the ship at `state` (float64, C order): the
    analytic rays or, given, MuJoCo's rangefinder `readings` (`seen_ranges`)."""
    out = np.empty(RAYS)
    if readings is None:
      self._ranges(state, self.islands, self.piers, self.cells, out, 0)
    else:
      harbour_core.seen_ranges(readings, out, 0)
    return out


def check_gate(gate, who, level=DEFAULT_LEVEL, obstacles=None):
  """A gate given by a user, [x, y, heading_deg], as a desired goal, or a one-line error:
  finite, its posts on the field, clear of `level`'s obstacles (`gate_clear`; or of
  `obstacles`, (islands, pier frames), where given)."""
  arr = np.asarray(gate, dtype=np.float64)
  if arr.shape != (3,) or not np.isfinite(arr).all():
    raise ValueError(f"{who}: a gate is [x, y, heading_deg] (3 finite numbers), got {gate!r}")
  heading = math.radians(arr[2])
  desired = np.array([arr[0], arr[1], math.sin(heading), math.cos(heading)])
  posts = gate_posts(desired)
  if not ((posts >= 0.0) & (posts <= core.FIELD_SIZE)).all():
    raise ValueError(f"{who}: gate {arr.tolist()} puts its posts at {posts.round(2).tolist()}; "
                     f"allowed: both posts on the field [0, {core.FIELD_SIZE}] m")
  islands, piers = level_shapes(level)[:2] if obstacles is None else obstacles
  if not gate_clear(*desired, islands, piers):
    raise ValueError(f"{who}: gate {arr.tolist()} comes within {CLEARANCE_M:g} m of an obstacle "
                     f"of level {level!r} (its posts' line or the {APPROACH_M:g} m before it); "
                     "allowed: a gate clear of them")
  return desired


# ---- the world as pure functions over a state and its parameters -------------------
# (gymnax's shape; the open machine's fused loop, `hierarchy.algorithm.run_world`,
# calls them, and they step as the Gymnasium environment's analytic backend does.)

EnvParams = collections.namedtuple("EnvParams", ("level", "rewards", "max_steps", "tolerance",
                                                 "islands", "piers", "cells"))
EnvParams.__doc__ = """The goal's task: the level's (lowest centre coordinate, highest,
largest heading in deg), [gate reward, out-of-bounds reward], the control steps before
truncation, the level's tolerance (`level_tolerance`), and its obstacles: islands, pier
frames and cells (`level_shapes`)."""
EnvState = collections.namedtuple("EnvState", ("ship", "desired", "draws"))
EnvState.__doc__ = """The world's state: the ship's [x, y, theta_deg, theta_dot_deg] and
the desired goal [x, y, sin, cos] of the episode's gate; `draws`, scratch for one try at
a start (`ship_harbour_core.start_of`)."""
START_SIZE = 7                # the ship's state, then the gate [x, y, heading_deg]
OBSERVATION_SIZE = 12 + RAYS
# The Gymnasium dictionary flattened in this order (its own order, and the manual's):
# the state first, where a view of the steering ship's pose reads it.
OBSERVATION_KEYS = ("observation", "achieved_goal", "desired_goal", "ranges")


def env_params(level, gate_reward=core.GATE_REWARD, out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD,
               max_steps=core.STEER_MAX_STEPS):
  """The `EnvParams` of `level` with the environment's rewards and step limit (the level's
  time limit where shorter: `episode_steps`)."""
  return EnvParams(np.array(level_range(level), dtype=np.float64),
                   np.array([gate_reward, out_of_bounds_reward], dtype=np.float64),
                   np.int64(episode_steps(level, max_steps)), level_tolerance(level),
                   *level_shapes(level))


def env_state(params):
  """A fresh `EnvState` (the fused loop's scratch)."""
  return EnvState(np.zeros(4), np.zeros(4), np.zeros(4))


def flatten(observation):
  """The Gymnasium dictionary as one float64 vector (OBSERVATION_SIZE), keys in
  `OBSERVATION_KEYS`' order: what `env_reset` and `env_step` write."""
  return np.concatenate([observation[key] for key in OBSERVATION_KEYS]).astype(np.float64)


@numba.njit(cache=True, error_model="numpy")
def observe_into(params, state, obs):
  """The flattened observation (`flatten`) of `state` into `obs`: the ship's state, its
  achieved goal (`goal_of`), the desired goal, the ranges."""
  ship = state.ship
  theta = math.radians(ship[2])
  for j in range(4):
    obs[j] = ship[j]
    obs[8 + j] = state.desired[j]
  obs[4] = ship[0]
  obs[5] = ship[1]
  obs[6] = math.sin(theta)
  obs[7] = math.cos(theta)
  harbour_core.ranges_into(ship, params.islands, params.piers, params.cells, obs, 12)


@numba.njit(cache=True, error_model="numpy")
def env_reset(params, state, start, obs):
  """An episode from `start` (the ship's state, then the gate [x, y, heading_deg], each
  made as the environment's `reset(options={"state": ..., "gate": ...})` makes it); its
  observation into `obs`."""
  ship = state.ship
  core.place(ship, start)
  heading = math.radians(start[6])
  state.desired[0] = start[4]
  state.desired[1] = start[5]
  state.desired[2] = math.sin(heading)
  state.desired[3] = math.cos(heading)
  observe_into(params, state, obs)


@numba.njit(cache=True, error_model="numpy")
def env_step(params, state, r_deg, samples, obs, steps):
  """One control step at turning rate `r_deg` (clipped to [-15, 15] deg/s), `steps`
  control steps in (this one counted): the positions sampled into `samples`, the
  flattened observation into `obs`; returns (event, reward, terminated, truncated) as
  `ShipGoalEnv.step` (`step_outcome`: the obstacles on the track, then the module's rule
  on the achieved goal)."""
  r = core.clipped(r_deg)
  core.euler_control(state.ship, r, samples, core.SPEED, core.TIME_CONSTANT,
                     core.SAMPLING_INTERVAL)
  observe_into(params, state, obs)
  event, reward = step_outcome(samples, obs[4:8], state.desired, params.rewards[0],
                               params.rewards[1], params.tolerance, params.islands,
                               params.piers, params.cells)
  terminated = event != core.NO_EVENT
  return event, reward, terminated, (not terminated) and steps >= params.max_steps


@numba.njit(cache=True, error_model="numpy")
def env_end(params, state, event):
  """An ended episode's (reached the gate: 1 or 0, 0)."""
  return (1.0 if event == core.SUCCESS else 0.0), 0.0
