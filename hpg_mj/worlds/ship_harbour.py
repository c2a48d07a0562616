"""The harbour, in the style of dm_control's suite: `ship/steer`'s gate behind islands and
piers, fixed per level, that end the episode when touched (`ship_harbour_core`'s rule,
layouts and rangefinders).

Tasks:
  easy:   two islands of radius 60 m, north and south-east of the gate.
  medium: breakwaters on the gate's line either side of it, and four islands.
  hard:   breakwaters across the field up to 40 m from its edges, the gate the only way
          through the middle, its mouth in a walled pocket on either side (entered from
          one end: a channel and a quarter turn); two piers, four islands; the episode
          closes after 1,000 control steps.

The ship, the field, the gate, the uniform starts (drawn again on an obstacle) and the
bounds are `ship/steer`'s. -1 per control step, +100 at the gate; -100 for leaving the
field or touching an obstacle (the sampled track meeting its shape), either ending the
episode; 5,000 control steps, then truncated. The observation adds `ranges`: the
distances (m) to the first obstacle along seven rays at -90, -60, ..., 90 degrees from
the heading, 150 m where none is nearer: MuJoCo's rangefinder sensors of
assets/ship_harbour.xml on this path.
"""
import collections

import numba
import numpy as np

from hpg_mj import _assets
from hpg_mj import _headless
from hpg_mj.worlds import ship
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_harbour_core as harbour_core
from hpg_mj.worlds import ship_model

with _headless.simulation_imports():   # no GL in the simulating process (SPEC section 9)
  import mujoco as mj
  from dm_control.utils import containers

SUITE = containers.TaggedTasks()

MODEL = "ship_harbour.xml"
_SENSOR = int(mj.mjtDisableBit.mjDSBL_SENSOR)


def get_model_and_assets():
  """The MJCF model of the harbour and its assets (ship.xml, which it includes)."""
  return _assets.read_model(MODEL), _assets.included_assets(MODEL)


obstacle_geoms = ship_model.harbour_obstacle_geoms
place_obstacles = ship_model.place_harbour_obstacles


@numba.njit(cache=True)
def sail_and_sense(calls, model, data, substeps, qpos, act, bow, rows, positions, state, flags,
                   sensordata, readings):
  """`ship_model.sail` (`calls[0]`, mj_step), then the rangefinders where the step ended:
  the sensor stage switched on in the mjModel's `flags` (`ship_model.disableflags_view`),
  mj_kinematics (`calls[1]`) and mj_sensorPos (`calls[2]`), switched off again; their
  readings into `readings`. One compiled call per control step, as the steering ship's."""
  ship_model.sail(calls[0], model, data, substeps, qpos, act, bow, rows, positions, state)
  flags[0] &= ~_SENSOR
  ship_model._c_call(calls[1], model, data)
  ship_model._c_call(calls[2], model, data)
  flags[0] |= _SENSOR
  for j in range(readings.shape[0]):
    readings[j] = sensordata[j]


class Physics(ship.Physics):
  """The steering ship on assets/ship_harbour.xml: a level's obstacles, and the
  rangefinders, read once per control step (`ranges`)."""

  model_file = MODEL

  def _reload_from_data(self, data):
    super()._reload_from_data(data)
    model = self._model_ptr
    # Off while the ship sails (six MuJoCo steps a control step would cast every ray six
    # times); they are cast once, where the step ended.
    model.opt.disableflags |= _SENSOR
    self._sensordata = self._data_ptr.sensordata
    self.level = None
    self._flags = ship_model.disableflags_view(model)
    self._calls = np.array([ship_model.MJ_STEP, ship_model.MJ_KINEMATICS,
                            ship_model.MJ_SENSOR_POS], dtype=np.int64)
    # Every MuJoCo function found for the compiled call: asked once, not at every step
    # (ndarray.all() took 8% of the goal's hard step).
    self._compiled = self._flags is not None and bool(self._calls.all())
    self._sensing = None
    self._readings = None     # the readings of the last step, until the ship is moved

  def set_ship_state(self, state):
    self._readings = None
    super().set_ship_state(state)

  def _sail(self, substeps, rows, positions, state):
    if not self._compiled:                         # the bindings' way, then read
      super()._sail(substeps, rows, positions, state)
      self._readings = None
      return
    readings = self._readings = np.empty(harbour_core.RAYS)
    args = (self._calls, self._addresses[0], self._addresses[1], substeps, self._qpos,
            self._act, self._bow, rows, positions, state, self._flags, self._sensordata,
            readings)
    if self._sensing is None:      # numba's code for these types, typed once
      self._sensing = sail_and_sense.compile(tuple(numba.typeof(a) for a in args))
    self._sensing(*args)

  def place_obstacles(self, level):
    """The obstacles of `level` on the sea, every other level's hidden."""
    harbour_core.level_obstacles(level, "ship_harbour")
    place_obstacles(self._model_ptr, level)
    self.level = level

  def rangefinder_readings(self):
    """MuJoCo's rangefinder readings (m; -1 where a ray meets nothing) of the ship where it
    is now (a new array): those the last step cast where it ended, or its kinematics,
    then the position-stage sensors, those alone enabled."""
    if self._readings is not None:
      return self._readings.copy()
    model, data = self._model_ptr, self._data_ptr
    flags = model.opt.disableflags
    model.opt.disableflags = flags & ~_SENSOR
    try:
      mj.mj_kinematics(model, data)
      mj.mj_sensorPos(model, data)
    finally:
      model.opt.disableflags = flags
    return self._sensordata.copy()

  def ranges(self):
    """The rangefinders' ranges (m) as the harbour's observation reads them
    (`ship_harbour_core.seen_ranges`): 150 m where nothing is nearer."""
    out = np.empty(harbour_core.RAYS)
    harbour_core.seen_ranges(self.rangefinder_readings(), out, 0)
    return out


