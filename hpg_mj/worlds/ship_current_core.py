"""The ship in a current (SPEC section 11): the water's velocity field of each level and
Equation 1 with the drift it adds, compiled (numba), shared by every backend and path.
Free of MuJoCo, as `ship_core` is (SPEC section 9).

The water moves at `c(x, y)` (m/s) and carries the ship with it: over ground the ship
sails `V * (sin(theta), cos(theta)) + c(x, y)`; heading and turning rate follow
Equation 1 unchanged (the rudder turns the hull relative to the water). To cross a
current the helmsman heads partly into it and the ship crabs: its track over ground
is not its heading.

One family of fields, four numbers per level (`LEVELS`), `s_x = x / 1000`,
`s_y = y / 1000` clamped to [0, 1]:

    c_x = uniform_x + river * 4 s_y (1 - s_y)      (a river along x, fastest mid-field)
    c_y = uniform_y + cross * (2 s_x - 1)          (a cross flow, north on the east side)

Each component varies only along the other axis, so the flow has no divergence (water
is neither made nor lost). Polynomials, not sines: a sampling interval of Equation 1
costs one sine and one cosine, and the field adds a few multiplications to it.

At `hard` the episode also closes (`TIME_LIMITS`, `episode_steps`): it is truncated
after 1,000 control steps (10 minutes) whatever a larger `max_steps` asks. The water
alone did not make the level hard: a designed hierarchy (the regatta's waypoints) passed
94% of the benchmark starts, drifting down the river and back in 902 control steps at
the median where the best known takes 312. Within the limit the best known passes 89.6%
and that hierarchy, trained under it, 48-61% (tuning seeds 0-2).
"""
import collections
import math

import numba
import numpy as np

from hpg_mj.worlds import ship_core as core

# level -> (uniform_x, uniform_y, river, cross), m/s.
LEVELS = {
    "easy": (1.0, 0.0, 0.0, 0.0),     # 1 m/s east everywhere
    "medium": (0.5, 0.0, 1.5, 0.0),   # east, 0.5 m/s at the north and south edges, 2.0 mid-field
    "hard": (0.5, 0.0, 2.2, 0.8),     # east up to 2.7 m/s mid-field; a cross flow of +-0.8 m/s
}
DEFAULT_LEVEL = "easy"
# level -> the control steps after which the episode is truncated, or None: the
# environment's `max_steps` alone (`episode_steps`).
TIME_LIMITS = {"easy": None, "medium": None, "hard": 1000}


def level_field(level, who="ship current"):
  """The field's four numbers (a float64 array) of `level`, or a one-line error."""
  if not isinstance(level, str) or level not in LEVELS:
    raise ValueError(f"{who}: unknown level {level!r}; allowed levels: {list(LEVELS)}")
  return np.array(LEVELS[level], dtype=np.float64)



def episode_steps(level, max_steps=None):
  """The control steps a current episode at `level` runs at most: `max_steps` (None:
  `ship_core.STEER_MAX_STEPS`), or the level's time limit (`TIME_LIMITS`) where that is
  shorter (`ship_core.limited_steps`)."""
  level_field(level)                  # a one-line error for an unknown level
  return core.limited_steps(TIME_LIMITS[level], max_steps)

def max_speed(field):
  """The fastest water (m/s) of a field anywhere: at the river's middle, at an edge."""
  ux, uy, river, cross = (float(v) for v in field)
  return math.hypot(max(abs(ux), abs(ux + river)), abs(uy) + abs(cross))


@numba.njit(cache=True, error_model="numpy", inline="always")
def current_at(field, x, y):
  """The water's velocity (c_x, c_y) in m/s at (x, y) (the module's formula)."""
  sx = min(max(x / core.FIELD_SIZE, 0.0), 1.0)
  sy = min(max(y / core.FIELD_SIZE, 0.0), 1.0)
  cx = field[0] + field[2] * 4.0 * sy * (1.0 - sy)
  cy = field[1] + field[3] * (2.0 * sx - 1.0)
  return cx, cy


@numba.njit(cache=True, error_model="numpy", inline="always")
def drift_sample(state, r_deg, field, speed, time_constant, dt):
  """One sampling interval of Equation 1 with the drift (explicit Euler), in place: the
  water's velocity is read where the interval begins, as the heading's sine is."""
  theta = state[2]
  theta_dot = state[3]
  rad = math.radians(theta)
  cx, cy = current_at(field, state[0], state[1])
  # Equation 1's terms as `ship_core.euler_sample` writes them, then the drift's: in
  # still water the same arithmetic, bit for bit.
  state[0] += dt * speed * math.sin(rad) + dt * cx
  state[1] += dt * speed * math.cos(rad) + dt * cy
  state[2] = core.wrap_deg(theta + dt * theta_dot)
  state[3] = theta_dot + dt * (r_deg - theta_dot) / time_constant


