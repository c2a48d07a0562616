"""Ship steering: the analytic dynamics (paper, Equation 1) and the task rules.

Everything here is a numba-compiled function over plain floats and arrays, so
that the Gymnasium environment, the dm_control tasks and the compiled training
loops all use one implementation of each rule (SPEC sections 1-3).

Units are the paper's: metres, degrees, degrees per second. The heading
`theta_deg = 0` points to +y ("north") and positive headings turn clockwise
towards +x: `x += dt * V * sin(theta)`, `y += dt * V * cos(theta)`.

A ship state is a float64 array `[x, y, theta_deg, theta_dot_deg]`.

The per-step rules are compiled with numba's `error_model="numpy"`: a division by
zero, which none of them can make, would give inf or nan instead of raising, and
without that raising branch numba drops most of the reference counting (atomic
operations) on the arrays they take. Nothing else changes: the same numbers, faster.
"""
import math
import numbers

import numba
import numpy as np

# SPEC section 1.
SPEED = 3.0                  # V, m/s
TIME_CONSTANT = 5.0          # T, s
SAMPLING_INTERVAL = 0.2      # Delta, s
SAMPLES_PER_CONTROL = 3      # a control (0.6 s) holds r for 3 sampling intervals
CONTROL_INTERVAL = SAMPLING_INTERVAL * SAMPLES_PER_CONTROL
MAX_TURN_RATE = 15.0         # |theta_dot| and |r| bound, deg/s

# SPEC section 2: the full task.
FIELD_SIZE = 1000.0
GATE = np.array([[350.0, 400.0], [450.0, 400.0]])
STEER_MAX_STEPS = 5000       # control steps, then truncated
# SPEC section 8: the continuing task's measure, gate passes per hour of sailing.
HOUR_STEPS = 6000            # control steps of 0.6 s in one hour
PATROL_MAX_STEPS = HOUR_STEPS  # the Gymnasium / dm_control patrol truncates after one hour
STEP_REWARD = -1.0
GATE_REWARD = 100.0
OUT_OF_BOUNDS_REWARD = -100.0

# SPEC section 3: the two low-level subtasks in their local frame.
LOCAL_SIZE = 150.0
DIAGONAL_START = np.array([40.0, 40.0])
DIAGONAL_GOAL = np.array([140.0, 140.0])
STRAIGHT_START = np.array([40.0, 75.0])
STRAIGHT_GOAL = np.array([140.0, 75.0])
GOAL_RADIUS = 10.0
SUBTASK_MAX_STEPS = 300
SHAPING_WIDTH_DEG = 30.0

# The eight directions of the root, clockwise from north (SPEC section 3).
DIRECTIONS = ("N", "NE", "E", "SE", "S", "SW", "W", "NW")

# Event codes returned by the rule functions.
NO_EVENT = 0
SUCCESS = 1      # gate passed / local goal reached
FAILURE = -1     # bounds left


def limited_steps(limit, max_steps=None):
  """The control steps an episode runs at most: `max_steps` (None: `STEER_MAX_STEPS`), or
  `limit`, a level's time limit (None: none), where that is shorter. A larger `max_steps`
  does not reopen an episode its level has closed; a smaller one still holds."""
  steps = STEER_MAX_STEPS if max_steps is None else max_steps
  # Anything but a number goes on as it came, to the check that refuses it by name.
  if limit is None or isinstance(steps, bool) or not isinstance(steps, numbers.Real):
    return steps
  return min(steps, limit)


@numba.njit(cache=True, error_model="numpy", inline="always")
def wrap_deg(angle):
  """Wraps an angle (one float) in degrees to [-180, 180): `(angle + 180) % 360 - 180`,
  to the bit (`wrap_deg_array` for arrays).

  A heading moves at most 3 degrees a sample, so the float modulo (an fmod)
  is skipped where its result is known exactly: inside [0, 360) it is the
  number itself, in [360, 720) an exact subtraction (Sterbenz's lemma), in
  (-360, 0) the same rounded addition that `%` makes.
  """
  shifted = angle + 180.0
  if 0.0 <= shifted < 360.0:
    return shifted - 180.0
  if 360.0 <= shifted < 720.0:
    return (shifted - 360.0) - 180.0
  if -360.0 < shifted < 0.0:
    return (shifted + 360.0) - 180.0
  return shifted % 360.0 - 180.0


