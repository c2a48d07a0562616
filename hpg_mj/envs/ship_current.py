"""The ship in a current as a Gymnasium environment and its native batch, on the MuJoCo
or the analytic ship (`hpg_mj.worlds.ship_current_core`)."""
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from hpg_mj.envs import ship as ship_env
from hpg_mj.envs import vector
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_current_core as current_core


class AnalyticCurrentBackend(ship_env.AnalyticBackend):
  """Equation 1 with the drift (`ship_current_core.drift_control`), explicit Euler."""

  def __init__(self, field):
    super().__init__()
    self.field = field

  def control(self, r_deg):
    samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
    current_core.drift_control(self._state, r_deg, samples, self.field)
    return samples, self._state.copy()


class MujocoCurrentBackend(ship_env.MujocoBackend):
  """The MJCF ship of assets/ship_current.xml, its current actuators set from the field."""

  def __init__(self, field):
    from hpg_mj.worlds import ship_current   # MuJoCo and dm_control only for this backend
    self.physics = ship_current.Physics.from_xml_string(*ship_current.get_model_and_assets())
    self.physics.set_field(field)
    self._nstep = core.SAMPLES_PER_CONTROL * self.physics._substeps_per_sample()


def _backend(name, field):
  if name == "mujoco":
    return MujocoCurrentBackend(field)
  if name == "analytic":
    return AnalyticCurrentBackend(field)
  raise ValueError(f"unknown ship backend {name!r}; valid backends: {list(ship_env.BACKENDS)}")


def spaces_of(rules, field):
  """`ship.spaces_of` with the water's velocity (c_x, c_y) after the ship's state."""
  observation, action = ship_env.spaces_of(rules)
  speed = current_core.max_speed(field)
  observation = spaces.Box(low=np.append(observation.low, [-speed, -speed]),
                           high=np.append(observation.high, [speed, speed]), dtype=np.float64)
  return observation, action


class ShipCurrentEnv(ship_env.ShipSteeringEnv):
  """Ship steering in a current (`hpg_mj/ShipCurrent-v0`).

  ## Description
  The steering task of `hpg_mj/ShipSteering-v0` (a 1 km field, the gate between
  (350, 400) and (450, 400), a ship at 3 m/s whose turning rate follows the command
  with a 5 s lag) on water that moves and carries the ship with it: over ground the
  ship sails `3 m/s * (sin(theta), cos(theta)) + c(x, y)`. To cross the current a
  policy heads partly into it and crabs. The field, in m/s, with `s = x / 1000`,
  `t = y / 1000` (clamped to [0, 1]):
  `c_x = u_x + river * 4 t (1 - t)`, `c_y = u_y + cross * (2 s - 1)`.

  | level | u_x | u_y | river | cross | fastest water |
  |---|---|---|---|---|---|
  | easy | 1.0 | 0 | 0 | 0 | 1.0 m/s, the same everywhere |
  | medium | 0.5 | 0 | 1.5 | 0 | 2.0 m/s mid-field, 0.5 at the edges |
  | hard | 0.5 | 0 | 2.2 | 0.8 | 2.8 m/s (2.7 east, 0.8 across) |

  ## Action space
  `Box(-15, 15, (1,), float64)`: the desired turning rate r in deg/s, held for one
  0.6 s control interval, as in `hpg_mj/ShipSteering-v0` (clipped, or refused with
  `strict=True`; NaN, infinity or a wrong shape raise `ValueError`).

  ## Observation space
  `Box(float64, (6,))`: the ship's state as in `hpg_mj/ShipSteering-v0`, then the
  water's velocity where the ship is (what its log reads: speed over ground less
  speed through the water), bounded by the level's fastest water.

  | Num | Observation | Unit |
  |---|---|---|
  | 0 | `x`: position east | m |
  | 1 | `y`: position north | m |
  | 2 | `theta_deg`: heading, clockwise from north (+y), in [-180, 180) | deg |
  | 3 | `theta_dot_deg`: turning rate | deg/s |
  | 4 | `current_x`: the water's velocity east, where the ship is | m/s |
  | 5 | `current_y`: the water's velocity north, where the ship is | m/s |

  ## Rewards
  -1 per control step, +100 more for passing the gate (in either direction, between
  the posts), -100 more for leaving the field.

  ## Starting state
  x, y uniform on [0, 1000] m, heading uniform on [-180, 180) deg, turning rate
  uniform on [-15, 15] deg/s; `reset(options={"state": [x, y, theta_deg,
  theta_dot_deg]})` starts from an exact state.

  ## Episode end
  Terminated at the gate or off the field (`info["event"]`: "gate",
  "out_of_bounds"); truncated after 5,000 control steps (`max_steps`; the
  environment truncates itself, without Gymnasium's `TimeLimit`); at `hard` the
  episode closes after 1,000 control steps (600 s), whatever a larger `max_steps` asks.

  ## Information
  As in `hpg_mj/ShipSteering-v0`: `reset()` returns `{"event": None}`; `step()`
  returns `event` ("gate", "out_of_bounds" or None) and `positions`, a `(4, 2)`
  array of the positions sampled every 0.2 s during the step (row 0 where it
  began), on which the gate and the bounds are checked.

  ## Arguments
  - `level="easy"`: "easy", "medium" or "hard".
  - `backend="mujoco"`: assets/ship_current.xml, the keel dragged towards the
    water's velocity by two actuators; or "analytic" (Equation 1 with the drift,
    explicit Euler at 0.2 s; `hpg-mj verify current` measures both against the
    continuous ODE).
  - `render_mode=None`: or "rgb_array" (the steering ship's picture; its wake
    shows the drift).
  - `strict=False`: True refuses out-of-range turning rates instead of clipping
    them.
  - `max_steps=None`: the episode's length in control steps; None is 5,000 (at most
    1,000 at `hard`).
  - `width=640`, `height=480`: the frame's size in pixels, at most 1280 x 960.
  - `camera=None`: "top", "local", "overview" or "chase"; None is "top".
  - `gate_reward=100.0`, `out_of_bounds_reward=-100.0`: the +100 and -100 of
    SPEC section 2.

  ## References
  [1] M. Ghavamzadeh and S. Mahadevan, "Hierarchical Policy Gradient
  Algorithms," Proceedings of the 20th International Conference on Machine
  Learning (ICML), 2003 (the ship steering task in still water).

  [2] W. T. Miller, R. S. Sutton and P. J. Werbos (eds.), *Neural Networks for
  Control*, MIT Press, 1990.

  ## Version history
  - v0: the first release (not yet tagged: until then a v0 task may still change;
    each change is dated in docs/changelog.md, and scores made before it are not
    comparable with later ones).
  - v0, 2026-12-07: a step before the first reset is refused, one after the episode's
    end warned of (refused with `strict=True`).
  """

  def __init__(self, level=current_core.DEFAULT_LEVEL, backend="mujoco", render_mode=None,
               strict=False, max_steps=None, width=640, height=480, camera=None,
               gate_reward=core.GATE_REWARD, out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD):
    self.level = level
    self.field = current_core.level_field(level, "ShipCurrentEnv")
    super().__init__("steer", backend, render_mode, strict,
                     current_core.episode_steps(level, max_steps), width, height, camera,
                     gate_reward, out_of_bounds_reward)
    self._name = f"ShipCurrent({level}, backend={backend})"
    self.observation_space, self.action_space = spaces_of(self.rules, self.field)

  def _make_backend(self, name):
    return _backend(name, self.field)

  def _with_current(self, state):
    x, y = state[:2].tolist()      # Python floats: numba types numpy's slowly (17 us)
    return np.append(state, current_core.current_at(self.field, x, y))

  def reset(self, *, seed=None, options=None):
    state, info = super().reset(seed=seed, options=options)
    return self._with_current(state), info

  def step(self, action):
    state, reward, terminated, truncated, info = super().step(action)
    return self._with_current(state), reward, terminated, truncated, info


