"""The ship in a current, in the style of dm_control's suite: the steering task of
SPEC section 2 on water that carries the ship (`ship_current_core`'s field).

Tasks:
  easy:   1 m/s of current towards the east, the same everywhere.
  medium: a river towards the east, 0.5 m/s at the north and south edges and 2.0 m/s
          mid-field.
  hard:   the river up to 2.7 m/s mid-field, and a cross flow of up to 0.8 m/s
          (south on the west side, north on the east): water up to 2.8 m/s, nearly
          the ship's own 3 m/s.

Everything else is `ship/steer`'s: the 1 km field, the gate (350, 400)-(450, 400),
the uniform starts, -1 per control step, +100 for the gate, -100 for leaving the
field, 5,000 control steps then truncated. The observation adds the water's velocity
where the ship is (`current`, m/s). On MuJoCo the drift is the keel's drag towards the
water's velocity, two actuators of assets/ship_current.xml whose controls the
`Physics` sets to the field at the ship before every MuJoCo step; the analytic ship
sails the same equations (`ship_current_core.drift_control`), and
`hpg-mj verify current` measures both against the continuous ODE.
"""
import numba
import numpy as np

from hpg_mj import _assets
from hpg_mj import _headless
from hpg_mj.worlds import ship
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_current_core as current_core
from hpg_mj.worlds import ship_model
from hpg_mj.worlds.ship_model import _c_call

with _headless.simulation_imports():   # no GL in the simulating process (SPEC section 9)
  import mujoco as mj
  from dm_control.utils import containers

SUITE = containers.TaggedTasks()

MODEL = "ship_current.xml"


def get_model_and_assets():
  """The MJCF model of the ship in a current and its assets (ship.xml, which it
  includes)."""
  return _assets.read_model(MODEL), {"ship.xml": _assets.read_model("ship.xml").encode()}


@numba.njit(cache=True)
def sail_current(mj_step, model, data, substeps, qpos, act, ctrl, first, bow, timestep, field,
                 rows, positions, state):
  """`ship_model.sail` in the current: before every MuJoCo step the controls of the
  current actuators (`ctrl[first]`, `ctrl[first + 1]`) are set to the water's velocity half a step
  ahead of the bow (the midpoint rule for the drift); `mj_step` <= 0 calls nothing
  (the caller steps through the bindings instead)."""
  for j in range(3):
    rows[0, j] = qpos[j]
  for k in range(1, rows.shape[0]):
    for _ in range(substeps):
      set_current_controls(qpos, ctrl, first, bow, timestep, field)
      _c_call(mj_step, model, data)
    for j in range(3):
      rows[k, j] = qpos[j]
  ship_model.bow_readings(rows, act, bow, positions, state)


@numba.njit(cache=True, error_model="numpy")
def set_current_controls(qpos, ctrl, first, bow, timestep, field):
  """The current actuators' controls: the water's velocity where the bow will be half a
  MuJoCo step on (sailing V along the heading plus the water here)."""
  sin, cos = np.sin(qpos[2]), np.cos(qpos[2])
  x = qpos[0] + bow * sin
  y = qpos[1] + bow * cos
  cx, cy = current_core.current_at(field, x, y)
  half = 0.5 * timestep
  ctrl[first], ctrl[first + 1] = current_core.current_at(field, x + half * (core.SPEED * sin + cx),
                                             y + half * (core.SPEED * cos + cy))