@numba.njit(cache=True, error_model="numpy", inline="always")
def place(ship, start):
  """`ship` set to the state `start` [x, y, theta_deg, theta_dot_deg], its heading wrapped
  (as an environment's `reset(options={"state": ...})` wraps it)."""
  for j in range(4):
    ship[j] = start[j]
  ship[2] = wrap_deg(start[2])


@numba.njit(cache=True, error_model="numpy", inline="always")
def clipped(r_deg):
  """A turning rate clipped to [-MAX_TURN_RATE, MAX_TURN_RATE] deg/s, as the
  environments clip their action."""
  return min(max(r_deg, -MAX_TURN_RATE), MAX_TURN_RATE)


def wrap_deg_array(angles):
  """`wrap_deg` for an array of angles (numpy; `wrap_deg` takes one float)."""
  return (np.asarray(angles, dtype=np.float64) + 180.0) % 360.0 - 180.0


@numba.njit(cache=True, error_model="numpy", inline="always")
def euler_sample(state, r_deg, speed, time_constant, dt):
  """One sampling interval of Equation 1 (explicit Euler), in place."""
  theta = state[2]
  theta_dot = state[3]
  rad = math.radians(theta)
  state[0] += dt * speed * math.sin(rad)
  state[1] += dt * speed * math.cos(rad)
  state[2] = wrap_deg(theta + dt * theta_dot)
  state[3] = theta_dot + dt * (r_deg - theta_dot) / time_constant


@numba.njit(cache=True, error_model="numpy")
def euler_control(state, r_deg, samples, speed=SPEED, time_constant=TIME_CONSTANT,
                  dt=SAMPLING_INTERVAL):
  """One control interval: `r_deg` held for `len(samples) - 1` sampling intervals.

  `samples[0]` receives the starting position and `samples[k]` the position after
  sampling interval k, so that the rules can look at every sampled segment.
  """
  samples[0, 0] = state[0]
  samples[0, 1] = state[1]
  for k in range(1, samples.shape[0]):
    euler_sample(state, r_deg, speed, time_constant, dt)
    samples[k, 0] = state[0]
    samples[k, 1] = state[1]


@numba.njit(cache=True)
def euler_run(state, r_deg, n_samples, speed=SPEED, time_constant=TIME_CONSTANT,
              dt=SAMPLING_INTERVAL):
  """Sails `n_samples` sampling intervals with a constant `r_deg` (for benchmarks)."""
  for _ in range(n_samples):
    euler_sample(state, r_deg, speed, time_constant, dt)


@numba.njit(cache=True)
def euler_batch(states, r_deg, samples):
  """One control interval for a batch: `states` (n, 4), `r_deg` (n,), `samples` (n, k, 2)."""
  for i in range(states.shape[0]):
    euler_control(states[i], r_deg[i], samples[i])


@numba.njit(cache=True, inline="always")
def _cross(ax, ay, bx, by):
  return ax * by - ay * bx


@numba.njit(cache=True, error_model="numpy")
def segment_crosses(p0x, p0y, p1x, p1y, q0x, q0y, q1x, q1y):
  """Whether the sailed segment p0->p1 crosses the segment q0-q1 (the gate).

  The crossing point must lie between the posts (inclusive) and after p0 along
  the sailed segment (p0 excluded, p1 included), so a ship that stops exactly on
  the line counts once, not twice. Sailing along the gate line is no crossing.
  """
  dx = p1x - p0x
  dy = p1y - p0y
  ex = q1x - q0x
  ey = q1y - q0y
  denom = _cross(dx, dy, ex, ey)
  if denom == 0.0:
    return False
  wx = q0x - p0x
  wy = q0y - p0y
  t = _cross(wx, wy, ex, ey) / denom   # along the sailed segment
  u = _cross(wx, wy, dx, dy) / denom   # along the gate
  return 0.0 < t <= 1.0 and 0.0 <= u <= 1.0


