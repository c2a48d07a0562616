"""Ship steering in pure JAX (SPEC sections 1-3 and 8), gymnax's interface.

The analytic ship of `hpg_mj.worlds.ship_core`, written again over jax.numpy:
Equation 1 by explicit Euler at dt = 0.2 s, three samples per 0.6 s control
(`euler_control`), the gate and the field checked on every sampled segment, the
first event in time winning (`steer_event`), the subtasks' goal, frame, time-out
and heading shaping (`subtask_event`, `shaping_reward`, `task_outcome`). Every
operation is the numba world's, in its order, so that in float64 a trajectory
equals the numba world's to rounding (the tests: 1,000 seeded episodes per task
within 1e-9); the numba world, the dm_control and the Gymnasium tasks stay the
reference. `ship_core` gives the constants only: nothing numba compiles is called.

One environment class for the four tasks of `hpg_mj.envs.ship.ShipSteeringEnv`
(its docstring is the manual; the ids are `hpg_mj.jax.ENV_IDS`): `steer`, the
full task of SPEC section 2; `diagonal` and `straight`, the low-level subtasks
in their 150 m frame (SPEC section 3); `patrol`, the continuing task of SPEC
section 8, where leaving the field costs the penalty and puts the ship at a fresh
uniform start drawn from the step's key, and only the clock ends an episode.

Differences from the Gymnasium environment, all forced by running under jit: an
action outside [-15, 15] deg/s is clipped (there is no strict mode), and a NaN
action is not refused (it makes the state NaN); an action of the wrong shape or
kind is refused when the step is traced. `step` resets an ended episode in the
same call (gymnax's auto-reset); `step_env` does not.
"""
import functools

import jax
import jax.numpy as jnp
import numpy as np

from hpg_mj.jax import environment
from hpg_mj.worlds import ship_core as core

TASKS = ("steer", "diagonal", "straight", "patrol")


@environment.record
class EnvState:
  """A ship and its episode (`ship_core`'s state array, named)."""
  x: jax.Array               # m (the local frame's for the subtasks)
  y: jax.Array               # m
  theta_deg: jax.Array       # heading, deg clockwise from +y, in [-180, 180)
  theta_dot_deg: jax.Array   # turning rate, deg/s
  time: jax.Array            # control steps taken in this episode
  event: jax.Array           # the last step's: core.NO_EVENT, SUCCESS, FAILURE or TIMEOUT


@environment.record
class EnvParams:
  """What a user may change per call; the defaults are SPEC sections 1-3 and 8's."""
  max_steps_in_episode: int = core.STEER_MAX_STEPS  # control steps, then truncated
  gate_reward: float = core.GATE_REWARD              # +100 (subtasks: reaching the goal)
  out_of_bounds_reward: float = core.OUT_OF_BOUNDS_REWARD  # -100 (subtasks: failing)
  speed: float = core.SPEED                          # V, m/s (Equation 1)
  time_constant: float = core.TIME_CONSTANT          # T, s
  sampling_interval: float = core.SAMPLING_INTERVAL  # dt, s


def wrap_deg(angle):
  """`ship_core.wrap_deg` over arrays, to the bit: the same three exact branches
  before the float modulo (jnp's `%` is Python's, as numba's)."""
  shifted = angle + 180.0
  return jnp.where(
      (0.0 <= shifted) & (shifted < 360.0), shifted - 180.0,
      jnp.where((360.0 <= shifted) & (shifted < 720.0), (shifted - 360.0) - 180.0,
                jnp.where((-360.0 < shifted) & (shifted < 0.0), (shifted + 360.0) - 180.0,
                          shifted % 360.0 - 180.0)))


