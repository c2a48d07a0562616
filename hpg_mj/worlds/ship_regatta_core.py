"""The regatta (SPEC section 11): a course of gates to pass in order, laid out from the
episode's seed, the rule that counts them and what the ship sees of them, compiled
(numba) and shared by every backend and path. Free of MuJoCo, as `ship_core` is (SPEC
section 9); the ship is the steering ship.

A course is rows `[x, y, heading_deg]`, one per gate: its centre and the heading to pass
it with (clockwise from north, as every heading here). Each gate is `ship/steer`'s gate
moved and turned: 100 m wide across its heading, its posts 50 m either side of the
centre (`ship_goal_core.gate_posts`). A gate is passed as `ship/steer`'s is, by
`ship_core.steer_event` itself: a segment between two consecutive sampled positions
crosses the segment between its posts, in either direction. Only the next gate counts;
a pass pays `gate_reward` and the gate after it becomes the next, and the last one
(`finish_reward`) ends the episode. Off the field ends it as on `ship/steer`.

The layout (`sample_course`): the first gate's centre uniform on [100, 900] m each way,
its heading uniform; each next gate `spacing` m on from the one before, along that
gate's heading turned by an angle uniform on [smallest, largest] degrees to a side
drawn at random, and facing along that leg. A gate that would leave [100, 900] m (its
posts then stay 50 m inside the field) or come within 110 m of another (two 100 m gates
can then never touch) is turned to the other side, else its turn drawn again; a course
that cannot go on is laid again from its first gate. Sharper turns between closer gates
make the harder levels: a leg is sailed in a few hundred metres, a turn of up to 135
degrees with the ship's 5 s lag takes a good part of it, and where the ship ends one leg
is where the next one starts. At `hard` the course also closes (`TIME_LIMITS`, `episode_steps`):
an episode is truncated after 1,000 control steps (10 minutes) whatever a larger `max_steps`
asks. The best known sails 95.7% of the level's benchmark starts within it; turns and gates
alone did not make the level hard (a designed hierarchy finished 95% of its courses, in
1,090 control steps at the median, where the best known takes 734), nor did 1,100 steps
(the same hierarchy, tuned and trained at hard, finished 72%; at 1,000, 53%).

The observation (`observe`): the ship's `[x, y, theta_deg, theta_dot_deg]`, then the next
gate and the one after it as the ship sees them, `[ahead_m, right_m, heading_deg]` each
(the centre's distance along the ship's heading and to its starboard, and the gate's
heading less the ship's, wrapped to [-180, 180)), and the gates left to pass. At the last
gate (and after the finish) the second is the last again.
"""
import collections
import functools
import math

import numba
import numpy as np

from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_goal_core as goal_core

# level -> (gates, spacing in m, smallest and largest turn between legs in deg).
LEVELS = {
    "easy": (3, 250.0, 0.0, 30.0),      # three gates, gentle bends
    "medium": (5, 200.0, 30.0, 75.0),   # five, every turn at least 30 degrees
    "hard": (8, 150.0, 60.0, 135.0),    # eight, close and sharp: hairpins of up to 135
}
DEFAULT_LEVEL = "easy"
# level -> the control steps after which the course closes (the episode is truncated), or
# None: the environment's `max_steps` alone.
TIME_LIMITS = {"easy": None, "medium": None, "hard": 1000}
MAX_GATES = max(gates for gates, _, _, _ in LEVELS.values())   # the MJCF's course geoms

LOW, HIGH = 100.0, 900.0           # m, where gate centres lie: posts 50 m inside the field
MIN_SEPARATION = 110.0             # m between any two gates' centres (> their 100 m width)
TRIES = 50                        # draws of a gate's turn before the course is laid again

# SPEC section 11's rewards: every gate but the last, the last, and off the field.
GATE_REWARD = 100.0
FINISH_REWARD = 500.0
OUT_OF_BOUNDS_REWARD = core.OUT_OF_BOUNDS_REWARD