@numba.njit(cache=True, error_model="numpy")
def steer_event(samples, gate, field_size):
  """The full task's outcome over one control interval (SPEC section 2).

  Returns (event, k): SUCCESS when a sampled segment crosses the gate, FAILURE
  when a sampled position leaves [0, field_size]^2, NO_EVENT otherwise; k is the
  sample at which it happened. The first event in time wins.
  """
  for k in range(1, samples.shape[0]):
    if segment_crosses(samples[k - 1, 0], samples[k - 1, 1], samples[k, 0], samples[k, 1],
                       gate[0, 0], gate[0, 1], gate[1, 0], gate[1, 1]):
      return SUCCESS, k
    x = samples[k, 0]
    y = samples[k, 1]
    if x < 0.0 or x > field_size or y < 0.0 or y > field_size:
      return FAILURE, k
  return NO_EVENT, 0


@numba.njit(cache=True, error_model="numpy")
def subtask_event(local_samples, goal, goal_radius, local_size):
  """A low-level subtask's outcome over one control interval (SPEC section 3).

  `local_samples` are the sampled positions in the subtask's local frame.
  SUCCESS within `goal_radius` of the goal, FAILURE outside [0, local_size]^2.
  The step limit is the caller's (it counts control steps).
  """
  return _subtask_event_at(local_samples, goal[0], goal[1], goal_radius, local_size)


@numba.njit(cache=True, error_model="numpy")
def _subtask_event_at(local_samples, goal_x, goal_y, goal_radius, local_size):
  """`subtask_event` with the goal as two floats."""
  for k in range(1, local_samples.shape[0]):
    x = local_samples[k, 0]
    y = local_samples[k, 1]
    dx = x - goal_x
    dy = y - goal_y
    # hypot(dx, dy) >= max(|dx|, |dy|) (libm's hypot is faithfully rounded), so
    # the square root is taken only near the goal: the same answers, faster.
    if abs(dx) <= goal_radius and abs(dy) <= goal_radius and math.hypot(dx, dy) <= goal_radius:
      return SUCCESS, k
    if x < 0.0 or x > local_size or y < 0.0 or y > local_size:
      return FAILURE, k
  return NO_EVENT, 0


@numba.njit(cache=True, error_model="numpy")
def bearing_deg(x, y, goal_x, goal_y):
  """Heading (deg, clockwise from +y) that points from (x, y) at the goal."""
  return math.degrees(math.atan2(goal_x - x, goal_y - y))


@numba.njit(cache=True, error_model="numpy")
def shaping_reward(x, y, theta_deg, goal_x, goal_y, width_deg=SHAPING_WIDTH_DEG):
  """Internal reward G = exp(-(theta - theta_hat)^2 / width^2) - 1 (SPEC section 3)."""
  diff = wrap_deg(theta_deg - bearing_deg(x, y, goal_x, goal_y))
  return math.exp(-(diff * diff) / (width_deg * width_deg)) - 1.0


# ----------------------------------------------------------------------------
# The local frame of the low-level subtasks (SPEC section 3).
#
# Direction d in 0..7 (N, NE, ..., NW) is the compass heading 45*d degrees.
# The diagonal subtask sails local NE (45 deg), the straight subtask local E
# (90 deg); the frame is turned clockwise by a multiple of 90 degrees so that
# the local direction lands on the global one. Turning by quarter turns uses
# exact 0/+-1 matrices, so the map is an exact isometry of Equation 1.
# ----------------------------------------------------------------------------

@numba.njit(cache=True)
def is_diagonal(direction):
  """Whether `direction` (0-7, eighths of a turn) is a diagonal one."""
  return direction % 2 == 1


