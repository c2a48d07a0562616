"""Taxi domain (SPEC section 5), in the style of dm_control's suite.

Tasks:
  fuel:    taxi-fuel: Dietterich's taxi with a tank of 12 units, one unit per
           action, and a Fillup action at the fuel station F (7 actions).
  classic: Dietterich's taxi as in Gymnasium's Taxi (6 actions, no fuel).

The board is `assets/taxi.xml`. Nothing moves by physics: the discrete state
lives in `mjData.userdata` and the mocap bodies show it. The rules are the
compiled functions of `hpg_mj.worlds.taxi_core`.

```python
from hpg_mj.worlds import taxi
env = taxi.fuel(random=0)
time_step = env.reset()
time_step = env.step(taxi.taxi_core.NORTH)
```
"""
import collections

import numpy as np

from hpg_mj import _assets
from hpg_mj import _headless
from hpg_mj import _validation
from hpg_mj import _render_worker as worker
from hpg_mj.worlds import taxi_core

with _headless.simulation_imports():   # no GL in the simulating process (SPEC section 9)
  from dm_control import mujoco
  from dm_control.rl import control
  from dm_control.suite import base
  from dm_control.utils import containers
  from dm_env import specs

SUITE = containers.TaggedTasks()

# Where the pieces stand on a square, relative to its centre (m).
_PASSENGER_WAITING = np.array([-0.2, 0.2, 0.0])
_PASSENGER_ABOARD = np.array([-0.03, 0.0, 0.31])   # on the cab's roof
_GAUGE_LIT = np.array([0.2, 0.8, 0.3, 1.0])
_GAUGE_LOW = np.array([0.9, 0.25, 0.15, 1.0])       # a quarter of the tank or less
_GAUGE_EMPTY = np.array([0.2, 0.2, 0.2, 1.0])


def get_model_and_assets():
  """Returns the MJCF model of the taxi board and the (empty) assets dict."""
  return _assets.read_model("taxi.xml"), {}


def _square_centre(row, col):
  return float(col) + 0.5, taxi_core.GRID_SIZE - 0.5 - float(row)


def square_centre(row, col):
  """(x, y) in metres of the centre of square (row, col); row 0 is at the top."""
  return np.array(_square_centre(row, col))