# Event codes: `ship_core`'s, and a gate passed that is not the last.
GATE = 2
EVENT_NAMES = {core.NO_EVENT: None, core.SUCCESS: "finish", core.FAILURE: "out_of_bounds",
               GATE: "gate"}
OBSERVATION_SIZE = 11              # the ship's 4, two gates' 3 each, the gates left


def level_layout(level, who="ship regatta"):
  """(gates, spacing, smallest turn, largest turn) of `level`, or a one-line error."""
  if not isinstance(level, str) or level not in LEVELS:
    raise ValueError(f"{who}: unknown level {level!r}; allowed levels: {list(LEVELS)}")
  return LEVELS[level]


def episode_steps(level, max_steps=None):
  """The control steps a regatta episode at `level` runs at most: `max_steps` (None:
  `ship_core.STEER_MAX_STEPS`), or the level's time limit (`TIME_LIMITS`) where that is
  shorter (`ship_core.limited_steps`)."""
  level_layout(level)                 # a one-line error for an unknown level
  return core.limited_steps(TIME_LIMITS[level], max_steps)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _fits(x, y, course, k):
  """Whether a gate centred at (x, y) stands where the layout allows, beside gates 0..k-1."""
  if not (LOW <= x <= HIGH and LOW <= y <= HIGH):
    return False
  for j in range(k):
    if math.hypot(x - course[j, 0], y - course[j, 1]) < MIN_SEPARATION:
      return False
  return True


@numba.njit(cache=True, error_model="numpy")
def lay_course(draws, spacing, smallest, largest, course):
  """Lays `course` (rows [x, y, heading_deg], filled in place) by the module's rule from
  `draws`, uniforms on [0, 1) (`draws_per_course` of them): the first gate's x, y and
  heading, then a turn and a side for each try of each gate. False where a gate finds
  no room in `TRIES` turns (the caller lays the course again with new draws)."""
  course[0, 0] = LOW + (HIGH - LOW) * draws[0]
  course[0, 1] = LOW + (HIGH - LOW) * draws[1]
  course[0, 2] = -180.0 + 360.0 * draws[2]
  at = 3
  for k in range(1, course.shape[0]):
    placed = False
    for _ in range(TRIES):
      turn = smallest + (largest - smallest) * draws[at]
      side = 1.0 if draws[at + 1] < 0.5 else -1.0
      at += 2
      for sign in (side, -side):
        heading = core.wrap_deg(course[k - 1, 2] + sign * turn)
        rad = math.radians(heading)
        x = course[k - 1, 0] + spacing * math.sin(rad)
        y = course[k - 1, 1] + spacing * math.cos(rad)
        if _fits(x, y, course, k):
          course[k, 0] = x
          course[k, 1] = y
          course[k, 2] = heading
          placed = True
          break
      if placed:
        break
    if not placed:
      return False
  return True


def draws_per_course(gates):
  """The uniforms one try at laying a course of `gates` takes (`lay_course`)."""
  return 3 + 2 * TRIES * (int(gates) - 1)


def sample_course(random, layout):
  """A course of `layout` (`LEVELS`' four numbers), rows [x, y, heading_deg], laid out by
  the module's rule from uniforms drawn from `random` (a Generator or a RandomState), a
  block at each try: a reset costs microseconds, and a batch resets its copies often."""
  gates, spacing, smallest, largest = layout
  course = np.empty((int(gates), 3))
  while not lay_course(random.uniform(0.0, 1.0, draws_per_course(gates)), float(spacing),
                       float(smallest), float(largest), course):
    pass
  return course


@numba.njit(cache=True, error_model="numpy")
def posts_into(course, out):
  """The posts of every gate of a course into `out`, (gates, 2, 2): rows (x, y), left then
  right of a ship passing it (`ship_goal_core.posts_into`)."""
  for k in range(course.shape[0]):
    rad = math.radians(course[k, 2])
    goal_core.posts_into(course[k, 0], course[k, 1], math.sin(rad), math.cos(rad), out[k])