class HarbourTask(ship.ShipTask):
  """`ship/steer` among the level's obstacles (`ship_harbour_core`); the observation adds
  the rangefinders' ranges."""

  def __init__(self, level=harbour_core.DEFAULT_LEVEL, random=None, initial_state=None,
               strict=False, max_steps=None, gate_reward=harbour_core.GATE_REWARD,
               out_of_bounds_reward=harbour_core.OUT_OF_BOUNDS_REWARD):
    """Args:
      level: "easy", "medium" or "hard" (`ship_harbour_core.LEVELS`).
      random, initial_state, strict: as `ShipTask`'s (a seed, a fixed start, whether a
        turning rate outside [-15, 15] deg/s is an error rather than clipped).
      max_steps: control steps before the episode is truncated (default 5,000; at
        hard at most the level's time limit, 1,000).
      gate_reward: passing the gate; out_of_bounds_reward: leaving the field or
        touching an obstacle.
    """
    self.level = level
    harbour_core.level_obstacles(level, "ship_harbour")
    self._ship = None
    super().__init__("steer", random=random, initial_state=initial_state, strict=strict,
                     max_steps=harbour_core.episode_steps(level, max_steps),
                     gate_reward=gate_reward, out_of_bounds_reward=out_of_bounds_reward)
    self.name = f"ship_harbour-{level}"
    self._ship = harbour_core.OneShip(level, self.rules.max_steps, gate_reward,
                                      out_of_bounds_reward)

  @property
  def initial_state(self):
    """A fixed start [x, y, theta_deg, theta_dot_deg] for the next episodes, or None."""
    return self._initial_state

  @initial_state.setter
  def initial_state(self, state):
    if state is None:
      self._initial_state = None
      return
    islands, piers = harbour_core.level_shapes(self.level)
    self._initial_state = harbour_core.check_start(self.rules, state, islands, piers,
                                                   f"ship_harbour-{self.level}")

  def initialize_episode(self, physics):
    if physics.level != self.level:
      physics.place_obstacles(self.level)
    state = (self._initial_state if self._initial_state is not None
             else harbour_core.sample_start(self.rules, self.random, self._ship.islands,
                                            self._ship.piers))
    physics.set_ship_state(state)
    physics.place_target(None)
    physics._samples = None
    self._steps = 0
    self._outcome = (0.0, False, False, None)
    self._state_after_step = None

  def after_step(self, physics):
    self._steps += 1
    state = physics.stepped_state
    event, reward, terminated, truncated = self._ship(physics.sampled_positions(), self._steps)
    self._outcome = (reward, terminated, truncated, harbour_core.EVENT_NAMES[event])
    self._state_after_step = state

  def get_observation(self, physics):
    # The state of the step just taken (or the physics' own before the first), and the
    # rangefinders read where it ended; every entry a part of one new array.
    state, self._state_after_step = self._state_after_step, None
    if state is None:
      state = physics.ship_state()
    if physics.level != self.level:     # dm_control reads one observation before any reset
      physics.place_obstacles(self.level)
    seen = self._ship.observe(state, physics.rangefinder_readings())
    return collections.OrderedDict(
        (("position", seen[:2]), ("heading_deg", seen[2:3]), ("turning_rate_deg", seen[3:4]),
         ("ranges", seen[4:])))


def _constructor(level, summary):
  def task(random=None, initial_state=None, strict=False, max_steps=None,
           environment_kwargs=None, gate_reward=harbour_core.GATE_REWARD,
           out_of_bounds_reward=harbour_core.OUT_OF_BOUNDS_REWARD):
    return ship.environment(
        Physics.from_xml_string(*get_model_and_assets()),
        HarbourTask(level, random=random, initial_state=initial_state, strict=strict,
                    max_steps=max_steps, gate_reward=gate_reward,
                    out_of_bounds_reward=out_of_bounds_reward),
        environment_kwargs)
  task.__name__ = task.__qualname__ = level
  task.__doc__ = (f"Sail through ship/steer's gate past the level's obstacles (level "
                  f"{level!r}: {summary}); touching one ends the episode with the "
                  f"out-of-bounds penalty ({core.OUT_OF_BOUNDS_REWARD:g} unless given).")
  return task


easy = SUITE.add("benchmarking", "easy")(_constructor("easy", "two islands"))
medium = SUITE.add("benchmarking", "medium")(_constructor(
    "medium", "breakwaters either side of the gate, four islands"))
hard = SUITE.add("benchmarking", "hard")(_constructor(
    "hard", "breakwaters across the field, the mouth in walled pockets, closing at 1,000 steps"))