@numba.njit(cache=True, error_model="numpy")
def drift_control(state, r_deg, samples, field):
  """`ship_core.euler_control` in the current: `r_deg` held over the samples' intervals;
  `samples[0]` the start, `samples[k]` the position after interval k."""
  samples[0, 0] = state[0]
  samples[0, 1] = state[1]
  for k in range(1, samples.shape[0]):
    drift_sample(state, r_deg, field, core.SPEED, core.TIME_CONSTANT, core.SAMPLING_INTERVAL)
    samples[k, 0] = state[0]
    samples[k, 1] = state[1]


@numba.njit(cache=True, error_model="numpy")
def drift_batch(states, r_deg, active, samples, field):
  """One control interval of every `active` ship of a batch, sample by sample across
  the batch (as `ship_core.task_step_batch` sails Equation 1)."""
  n = states.shape[0]
  for i in range(n):
    if active[i]:
      samples[i, 0, 0] = states[i, 0]
      samples[i, 0, 1] = states[i, 1]
  for k in range(1, samples.shape[1]):
    for i in range(n):
      if active[i]:
        state = states[i]
        drift_sample(state, r_deg[i], field, core.SPEED, core.TIME_CONSTANT,
                     core.SAMPLING_INTERVAL)
        samples[i, k, 0] = state[0]
        samples[i, k, 1] = state[1]


@numba.njit(cache=True, error_model="numpy")
def currents_of(states, field, out):
  """The water's velocity at each ship's position: rows (c_x, c_y) into `out`."""
  for i in range(states.shape[0]):
    out[i, 0], out[i, 1] = current_at(field, states[i, 0], states[i, 1])


# ---- the world as pure functions over a state and its parameters -------------------
# (gymnax's shape; the open machine's fused loop, `hierarchy.algorithm.run_world`,
# calls them, and they step as the Gymnasium environment's analytic backend does: the
# same compiled rules, so both paths give the same numbers.)

EnvParams = collections.namedtuple("EnvParams", ("field", "rewards", "max_steps"))
EnvParams.__doc__ = """The current's task: the level's field (`LEVELS`' four numbers),
[gate reward, out-of-bounds reward], the control steps before truncation."""
EnvState = collections.namedtuple("EnvState", ("ship",))
EnvState.__doc__ = """The world's state: the ship's [x, y, theta_deg, theta_dot_deg]."""
START_SIZE = 4                # an episode's start: the ship's state
OBSERVATION_SIZE = 6


def env_params(level, gate_reward=core.GATE_REWARD, out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD,
               max_steps=core.STEER_MAX_STEPS):
  """The `EnvParams` of `level` with the environment's rewards and step limit (the level's
  time limit where shorter: `episode_steps`)."""
  return EnvParams(level_field(level), np.array([gate_reward, out_of_bounds_reward],
                                                dtype=np.float64),
                   np.int64(episode_steps(level, max_steps)))


def env_state(params):
  """A fresh `EnvState` (the fused loop's scratch)."""
  return EnvState(np.zeros(4))


@numba.njit(cache=True, error_model="numpy")
def observe_into(params, ship, obs):
  """The Gymnasium environment's observation of `ship` into `obs` (6): its state, then
  the water's velocity where it is."""
  for j in range(4):
    obs[j] = ship[j]
  obs[4], obs[5] = current_at(params.field, ship[0], ship[1])


@numba.njit(cache=True, error_model="numpy")
def env_reset(params, state, start, obs):
  """An episode from `start` (the ship's state; its heading wrapped as the environment's
  `reset(options={"state": ...})` wraps it); its observation into `obs`."""
  ship = state.ship
  core.place(ship, start)
  observe_into(params, ship, obs)


@numba.njit(cache=True, error_model="numpy")
def env_step(params, state, r_deg, samples, obs, steps):
  """One control step at turning rate `r_deg` (clipped to [-15, 15] deg/s, as the
  environment clips it), `steps` control steps in (this one counted): the positions
  sampled into `samples`, the observation into `obs`; returns (event, reward,
  terminated, truncated) as `ShipCurrentEnv.step` (the steering task's gate and field)."""
  r = core.clipped(r_deg)
  drift_control(state.ship, r, samples, params.field)
  event, reward = core.global_outcome(samples, params.rewards[0], params.rewards[1])
  terminated = event != core.NO_EVENT
  observe_into(params, state.ship, obs)
  return event, reward, terminated, (not terminated) and steps >= params.max_steps


@numba.njit(cache=True, error_model="numpy")
def env_end(params, state, event):
  """An ended episode's (passed the gate: 1 or 0, 0)."""
  return (1.0 if event == core.SUCCESS else 0.0), 0.0