@numba.njit(cache=True)
def quarter_turns(direction):
  """Clockwise quarter turns taking the local frame onto global direction `direction`."""
  local_heading = 45 if direction % 2 == 1 else 90
  return ((45 * direction - local_heading) // 90) % 4


@numba.njit(cache=True, inline="always")
def _rotate_cw(vx, vy, quarters):
  """Turns vector (vx, vy) clockwise by `quarters` * 90 degrees (heading += 90 * quarters)."""
  q = quarters % 4
  if q == 0:
    return vx, vy
  if q == 1:
    return vy, -vx
  if q == 2:
    return -vx, -vy
  return -vy, vx


@numba.njit(cache=True)
def local_start(direction):
  """(x, y) in m of a local subtask's start in its frame: the diagonal's or the
  straight's."""
  if direction % 2 == 1:
    return DIAGONAL_START[0], DIAGONAL_START[1]
  return STRAIGHT_START[0], STRAIGHT_START[1]


@numba.njit(cache=True)
def local_goal(direction):
  """(x, y) in m of a local subtask's goal in its frame: the diagonal's or the
  straight's."""
  if direction % 2 == 1:
    return DIAGONAL_GOAL[0], DIAGONAL_GOAL[1]
  return STRAIGHT_GOAL[0], STRAIGHT_GOAL[1]


@numba.njit(cache=True, error_model="numpy")
def global_to_local(state, origin, direction, out):
  """Maps a global ship state into the local frame of a call that began at `origin`.

  `origin` is the global (x, y) where the subtask was called; it maps to the
  local start. `out` receives [x, y, theta_deg, theta_dot_deg] in the local frame.
  """
  q = quarter_turns(direction)
  sx, sy = local_start(direction)
  lx, ly = _rotate_cw(state[0] - origin[0], state[1] - origin[1], -q)
  out[0] = sx + lx
  out[1] = sy + ly
  out[2] = wrap_deg(state[2] - 90.0 * q)
  out[3] = state[3]


@numba.njit(cache=True)
def local_to_global(local_state, origin, direction, out):
  """The inverse of `global_to_local`."""
  q = quarter_turns(direction)
  sx, sy = local_start(direction)
  gx, gy = _rotate_cw(local_state[0] - sx, local_state[1] - sy, q)
  out[0] = origin[0] + gx
  out[1] = origin[1] + gy
  out[2] = wrap_deg(local_state[2] + 90.0 * q)
  out[3] = local_state[3]


@numba.njit(cache=True, error_model="numpy")
def samples_to_local(samples, origin, direction, out):
  """Maps sampled global positions (k, 2) into the local frame."""
  q = quarter_turns(direction)
  sx, sy = local_start(direction)
  for k in range(samples.shape[0]):
    lx, ly = _rotate_cw(samples[k, 0] - origin[0], samples[k, 1] - origin[1], -q)
    out[k, 0] = sx + lx
    out[k, 1] = sy + ly


def check_state(state, task: str, low_xy: float = 0.0, high_xy: float = FIELD_SIZE) -> np.ndarray:
  """Returns `state` as a float64 [x, y, theta_deg, theta_dot_deg], or raises.

  Position must lie in [low_xy, high_xy]^2, the heading is any finite angle
  (wrapped), the turning rate must lie in [-15, 15] deg/s.
  """
  arr = np.asarray(state, dtype=np.float64)
  if arr.shape != (4,):
    raise ValueError(f"{task}: a ship state is [x, y, theta_deg, theta_dot_deg] (shape (4,)), "
                     f"got shape {arr.shape}")
  names = ("x", "y", "theta_deg", "theta_dot_deg")
  for name, value in zip(names, arr.tolist()):
    if not math.isfinite(value):
      raise ValueError(f"{task}: state {name} must be finite, got {value!r}")
  for name, value in zip(names[:2], arr[:2].tolist()):
    if not low_xy <= value <= high_xy:
      raise ValueError(f"{task}: state {name}={value!r} is off the field; allowed "
                       f"[{low_xy}, {high_xy}] m")
  if not -MAX_TURN_RATE <= arr[3] <= MAX_TURN_RATE:
    raise ValueError(f"{task}: state theta_dot_deg={float(arr[3])!r} is outside the allowed "
                     f"[{-MAX_TURN_RATE}, {MAX_TURN_RATE}] deg/s")
  out = arr.copy()
  out[2] = wrap_deg(out[2])
  return out


@numba.njit(cache=True)
def pilot_turn_rate(state, target_x, target_y, heading_gain=0.4, lead=4.0):
  """A scripted helmsman: the turning rate r (deg/s) that heads for (target_x, target_y).

  It asks for a turning rate proportional to the heading error and, because the
  ship answers with a 5 s lag, commands past it (`lead` seconds of the rate
  error) to get there sooner. Used for demonstrations and videos, not learned.
  """
  error = wrap_deg(bearing_deg(state[0], state[1], target_x, target_y) - state[2])
  wanted = min(max(heading_gain * error, -MAX_TURN_RATE), MAX_TURN_RATE)
  r = wanted + lead * (wanted - state[3]) / TIME_CONSTANT * 2.0
  return min(max(r, -MAX_TURN_RATE), MAX_TURN_RATE)


@numba.njit(cache=True)
def gate_pilot_target(state, phase):
  """Waypoints for the scripted helmsman: first 150 m off the gate on the ship's
  side (phase 0), then through the gate's middle (phase 1). Returns (x, y, phase)."""
  mid_x = 0.5 * (GATE[0, 0] + GATE[1, 0])
  mid_y = 0.5 * (GATE[0, 1] + GATE[1, 1])
  side = 1.0 if state[1] >= mid_y else -1.0
  if phase == 0:
    ax, ay = mid_x, mid_y + side * 150.0
    if math.hypot(state[0] - ax, state[1] - ay) < 40.0:
      phase = 1
    else:
      return ax, ay, 0
  return mid_x, mid_y - side * 60.0, phase


@numba.njit(cache=True)
def patrol_pilot_target(state, phase, offset=25.0, reach=40.0):
  """Waypoints of the figure-eight helmsman of the continuing task (SPEC section 8).

  Phase 0: towards the approach point `reach` m off the gate's middle on the
  ship's side, `offset` m to the east when the ship is north of the gate line and
  to the west when south, until within 30 m of it; phase 1: through the gate's
  middle, aiming 60 m beyond it. After a pass the caller sets phase 0 again: the
  ship, now on the other side, swings round the next approach point (east of the
  gate going south, west going north: a figure eight) and comes back. The
  defaults are the tightest of a small sweep (offset 0-75 m, reach 40-120 m, one
  hour from 3 uniform starts) that still sails an eight: ~112 passes an hour
  (a plain hairpin, offset 0, gives ~133; reach 90 m ~56).
  Returns (x, y, phase).
  """
  mid_x = 0.5 * (GATE[0, 0] + GATE[1, 0])
  mid_y = 0.5 * (GATE[0, 1] + GATE[1, 1])
  side = 1.0 if state[1] >= mid_y else -1.0
  if phase == 0:
    ax, ay = mid_x + side * offset, mid_y + side * reach
    if math.hypot(state[0] - ax, state[1] - ay) < 30.0:
      phase = 1
    else:
      return ax, ay, 0
  return mid_x, mid_y - side * 60.0, phase


# ---- outcomes of one control step (shared by every path) ----------------------------

@numba.njit(cache=True, error_model="numpy")
def low_level_outcome(samples, state, origin, direction, steps_in_call, local_samples,
                      local_state, max_steps):
  """After one control step inside a low-level call: (local event, G).

  The local event is SUCCESS (goal within 10 m), FAILURE (left the 150 m frame,
  or `max_steps` control steps without success) or NO_EVENT. G is the internal
  reward: the heading shaping and the local +100 / -100; it never reaches the
  root. The low level learns from R + G with R the step's -1.
  """
  samples_to_local(samples, origin, direction, local_samples)
  gx, gy = local_goal(direction)
  event, _ = _subtask_event_at(local_samples, gx, gy, GOAL_RADIUS, LOCAL_SIZE)
  if event == NO_EVENT and steps_in_call >= max_steps:
    event = FAILURE
  global_to_local(state, origin, direction, local_state)
  internal = shaping_reward(local_state[0], local_state[1], local_state[2], gx, gy)
  if event == SUCCESS:
    internal += GATE_REWARD
  elif event == FAILURE:
    internal += OUT_OF_BOUNDS_REWARD
  return event, internal


@numba.njit(cache=True, error_model="numpy")
def global_outcome(samples, gate_reward, out_of_bounds_reward):
  """The full task's event and reward for one control step (SPEC section 2)."""
  event, _ = steer_event(samples, GATE, FIELD_SIZE)
  reward = STEP_REWARD
  if event == SUCCESS:
    reward += gate_reward
  elif event == FAILURE:
    reward += out_of_bounds_reward
  return event, reward


# ---- one control step of a Gymnasium / dm_control ship task, single or batched --------

TIMEOUT = -2     # a subtask's 300 control steps without success (a FAILURE, SPEC section 3)


@numba.njit(cache=True)
def task_outcome(samples, end_state, steps, is_steer, goal, size, max_steps, success_reward,
                 failure_reward):
  """(event, reward, terminated, truncated) of the task after one control step.

  `samples` are the positions sampled during the step, `end_state` the state at
  its end, `steps` the control steps taken so far, this one included. The full
  task (`is_steer`) ends at the gate or off the field and is truncated after
  `max_steps` (SPEC section 2); a subtask ends at its `goal`, off its field or
  as a TIMEOUT after `max_steps`, and adds the heading shaping (SPEC section 3).
  The event is NO_EVENT, SUCCESS, FAILURE or TIMEOUT.
  """
  reward = STEP_REWARD
  if is_steer:
    event, _ = steer_event(samples, GATE, size)
  else:
    event, _ = subtask_event(samples, goal, GOAL_RADIUS, size)
    if event == NO_EVENT and steps >= max_steps:
      event = TIMEOUT
    reward += shaping_reward(end_state[0], end_state[1], end_state[2], goal[0], goal[1],
                             SHAPING_WIDTH_DEG)
  if event == SUCCESS:
    reward += success_reward
  elif event == FAILURE or event == TIMEOUT:
    reward += failure_reward
  terminated = event != NO_EVENT
  truncated = not terminated and steps >= max_steps
  return event, reward, terminated, truncated


@numba.njit(cache=True, error_model="numpy", inline="always")
def sail_batch(states, r_deg, active, samples):
  """One control interval of Equation 1 for every `active` ship of a batch: `euler_control`
  for each, sample by sample across the batch (the ships' independent chains of sin and
  cos then overlap in the processor). Every batch of ships on still water sails here
  (`task_step_batch`, the regatta's `ship_regatta_core.step_batch`)."""
  n = states.shape[0]
  for i in range(n):
    if active[i]:
      samples[i, 0, 0] = states[i, 0]
      samples[i, 0, 1] = states[i, 1]
  for k in range(1, samples.shape[1]):
    for i in range(n):
      if active[i]:
        state = states[i]
        euler_sample(state, r_deg[i], SPEED, TIME_CONSTANT, SAMPLING_INTERVAL)
        samples[i, k, 0] = state[0]
        samples[i, k, 1] = state[1]


@numba.njit(cache=True)
def task_step_batch(states, r_deg, active, samples, steps, integrate, is_steer, goal, size,
                    max_steps, success_reward, failure_reward, outcome):
  """One control step of every `active` ship of a batch, in one call.

  With `integrate` the ships sail Equation 1 here (`euler_control`, as the
  single analytic ship does); without it `samples` and `states` already hold
  the step's sampled positions and end states (the MuJoCo ships). Then each
  active ship's `steps` count grows by one and `task_outcome` fills `outcome` =
  (event, reward, terminated, truncated), one array each; inactive ships are left
  untouched.
  """
  event, reward, terminated, truncated = outcome
  n = states.shape[0]
  if integrate:
    sail_batch(states, r_deg, active, samples)
  for i in range(n):
    if not active[i]:
      continue
    steps[i] += 1
    e, rw, te, tr = task_outcome(samples[i], states[i], steps[i], is_steer, goal, size,
                                 max_steps, success_reward, failure_reward)
    event[i] = e
    reward[i] = rw
    terminated[i] = te
    truncated[i] = tr