def sail(x, y, theta_deg, theta_dot_deg, r_deg, params):
  """One control interval of Equation 1 (`ship_core.euler_control`): `r_deg` held for
  three sampling intervals. Returns the end state and the four sampled positions
  (the start first), on which the gate and the bounds are checked."""
  dt, speed = params.sampling_interval, params.speed
  positions = [(x, y)]
  for _ in range(core.SAMPLES_PER_CONTROL):
    rad = jnp.radians(theta_deg)                       # Eq. 1, as `euler_sample`
    x = x + dt * speed * jnp.sin(rad)
    y = y + dt * speed * jnp.cos(rad)
    theta_deg, theta_dot_deg = (
        wrap_deg(theta_deg + dt * theta_dot_deg),
        theta_dot_deg + dt * (r_deg - theta_dot_deg) / params.time_constant)
    positions.append((x, y))
  return x, y, theta_deg, theta_dot_deg, positions


def _cross(ax, ay, bx, by):
  return ax * by - ay * bx


def segment_crosses(p0x, p0y, p1x, p1y, q0x, q0y, q1x, q1y):
  """`ship_core.segment_crosses`: the sailed segment p0->p1 crosses the gate q0-q1
  (between the posts inclusive, after p0, up to p1 inclusive; never along it)."""
  dx, dy = p1x - p0x, p1y - p0y
  ex, ey = q1x - q0x, q1y - q0y
  denom = _cross(dx, dy, ex, ey)
  parallel = denom == 0.0
  safe = jnp.where(parallel, 1.0, denom)
  wx, wy = q0x - p0x, q0y - p0y
  t = _cross(wx, wy, ex, ey) / safe   # along the sailed segment
  u = _cross(wx, wy, dx, dy) / safe   # along the gate
  return ~parallel & (0.0 < t) & (t <= 1.0) & (0.0 <= u) & (u <= 1.0)


def _first(events):
  """The first event in time of a list of per-sample event codes (0: none)."""
  first = events[0]
  for event in events[1:]:
    first = jnp.where(first == core.NO_EVENT, event, first)
  return first


def steer_event(positions, size):
  """`ship_core.steer_event`'s event: SUCCESS where a sampled segment crosses the
  gate, FAILURE where a sampled position leaves [0, size]^2 (SPEC section 2)."""
  (g0x, g0y), (g1x, g1y) = core.GATE.tolist()
  events = []
  for (px, py), (x, y) in zip(positions[:-1], positions[1:]):
    crossed = segment_crosses(px, py, x, y, g0x, g0y, g1x, g1y)
    left = (x < 0.0) | (x > size) | (y < 0.0) | (y > size)
    events.append(jnp.where(crossed, core.SUCCESS, jnp.where(left, core.FAILURE, core.NO_EVENT)))
  return _first(events)


def subtask_event(positions, goal_x, goal_y, size):
  """`ship_core.subtask_event`'s event: SUCCESS within 10 m of the local goal,
  FAILURE outside [0, size]^2 (SPEC section 3)."""
  radius = core.GOAL_RADIUS
  events = []
  for x, y in positions[1:]:
    dx, dy = x - goal_x, y - goal_y
    reached = (jnp.abs(dx) <= radius) & (jnp.abs(dy) <= radius) & (jnp.hypot(dx, dy) <= radius)
    left = (x < 0.0) | (x > size) | (y < 0.0) | (y > size)
    events.append(jnp.where(reached, core.SUCCESS, jnp.where(left, core.FAILURE, core.NO_EVENT)))
  return _first(events)


def shaping_reward(x, y, theta_deg, goal_x, goal_y):
  """G = exp(-(theta - theta_hat)^2 / 30^2) - 1 (SPEC section 3; `ship_core.shaping_reward`)."""
  bearing = jnp.degrees(jnp.arctan2(goal_x - x, goal_y - y))
  diff = wrap_deg(theta_deg - bearing)
  width = core.SHAPING_WIDTH_DEG
  return jnp.exp(-(diff * diff) / (width * width)) - 1.0