def posts_of(course):
  """The posts of every gate of a course, a new (gates, 2, 2) array (`posts_into`)."""
  out = np.empty((len(course), 2, 2))
  posts_into(np.ascontiguousarray(course, dtype=np.float64), out)
  return out


def check_course(course, gates, who):
  """A course given by a user as float64 rows [x, y, heading_deg] (headings wrapped), or a
  one-line error: `gates` rows of finite numbers, every gate's posts on the field."""
  arr = np.asarray(course, dtype=np.float64)
  if arr.shape != (gates, 3):
    raise ValueError(f"{who}: a course is {gates} gates [x, y, heading_deg] (shape "
                     f"({gates}, 3)), got shape {arr.shape}")
  for k, row in enumerate(arr):
    goal_core.check_gate(row, f"{who} gate {k}")
  out = arr.copy()
  out[:, 2] = core.wrap_deg_array(out[:, 2])
  return out


# ---- one control step: the rule, and what the ship sees ------------------------------

@numba.njit(cache=True, error_model="numpy", inline="always")
def course_outcome(samples, posts, next_gate, gate_reward, finish_reward, out_of_bounds_reward):
  """(event, reward, next gate) after a control step that sampled `samples` with gate
  `next_gate` of `posts` to pass: `ship_core.steer_event` on the next gate, from each
  pass on to the gate after it. -1 a step, `gate_reward` more for each gate passed
  (GATE), `finish_reward` for the last (SUCCESS), `out_of_bounds_reward` off the field
  (FAILURE, which ends the step's reckoning: the first event in time wins)."""
  n = posts.shape[0]
  reward = core.STEP_REWARD
  event = core.NO_EVENT
  start = 0
  while next_gate < n:
    e, k = core.steer_event(samples[start:], posts[next_gate], core.FIELD_SIZE)
    if e == core.NO_EVENT:
      break
    if e == core.FAILURE:
      return core.FAILURE, reward + out_of_bounds_reward, next_gate
    next_gate += 1
    if next_gate == n:
      return core.SUCCESS, reward + finish_reward, next_gate
    reward += gate_reward
    event = GATE
    start += k                     # on from the sample after the crossing (its own
    x = samples[start, 0]          # bounds, which `steer_event` leaves at a pass, first)
    y = samples[start, 1]
    if x < 0.0 or x > core.FIELD_SIZE or y < 0.0 or y > core.FIELD_SIZE:
      return core.FAILURE, reward + out_of_bounds_reward, next_gate
  return event, reward, next_gate


@numba.njit(cache=True, error_model="numpy", inline="always")
def ship_outcome(samples, posts, next_gate, steps, max_steps, gate_reward, finish_reward,
                 out_of_bounds_reward):
  """(event, reward, next gate, terminated, truncated) of one ship's control step, `steps`
  control steps in (this one counted): `course_outcome`'s, terminated at the finish or
  off the field, truncated after `max_steps`."""
  event, reward, next_gate = course_outcome(samples, posts, next_gate, gate_reward,
                                            finish_reward, out_of_bounds_reward)
  terminated = event == core.SUCCESS or event == core.FAILURE
  return event, reward, next_gate, terminated, not terminated and steps >= max_steps


@numba.njit(cache=True, error_model="numpy")
def step_batch(states, r_deg, active, samples, steps, integrate, posts, next_gate, max_steps,
               gate_reward, finish_reward, out_of_bounds_reward, outcome):
  """One control step of every `active` ship of a batch, each on its own course (`posts`,
  (n, gates, 2, 2), the next gate of each in `next_gate`). With `integrate` the ships
  sail Equation 1 here (`ship_core.sail_batch`); without it `samples` and `states`
  already hold the step (the MuJoCo ships). Each active ship's `steps` grows by one and
  `outcome` = (event, reward, terminated, truncated) is filled by `ship_outcome`."""
  event, reward, terminated, truncated = outcome
  if integrate:
    core.sail_batch(states, r_deg, active, samples)
  for i in range(states.shape[0]):
    if not active[i]:
      continue
    steps[i] += 1
    event[i], reward[i], next_gate[i], terminated[i], truncated[i] = ship_outcome(
        samples[i], posts[i], next_gate[i], steps[i], max_steps, gate_reward, finish_reward,
        out_of_bounds_reward)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _seen(state, sin, cos, gate, out, at):
  """Gate `gate` ([x, y, heading_deg]) as the ship at `state` (its heading's sine and
  cosine `sin`, `cos`) sees it, into out[at:at + 3]."""
  dx = gate[0] - state[0]
  dy = gate[1] - state[1]
  out[at] = dx * sin + dy * cos                   # ahead
  out[at + 1] = dx * cos - dy * sin               # to starboard
  out[at + 2] = core.wrap_deg(gate[2] - state[2])