class Physics(mujoco.Physics):
  """The taxi board: the discrete state and the pieces that show it."""

  def _reload_from_data(self, data):
    super()._reload_from_data(data)
    model = self.model.ptr
    body = lambda name: model.body(name).id
    self._mocap = {name: int(model.body_mocapid[body(name)])
                   for name in ("taxi", "passenger", "destination")}
    self._gauge = np.array([model.geom(f"gauge_{k}").id for k in range(12)])
    self._fuel_pad = (model.geom("station_F").id, model.geom("pump").id,
                      model.geom("pump_nozzle").id)
    self._pad_offsets = [model.geom_pos[i] - model.geom_pos[self._fuel_pad[0]]
                         for i in self._fuel_pad]
    self._gauge_shown = ()   # (fuel, capacity) the gauge shows, None when hidden

  def board_state(self):
    """(row, col, passenger, destination, fuel) as Python ints."""
    return tuple(map(int, self.data.userdata[:5].tolist()))

  def taxi_square(self):
    """[row, col] of the taxi, as a new int array."""
    return self.data.userdata[0:2].astype(np.int64)

  def passenger_location(self):
    """0..3: waiting at station R, G, Y, B; 4: in the taxi."""
    return int(self.data.userdata[2])

  def destination(self):
    """The passenger's destination station, 0..3 (R, G, Y, B)."""
    return int(self.data.userdata[3])

  def fuel(self):
    """Units of fuel in the tank (the classic task carries a full tank)."""
    return int(self.data.userdata[4])

  def taxi_position(self):
    """(x, y) of the taxi piece on the board, metres."""
    return self.data.mocap_pos[self._mocap["taxi"], :2].copy()

  def set_board_state(self, state, show_fuel=True, capacity=taxi_core.FUEL_CAPACITY):
    """Stores `state` and moves the pieces to show it.

    The passenger waits on the corner of its station or rides on the cab's roof;
    a frame and a flag mark the destination; the gauge lights one segment per
    `capacity / 12` units of fuel, and is hidden when `show_fuel` is False.
    """
    row, col, passenger, destination, fuel = state
    self.data.userdata[:5] = state
    pos = self.data.mocap_pos
    taxi_x, taxi_y = _square_centre(row, col)
    pos[self._mocap["taxi"]] = (taxi_x, taxi_y, 0.0)
    if passenger == taxi_core.IN_TAXI:
      x, y, z = taxi_x + _PASSENGER_ABOARD[0], taxi_y + _PASSENGER_ABOARD[1], _PASSENGER_ABOARD[2]
    else:
      x, y = _square_centre(*taxi_core.STATIONS[passenger])
      x, y, z = x + _PASSENGER_WAITING[0], y + _PASSENGER_WAITING[1], _PASSENGER_WAITING[2]
    pos[self._mocap["passenger"]] = (x, y, z)
    pos[self._mocap["destination"]] = (*_square_centre(*taxi_core.STATIONS[destination]), 0.0)
    gauge = (fuel, capacity) if show_fuel else None
    if gauge != self._gauge_shown:   # the gauge's colours live in the model: change rarely
      rgba = self.model.geom_rgba
      if show_fuel:
        lit = int(np.ceil(len(self._gauge) * fuel / capacity))
        rgba[self._gauge[:lit]] = _GAUGE_LOW if 4 * fuel <= capacity else _GAUGE_LIT
        rgba[self._gauge[lit:]] = _GAUGE_EMPTY
      else:
        rgba[self._gauge, 3] = 0.0
      self._gauge_shown = gauge

  def render(self, height=240, width=320, camera_id=-1, **options):
    """dm_control's `render`, drawn in a worker process (SPEC section 9)."""
    return worker.render_physics(self, "taxi.xml", height, width, camera_id, **options)

  def free(self):
    worker.close_physics_worker(self)
    super().free()

  def set_fuel_station(self, row, col, show=True):
    """Moves the fuel station F (pad and pump) to square (row, col), or hides it."""
    centre = np.append(square_centre(row, col), 0.0)
    for geom, offset in zip(self._fuel_pad, self._pad_offsets):
      self.model.geom_pos[geom, :2] = (centre + offset)[:2]
      self.model.geom_rgba[geom, 3] = 1.0 if show else 0.0