class ShipSteering(environment.Environment):
  """One ship task (`task`: "steer", "diagonal", "straight" or "patrol") as a
  gymnax environment; `hpg_mj.jax.make("ShipSteering-v0")` builds it with its
  parameters. Observation `[x, y, theta_deg, theta_dot_deg]` in the default float
  dtype (float64 with `jax_enable_x64`); action the turning rate r in deg/s,
  shape (1,) (or ()). `info`: `terminated`, `truncated`, `event` (the codes of
  `ship_core`: 0 none, 1 gate or goal, -1 out of bounds, -2 the subtask's time-out),
  `discount` (0 only where terminated) and, for the patrol, `state_before_restart`.
  """

  # A level's time limit in control steps (the ladder's hard levels set theirs: each
  # core's `episode_steps`), or None: `max_steps_in_episode` alone.
  time_limit = None

  def __init__(self, task="steer", env_id=None):
    if task not in TASKS:
      raise ValueError(f"unknown ship task {task!r}; valid tasks: {list(TASKS)}")
    self.task = task
    self.env_id = env_id or f"ShipSteering({task})"
    self.continuing = task == "patrol"
    if task in ("steer", "patrol"):
      self.size, self.start, self.goal = core.FIELD_SIZE, None, None
    else:
      diagonal = task == "diagonal"
      self.size = core.LOCAL_SIZE
      self.start = tuple((core.DIAGONAL_START if diagonal else core.STRAIGHT_START).tolist())
      self.goal = tuple((core.DIAGONAL_GOAL if diagonal else core.STRAIGHT_GOAL).tolist())

  @property
  def name(self):
    return self.env_id

  @property
  def default_params(self):
    steps = {"steer": core.STEER_MAX_STEPS, "patrol": core.PATROL_MAX_STEPS}.get(
        self.task, core.SUBTASK_MAX_STEPS)
    return EnvParams(max_steps_in_episode=steps)

  @property
  def num_actions(self):
    return 1

  def action_space(self, params=None):
    return environment.Box(-core.MAX_TURN_RATE, core.MAX_TURN_RATE, (1,),
                           environment.float_dtype())

  def observation_space(self, params=None):
    # `hpg_mj.envs.ship.spaces_of`: the field with one control step's overshoot.
    margin = core.SPEED * core.CONTROL_INTERVAL
    high = self.size + margin
    return environment.Box(jnp.array([-margin, -margin, -180.0, -core.MAX_TURN_RATE]),
                           jnp.array([high, high, 180.0, core.MAX_TURN_RATE]), (4,),
                           environment.float_dtype())

  def get_obs(self, state, params=None, key=None):
    return jnp.stack([state.x, state.y, state.theta_deg, state.theta_dot_deg])

  def closes(self, params):
    """The control steps an episode runs at most: `max_steps_in_episode`, or the level's
    time limit where shorter (a larger one does not reopen an episode that has closed)."""
    steps = params.max_steps_in_episode
    return steps if self.time_limit is None else jnp.minimum(steps, self.time_limit)

  def is_terminal(self, state, params):
    out_of_time = state.time >= self.closes(params)
    if self.continuing:            # SPEC section 8: only the clock ends the process
      return out_of_time
    return (state.event != core.NO_EVENT) | out_of_time

  # ---- starts -------------------------------------------------------------------

  def _state(self, x, y, theta_deg, theta_dot_deg):
    dtype = environment.float_dtype()
    x, y, theta_deg, theta_dot_deg = (jnp.asarray(v, dtype) for v in
                                      (x, y, theta_deg, theta_dot_deg))
    return EnvState(x, y, wrap_deg(theta_deg), theta_dot_deg,
                    jnp.asarray(0, jnp.int32), jnp.asarray(core.NO_EVENT, jnp.int32))

  def _draw_start(self, key):
    """SPEC section 2: x, y, heading and turning rate uniform over their ranges (the
    subtasks: at the local start, heading and turning rate uniform)."""
    # One draw of four uniforms: each call of the generator is compiled on its own.
    size = self.size if self.start is None else 0.0
    low = jnp.array([0.0, 0.0, -180.0, -core.MAX_TURN_RATE], environment.float_dtype())
    high = jnp.array([size, size, 180.0, core.MAX_TURN_RATE], environment.float_dtype())
    x, y, theta, rate = jax.random.uniform(key, (4,), low.dtype, low, high)
    if self.start is not None:
      x, y = self.start
    return self._state(x, y, theta, rate)

  def reset_env(self, key, params):
    state = self._draw_start(key)
    return self.get_obs(state, params), state

  def reset_to(self, ship_state, params=None):
    """`(obs, state)` starting exactly at `ship_state` = `[x, y, theta_deg,
    theta_dot_deg]` (the Gymnasium environment's `reset(options={"state": ...})`).
    Its values are checked as there where they are known (not under jit or vmap)."""
    arr = jnp.asarray(ship_state)
    if arr.shape != (4,):
      raise ValueError(f"{self.env_id}: reset_to takes a ship state [x, y, theta_deg, "
                       f"theta_dot_deg] of shape (4,), got shape {arr.shape}")
    if environment.is_concrete(arr):
      core.check_state(np.asarray(arr, dtype=np.float64), self.env_id, 0.0, self.size)
    return self._start_at(arr, params)

  @functools.partial(jax.jit, static_argnames=("self",))
  def _start_at(self, arr, params=None):
    params = self.default_params if params is None else params
    state = self._state(arr[0], arr[1], arr[2], arr[3])
    return self.get_obs(state, params), state

  # ---- one control step ---------------------------------------------------------

  def _turn_rate(self, action, dtype):
    arr = jnp.asarray(action)
    if arr.shape not in ((), (1,)) or not (jnp.issubdtype(arr.dtype, jnp.number)
                                            or arr.dtype == jnp.bool_):
      raise ValueError(f"{self.env_id}: the action is the turning rate r in deg/s, a number "
                       f"of shape (1,) or (), got shape {arr.shape} of dtype {arr.dtype}")
    # Clipped as the Gymnasium environment's default (non-strict); SPEC section 1.
    return jnp.clip(arr.reshape(()).astype(dtype), -core.MAX_TURN_RATE, core.MAX_TURN_RATE)

  def _sail(self, state, r_deg, params):
    """One control interval from `state` (`sail`; a world with water moving sails
    its own): the end state and the sampled positions."""
    return sail(state.x, state.y, state.theta_deg, state.theta_dot_deg, r_deg, params)

  def step_env(self, key, state, action, params):
    r = self._turn_rate(action, state.x.dtype)
    x, y, theta, rate, positions = self._sail(state, r, params)
    time = state.time + 1
    # `ship_core.task_outcome`, the sums in its order.
    reward = jnp.asarray(core.STEP_REWARD, x.dtype)
    if self.goal is None:
      event = steer_event(positions, self.size)
    else:
      gx, gy = self.goal
      event = subtask_event(positions, gx, gy, self.size)
      event = jnp.where((event == core.NO_EVENT) & (time >= params.max_steps_in_episode),
                        core.TIMEOUT, event)
      reward = reward + shaping_reward(x, y, theta, gx, gy)
    reward = reward + jnp.where(event == core.SUCCESS, params.gate_reward, 0.0)
    reward = reward + jnp.where((event == core.FAILURE) | (event == core.TIMEOUT),
                                params.out_of_bounds_reward, 0.0)
    event = event.astype(jnp.int32)
    end = EnvState(x, y, theta, rate, time, event)
    info = {}
    if self.continuing:
      # SPEC section 8: leaving the field puts the ship at a fresh uniform start.
      info["state_before_restart"] = self.get_obs(end, params)
      fresh = self._draw_start(key).replace(time=time, event=event)
      end = jax.tree.map(lambda a, b: jnp.where(event == core.FAILURE, a, b), fresh, end)
      terminated = jnp.asarray(False)
    else:
      terminated = event != core.NO_EVENT
    truncated = ~terminated & (time >= self.closes(params))
    info.update(terminated=terminated, truncated=truncated, event=event,
                discount=jnp.where(terminated, 0.0, 1.0).astype(x.dtype))
    return self.get_obs(end, params), end, reward, terminated | truncated, info