@numba.njit(cache=True, error_model="numpy", inline="always")
def observe(state, course, next_gate, out):
  """The observation (the module's) of the ship at `state` with gate `next_gate` of
  `course` to pass next, into `out` (11): its state, its next two gates as it sees them,
  the gates it has left to pass."""
  for j in range(4):
    out[j] = state[j]
  last = course.shape[0] - 1
  rad = math.radians(state[2])
  sin, cos = math.sin(rad), math.cos(rad)
  _seen(state, sin, cos, course[min(next_gate, last)], out, 4)
  _seen(state, sin, cos, course[min(next_gate + 1, last)], out, 7)
  out[10] = course.shape[0] - next_gate


@numba.njit(cache=True, error_model="numpy")
def observe_batch(states, courses, next_gate, out):
  """Each ship's observation (`observe`) into the rows of `out`, (n, 11)."""
  for i in range(states.shape[0]):
    observe(states[i], courses[i], next_gate[i], out[i])


@functools.cache
def _one_ship():
  """`ship_outcome`'s and `observe`'s entry points for one ship's arrays: numba's
  dispatcher would type their arguments again at each step (most of the call)."""
  f64, i64 = numba.float64, numba.int64
  step = ship_outcome.compile((f64[:, ::1], f64[:, :, ::1], i64, i64, i64, f64, f64, f64))
  seen = observe.compile((f64[::1], f64[:, ::1], i64, f64[::1]))
  return step, seen


class OneShip:
  """The regatta's rule and observation for the single environments (Gymnasium's and
  dm_control's): one ship on one course, its arrays made once."""

  def __init__(self, max_steps, gate_reward=GATE_REWARD, finish_reward=FINISH_REWARD,
               out_of_bounds_reward=OUT_OF_BOUNDS_REWARD):
    self.max_steps = int(max_steps)
    self.rewards = (float(gate_reward), float(finish_reward), float(out_of_bounds_reward))
    self.next_gate = 0                  # the gate to pass next (the number passed so far)
    self._step, self._observe = _one_ship()
    self.set_course(sample_course(np.random.default_rng(0), LEVELS[DEFAULT_LEVEL]))

  def set_course(self, course):
    """A new course (rows [x, y, heading_deg]), its first gate the next."""
    self.course = np.ascontiguousarray(course, dtype=np.float64)
    self.posts = posts_of(self.course)
    self.next_gate = 0

  def __call__(self, samples, steps):
    """(event, reward, terminated, truncated) after a control step that sampled `samples`
    (float64, C order), `steps` control steps in (this one counted)."""
    event, reward, self.next_gate, terminated, truncated = self._step(
        samples, self.posts, self.next_gate, steps, self.max_steps, *self.rewards)
    return event, reward, terminated, truncated

  def observe(self, state):
    """The observation (a new array of 11) of the ship at `state` (float64, C order) on
    this course."""
    out = np.empty(OBSERVATION_SIZE)
    self._observe(state, self.course, self.next_gate, out)
    return out


def pilot_target(state, phase, course, next_gate, reach):
  """Waypoints of a scripted helmsman round the course: `ship_goal_core.pilot_target` on
  the next gate, its approach point `reach` m before it (`phase` starts at 0 for each
  gate; half a leg suits every level). Returns (x, y, phase). For pictures and checks,
  not learned."""
  x, y, heading = course[min(next_gate, len(course) - 1)]
  rad = math.radians(heading)
  return goal_core.pilot_target(state, phase, np.array([x, y, math.sin(rad), math.cos(rad)]),
                                reach)