class Taxi(base.Task):
  """Dietterich's taxi, with or without fuel (SPEC section 5).

  Observations are small int arrays: `taxi` [row, col], `passenger` [0..4],
  `destination` [0..3] and, with fuel, `fuel` [0..12]. The reward is the
  primitive action's reward. The episode ends with discount 0 on delivery or
  when the fuel runs out, and is truncated with discount 1 after 200 steps: the
  task owns the time limit, so the Environment runs with `time_limit=inf`.
  """

  def __init__(self, fuel=True, random=None, initial_state=None, strict=True,
               max_steps=taxi_core.MAX_STEPS, fuel_station=taxi_core.FUEL_STATION,
               capacity=taxi_core.FUEL_CAPACITY,
               start_fuel=(taxi_core.START_FUEL_MIN, taxi_core.START_FUEL_MAX)):
    """Args:
      fuel: taxi-fuel (7 actions) if True, the classic taxi (6 actions) if False.
      random: seed, np.random.RandomState or None (dm_control's convention).
      initial_state: optional fixed start `[row, col, passenger, destination]`,
        plus `fuel` for the fuel task; checked here.
      strict: if True (default), a start with the passenger waiting at its own
        destination (which no episode reaches) is refused; False accepts it,
        as Gymnasium's Taxi table does.
      max_steps, fuel_station, capacity, start_fuel: SPEC section 5's 200,
        (2, 1), 12 and (5, 12); see `taxi_core.TaxiRules`.
    """
    self.name = "taxi-fuel" if fuel else "taxi-classic"
    self.rules = taxi_core.TaxiRules(fuel, fuel_station=fuel_station, capacity=capacity,
                                     start_fuel=start_fuel, max_steps=max_steps, who=self.name)
    self.strict = bool(strict)
    self.initial_state = initial_state
    self._steps = 0
    self._reward = 0.0
    self._terminated = False
    super().__init__(random=random)

  @property
  def fuel_enabled(self):
    """Whether the taxi has a fuel tank (the fuel task) or not (the classic one)."""
    return self.rules.fuel_enabled

  @property
  def initial_state(self):
    """A fixed start for the next episodes, or None for random starts."""
    return self._initial_state

  @initial_state.setter
  def initial_state(self, state):
    self._initial_state = (None if state is None
                           else self.rules.check_state(state, strict=self.strict))

  def initialize_episode(self, physics):
    """Puts the pieces on a random start (or the fixed `initial_state`)."""
    state = (self._initial_state if self._initial_state is not None
             else self.rules.sample_start(self.random))
    physics.set_fuel_station(*self.rules.fuel_station, show=self.fuel_enabled)
    physics.set_board_state(state, self.fuel_enabled, self.rules.capacity)
    self._steps = 0
    self._reward = 0.0
    self._terminated = False
    super().initialize_episode(physics)

  def action_spec(self, physics):
    return specs.DiscreteArray(num_values=self.rules.num_actions, dtype=np.int64, name="action")

  def observation_spec(self, physics):
    obs = collections.OrderedDict()
    grid = taxi_core.GRID_SIZE - 1
    obs["taxi"] = specs.BoundedArray((2,), np.int64, 0, grid, name="taxi")
    obs["passenger"] = specs.BoundedArray((1,), np.int64, 0, taxi_core.IN_TAXI, name="passenger")
    obs["destination"] = specs.BoundedArray((1,), np.int64, 0, 3, name="destination")
    if self.fuel_enabled:
      obs["fuel"] = specs.BoundedArray((1,), np.int64, 0, self.rules.capacity, name="fuel")
    return obs

  def before_step(self, action, physics):
    """Checks the action and applies the rules (SPEC section 5)."""
    action = _validation.discrete_action(action, self.rules.num_actions, self.name,
                                         self.rules.action_names)
    state, self._reward, self._terminated = self.rules.step(physics.board_state(), action)
    physics.set_board_state(state, self.fuel_enabled, self.rules.capacity)
    self._steps += 1

  def get_observation(self, physics):
    """The board state as small int arrays (new arrays each call)."""
    row, col, passenger, destination, fuel = physics.board_state()
    obs = collections.OrderedDict()
    obs["taxi"] = np.array([row, col], dtype=np.int64)
    obs["passenger"] = np.array([passenger], dtype=np.int64)
    obs["destination"] = np.array([destination], dtype=np.int64)
    if self.fuel_enabled:
      obs["fuel"] = np.array([fuel], dtype=np.int64)
    return obs

  def get_reward(self, physics):
    return self._reward

  def get_termination(self, physics):
    if self._terminated:
      return 0.0   # delivered, or out of fuel
    if self._steps >= self.rules.max_steps:
      return 1.0   # SPEC section 5: truncated, not terminal
    return None


def _environment(fuel, random, initial_state, strict, max_steps, environment_kwargs,
                 **rules_kwargs):
  physics = Physics.from_xml_string(*get_model_and_assets())
  task = Taxi(fuel=fuel, random=random, initial_state=initial_state, strict=strict,
              max_steps=max_steps, **rules_kwargs)
  environment_kwargs = dict(environment_kwargs or {})
  # The task owns the episode's length (200 primitive steps, SPEC section 5).
  environment_kwargs.setdefault("time_limit", float("inf"))
  return control.Environment(physics, task, **environment_kwargs)


@SUITE.add("benchmarking")
def fuel(random=None, initial_state=None, strict=True, max_steps=taxi_core.MAX_STEPS,
         environment_kwargs=None, **rules_kwargs):
  """Taxi-fuel (SPEC section 5); `rules_kwargs`: fuel_station, capacity, start_fuel."""
  return _environment(True, random, initial_state, strict, max_steps, environment_kwargs,
                      **rules_kwargs)


@SUITE.add("benchmarking")
def classic(random=None, initial_state=None, strict=True, max_steps=taxi_core.MAX_STEPS,
            environment_kwargs=None):
  """Dietterich's taxi without fuel, as in Gymnasium's Taxi (SPEC section 5)."""
  return _environment(False, random, initial_state, strict, max_steps, environment_kwargs)
