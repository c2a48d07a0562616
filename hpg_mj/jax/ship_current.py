"""The ship in a current in pure JAX (SPEC section 11, `hpg_mj/ShipCurrent-v0`),
gymnax's interface.

The analytic ship of `hpg_mj.worlds.ship_current_core`, written again over
jax.numpy: Equation 1 by explicit Euler at 0.2 s with the water's velocity
`c(x, y)` read where each sampling interval begins and added to the ship's own
(`drift_sample`), three samples per control; everything else is the steering
task's (`hpg_mj.jax.ship`: the gate and the field checked on every sampled
segment, the first event in time winning, the rewards, the step limit). Every
operation is the numba world's, in its order, so that in float64 a trajectory
equals it to rounding (tests/jax/test_jax_ladder.py: 1,000 seeded episodes per
level within 1e-9). `ship_current_core` gives the levels' numbers only: nothing
numba compiles is called.

The level (`easy`, `medium`, `hard`) is a constructor argument, as the Gymnasium
environment's: `hpg_mj.jax.make("ShipCurrent-v0", level="hard")`. It gives the
default parameters: the field's four numbers are `CurrentParams` fields, like the
step limit and the rewards, so that one compiled step sails any level's water (or
another field: `params.replace(river=3.0)`, vmapped over fields if wished). The
observation adds the water's velocity at the ship, `[x, y, theta_deg,
theta_dot_deg, current_x, current_y]` (m, deg, deg/s, m/s); its space is bounded
by the level's fastest water, as the Gymnasium environment's.
"""
import jax.numpy as jnp

from hpg_mj.jax import environment
from hpg_mj.jax import ship
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_current_core as current_core


@environment.record
class CurrentParams(ship.EnvParams):
  """The steering task's `EnvParams` and the water's velocity field (SPEC section 11,
  `ship_current_core`, m/s): `c_x = uniform_x + river * 4 t (1 - t)`, `c_y = uniform_y
  + cross * (2 s - 1)`, with `s = x / 1000`, `t = y / 1000` clamped to [0, 1]."""
  uniform_x: float = current_core.LEVELS[current_core.DEFAULT_LEVEL][0]
  uniform_y: float = current_core.LEVELS[current_core.DEFAULT_LEVEL][1]
  river: float = current_core.LEVELS[current_core.DEFAULT_LEVEL][2]
  cross: float = current_core.LEVELS[current_core.DEFAULT_LEVEL][3]


def current_at(params, x, y):
  """`ship_current_core.current_at`: the water's velocity (c_x, c_y) in m/s at (x, y)
  in the field of `params` (a `CurrentParams`)."""
  sx = jnp.minimum(jnp.maximum(x / core.FIELD_SIZE, 0.0), 1.0)
  sy = jnp.minimum(jnp.maximum(y / core.FIELD_SIZE, 0.0), 1.0)
  cx = params.uniform_x + params.river * 4.0 * sy * (1.0 - sy)
  cy = params.uniform_y + params.cross * (2.0 * sx - 1.0)
  return cx, cy


def drift_sail(x, y, theta_deg, theta_dot_deg, r_deg, params):
  """One control interval of Equation 1 in the current (`ship_current_core.drift_control`):
  `r_deg` held for three sampling intervals, the water read where each begins. Returns
  the end state and the four sampled positions (the start first)."""
  dt, speed = params.sampling_interval, params.speed
  positions = [(x, y)]
  for _ in range(core.SAMPLES_PER_CONTROL):
    rad = jnp.radians(theta_deg)
    cx, cy = current_at(params, x, y)
    # `drift_sample`'s sums in its order: Equation 1's term, then the drift's.
    x = x + (dt * speed * jnp.sin(rad) + dt * cx)
    y = y + (dt * speed * jnp.cos(rad) + dt * cy)
    theta_deg, theta_dot_deg = (
        ship.wrap_deg(theta_deg + dt * theta_dot_deg),
        theta_dot_deg + dt * (r_deg - theta_dot_deg) / params.time_constant)
    positions.append((x, y))
  return x, y, theta_deg, theta_dot_deg, positions


class ShipCurrent(ship.ShipSteering):
  """`hpg_mj/ShipCurrent-v0` as a gymnax environment: the steering task (`ShipSteering`
  with `task="steer"`; its `EnvState` and `info`) on water that carries the ship;
  `level` ("easy", "medium" or "hard"; `ship_current_core.LEVELS`) gives the default
  `CurrentParams`. Observation `[x, y, theta_deg, theta_dot_deg, current_x,
  current_y]` in the default float dtype; action the turning rate r in deg/s, shape
  (1,) (or ()), clipped to [-15, 15]. The manual is
  `hpg_mj.envs.ship_current.ShipCurrentEnv`'s.
  """

  def __init__(self, level=current_core.DEFAULT_LEVEL, env_id=None):
    self.level = level
    self.field = tuple(current_core.level_field(level, env_id or "ShipCurrent").tolist())
    self.time_limit = current_core.TIME_LIMITS[level]
    super().__init__("steer", env_id or f"ShipCurrent({level})")

  @property
  def default_params(self):
    ux, uy, river, cross = self.field
    return CurrentParams(max_steps_in_episode=current_core.episode_steps(self.level),
                         uniform_x=ux, uniform_y=uy, river=river, cross=cross)

  def observation_space(self, params=None):
    # `hpg_mj.envs.ship_current.spaces_of`: the ship's, then the level's fastest water.
    ship_space = super().observation_space(params)
    speed = current_core.max_speed(self.field if params is None else
                                   (params.uniform_x, params.uniform_y, params.river,
                                    params.cross))
    return environment.Box(jnp.append(ship_space.low, jnp.array([-speed, -speed])),
                           jnp.append(ship_space.high, jnp.array([speed, speed])), (6,),
                           environment.float_dtype())

  def get_obs(self, state, params=None, key=None):
    params = self.default_params if params is None else params
    cx, cy = current_at(params, state.x, state.y)
    dtype = state.x.dtype
    return jnp.stack([state.x, state.y, state.theta_deg, state.theta_dot_deg,
                      jnp.asarray(cx, dtype), jnp.asarray(cy, dtype)])

  def _sail(self, state, r_deg, params):
    return drift_sail(state.x, state.y, state.theta_deg, state.theta_dot_deg, r_deg, params)