class _AnalyticCurrentShips:
  """The batch's ships sail in the current here (`drift_batch`, one compiled call);
  the rules then run over the batch as for the steering ship."""

  integrate = False

  def __init__(self, field):
    self.field = field

  def set_state(self, states, i, state):
    states[i] = state

  def control(self, states, r, active, samples):
    current_core.drift_batch(states, r, active, samples, self.field)


class ShipCurrentVectorEnv(vector.ShipSteeringVectorEnv):
  """A batch of `num_envs` ships in a current (`ShipCurrentEnv`'s manual; the batch
  as `ShipSteeringVectorEnv`'s): `gymnasium.make_vec("hpg_mj/ShipCurrent-v0",
  num_envs=N, level="hard", backend="analytic")`. Observations `(N, 6)`: each row as
  the single environment's."""

  def __init__(self, num_envs=1, level=current_core.DEFAULT_LEVEL, backend="mujoco",
               strict=False, max_steps=None, gate_reward=core.GATE_REWARD,
               out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD,
               autoreset_mode=AutoresetMode.NEXT_STEP, render_mode=None):
    self.level = level
    self.field = current_core.level_field(level, "ShipCurrentVectorEnv")
    super().__init__(num_envs, "steer", backend, strict,
                     current_core.episode_steps(level, max_steps), gate_reward,
                     out_of_bounds_reward, autoreset_mode, render_mode)
    self.who = f"ShipCurrentVectorEnv({level}, backend={backend})"
    self.single_observation_space, _ = spaces_of(self.rules, self.field)
    self.observation_space = batch_space(self.single_observation_space, self.num_envs)
    self._currents = np.zeros((self.num_envs, 2))

  def _make_ships(self, backend):
    if backend == "analytic":
      return _AnalyticCurrentShips(self.field)
    if backend == "mujoco":
      return vector._MujocoShips(self.num_envs, lambda: MujocoCurrentBackend(self.field))
    raise ValueError(f"unknown ship backend {backend!r}; valid backends: "
                     f"{list(ship_env.BACKENDS)}")

  def _observations(self):
    current_core.currents_of(self._states, self.field, self._currents)
    return np.concatenate([self._states, self._currents], axis=1)