# ---- the world as pure functions over a state and its parameters -------------------
# (gymnax's shape; the open machine's fused loop, `hierarchy.algorithm.run_world`,
# calls them, and they step as the Gymnasium environment's analytic backend does.)

EnvParams = collections.namedtuple("EnvParams", ("layout", "rewards", "max_steps"))
EnvParams.__doc__ = """The regatta's task: the level's (gates, spacing, smallest turn,
largest turn), [gate reward, finish reward, out-of-bounds reward], the control steps
before truncation."""
EnvState = collections.namedtuple("EnvState", ("ship", "next_gate", "course", "posts", "draws"))
EnvState.__doc__ = """The world's state: the ship's [x, y, theta_deg, theta_dot_deg], the
gate to pass next (int64[1]), the course (gates, 3) and its posts (gates, 2, 2); `draws`,
scratch for one try at laying a course (`lay_course`)."""


def start_size(level):
  """The length of an episode's start: the ship's state, then the course's rows."""
  return 4 + 3 * level_layout(level)[0]


def env_params(level, gate_reward=GATE_REWARD, finish_reward=FINISH_REWARD,
               out_of_bounds_reward=OUT_OF_BOUNDS_REWARD, max_steps=core.STEER_MAX_STEPS):
  """The `EnvParams` of `level` with the environment's rewards and step limit (the level's
  time limit where shorter: `episode_steps`)."""
  return EnvParams(np.array(level_layout(level), dtype=np.float64),
                   np.array([gate_reward, finish_reward, out_of_bounds_reward], dtype=np.float64),
                   np.int64(episode_steps(level, max_steps)))


def env_state(params):
  """A fresh `EnvState` (the fused loop's scratch)."""
  gates = int(params.layout[0])
  return EnvState(np.zeros(4), np.zeros(1, dtype=np.int64), np.zeros((gates, 3)),
                  np.zeros((gates, 2, 2)), np.zeros(draws_per_course(gates)))


@numba.njit(cache=True, error_model="numpy")
def env_reset(params, state, start, obs):
  """An episode from `start` (the ship's state, then the course's rows [x, y,
  heading_deg], each made as the environment's `reset(options={"state": ...,
  "course": ...})` makes it: headings wrapped); its observation into `obs`."""
  ship = state.ship
  core.place(ship, start)
  course = state.course
  for k in range(course.shape[0]):
    course[k, 0] = start[4 + 3 * k]
    course[k, 1] = start[5 + 3 * k]
    course[k, 2] = core.wrap_deg(start[6 + 3 * k])
  posts_into(course, state.posts)
  state.next_gate[0] = 0
  observe(ship, course, 0, obs)


@numba.njit(cache=True, error_model="numpy")
def env_step(params, state, r_deg, samples, obs, steps):
  """One control step at turning rate `r_deg` (clipped to [-15, 15] deg/s), `steps`
  control steps in (this one counted): the positions sampled into `samples`, the
  observation into `obs`; returns (event, reward, terminated, truncated) as
  `ShipRegattaEnv.step` (`ship_outcome`)."""
  r = core.clipped(r_deg)
  core.euler_control(state.ship, r, samples, core.SPEED, core.TIME_CONSTANT,
                     core.SAMPLING_INTERVAL)
  rewards = params.rewards
  event, reward, next_gate, terminated, truncated = ship_outcome(
      samples, state.posts, state.next_gate[0], steps, params.max_steps, rewards[0], rewards[1],
      rewards[2])
  state.next_gate[0] = next_gate
  observe(state.ship, state.course, next_gate, obs)
  return event, reward, terminated, truncated


@numba.njit(cache=True, error_model="numpy")
def env_end(params, state, event):
  """An ended episode's (finished the course: 1 or 0, the gates passed)."""
  return (1.0 if event == core.SUCCESS else 0.0), float(state.next_gate[0])