class Physics(ship.Physics):
  """The MuJoCo ship in a current (assets/ship_current.xml); `field` is the level's."""

  field = np.array(current_core.LEVELS[current_core.DEFAULT_LEVEL])

  def _reload_from_data(self, data):
    super()._reload_from_data(data)
    first = mj.mj_name2id(self._model_ptr, mj.mjtObj.mjOBJ_ACTUATOR, "current_x")
    if first < 0 or mj.mj_name2id(self._model_ptr, mj.mjtObj.mjOBJ_ACTUATOR,
                                  "current_y") != first + 1:
      raise ValueError(f"{MODEL}: the actuators current_x, current_y must follow each other")
    self._first_current = first

  def set_field(self, field):
    """Sets the water's velocity field (`ship_current_core`'s four numbers)."""
    self.field = np.asarray(field, dtype=np.float64).copy()

  def set_ship_state(self, state):
    super().set_ship_state(state)
    set_current_controls(self._qpos, self._ctrl, self._first_current, self._bow,
                         self._model_ptr.opt.timestep, self.field)

  def current(self):
    """The water's velocity (c_x, c_y) in m/s at the ship, as a new array."""
    x, y = self._position()
    return np.array(current_core.current_at(self.field, x, y))

  def _sail(self, substeps, rows, positions, state):
    """`ShipPhysics._sail` with the current's controls set before every MuJoCo step."""
    timestep = self._model_ptr.opt.timestep
    if ship_model.MJ_STEP:
      args = (ship_model.MJ_STEP, self._addresses[0], self._addresses[1], substeps, self._qpos,
              self._act, self._ctrl, self._first_current, self._bow, timestep, self.field, rows,
              positions, state)
      if self._sailing is None:      # numba's code for these types, typed once
        self._sailing = sail_current.compile(tuple(numba.typeof(a) for a in args))
      self._sailing(*args)
      return
    model, data, qpos = self._model_ptr, self._data_ptr, self._qpos
    rows[0] = qpos
    for k in range(1, rows.shape[0]):
      for _ in range(substeps):
        set_current_controls(qpos, self._ctrl, self._first_current, self._bow, timestep,
                             self.field)
        mj.mj_step(model, data)
      rows[k] = qpos
    ship_model.bow_readings(rows, self._act, self._bow, positions, state)


class CurrentTask(ship.ShipTask):
  """`ship/steer` in the current of one level; the observation adds `current`."""

  def __init__(self, level=current_core.DEFAULT_LEVEL, random=None, initial_state=None,
               strict=False, max_steps=None, **rewards):
    """Args:
      level: "easy", "medium" or "hard" (`ship_current_core.LEVELS`).
      random, initial_state, strict: as `ShipTask`'s (a seed, a fixed start, whether a
        turning rate outside [-15, 15] deg/s is an error rather than clipped).
      max_steps: control steps before the episode is truncated (default 5,000; at
        hard at most the level's time limit, 1,000).
      **rewards: `gate_reward`, `out_of_bounds_reward` (as `ShipTask`'s).
    """
    self.level = level
    self.field = current_core.level_field(level, "ship_current")
    super().__init__("steer", random=random, initial_state=initial_state, strict=strict,
                     max_steps=current_core.episode_steps(level, max_steps), **rewards)
    self.name = f"ship_current-{level}"

  def initialize_episode(self, physics):
    physics.set_field(self.field)
    super().initialize_episode(physics)

  def get_observation(self, physics):
    obs = super().get_observation(physics)
    x, y = obs["position"].tolist()     # Python floats: numba types numpy's slowly (17 us)
    obs["current"] = np.array(current_core.current_at(self.field, x, y))
    return obs


def _constructor(level):
  def task(random=None, initial_state=None, strict=False, max_steps=None,
           environment_kwargs=None, gate_reward=core.GATE_REWARD,
           out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD):
    return ship.environment(
        Physics.from_xml_string(*get_model_and_assets()),
        CurrentTask(level, random=random, initial_state=initial_state, strict=strict,
                    max_steps=max_steps, gate_reward=gate_reward,
                    out_of_bounds_reward=out_of_bounds_reward), environment_kwargs)
  task.__name__ = task.__qualname__ = level
  task.__doc__ = (f"`ship/steer` in the current of level {level!r} (water up to "
                  f"{current_core.max_speed(current_core.LEVELS[level]):.2f} m/s); the rewards "
                  "at the gate and off the field are SPEC section 2's unless given.")
  if current_core.TIME_LIMITS[level] is not None:
    task.__doc__ += (f" The episode closes after {current_core.TIME_LIMITS[level]:,} control "
                     "steps, whatever a larger `max_steps` asks.")
  return task


easy = SUITE.add("benchmarking", "easy")(_constructor("easy"))
medium = SUITE.add("benchmarking", "medium")(_constructor("medium"))
hard = SUITE.add("benchmarking", "hard")(_constructor("hard"))
