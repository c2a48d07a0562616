"""Gymnasium taxi environments: `hpg_mj/TaxiFuel-v0` and `hpg_mj/Taxi-v0`."""
import gymnasium
import numpy as np
from gymnasium import spaces

from hpg_mj import _validation
from hpg_mj import envs
from hpg_mj.worlds import taxi_core


class TaxiEnv(gymnasium.Env):
  """
  Dietterich's taxi with the fuel extension of Ghavamzadeh & Mahadevan (2003):
  drive to the passenger, pick them up, drive to their destination and drop
  them off, without running out of fuel.

  ## Description
  A 5x5 grid with four stations, Red, Green, Yellow and Blue, and a fuel
  station F. The taxi starts on a random square and the passenger at one of the
  four stations, wanting to go to one of the other three. With fuel
  (`hpg_mj/TaxiFuel-v0`, SPEC section 5) every action burns one unit of fuel
  from a tank of 12, except filling up at F; an empty tank ends the episode.
  Without fuel (`hpg_mj/Taxi-v0`) this is Gymnasium's `Taxi-v3` with one rule
  of Dietterich's kept: the passenger can only be dropped off at their
  destination.

  Map (row 0 at the top, column 0 on the left):

      +---------+
      |R: | : :G|
      | : | : : |
      | :F: : : |
      | | : | : |
      |Y| : |B: |
      +---------+

  The rules are `hpg_mj.worlds.taxi_core`, shared with the dm_control tasks
  (`hpg_mj.suite.load("taxi", "fuel")`); the picture is the MuJoCo board
  `assets/taxi.xml`.

  From "Hierarchical Policy Gradient Algorithms" by M. Ghavamzadeh and
  S. Mahadevan (ICML 2003, Section 5.1) [<a href="#hpg_ref">1</a>], after
  "Hierarchical Reinforcement Learning with the MAXQ Value Function
  Decomposition" by T. G. Dietterich [<a href="#taxi_ref">2</a>].

  ## Action Space
  The action is an integer in 0..6 (0..5 without fuel), numbered as in
  Gymnasium's Taxi:

  - 0: Move south (down)
  - 1: Move north (up)
  - 2: Move east (right)
  - 3: Move west (left)
  - 4: Pickup passenger
  - 5: Drop off passenger
  - 6: Fill up the tank (fuel only)

  An action that is not one of these (a float with a fraction, NaN, an array
  of more than one element, 6 without fuel) raises a `ValueError`.

  ## Observation Space
  `MultiDiscrete([5, 5, 5, 4, 13])` (`[5, 5, 5, 4]` without fuel), int64:
  `[taxi_row, taxi_col, passenger_location, destination, fuel]`.

  | Num | Observation | Values |
  |---|---|---|
  | 0 | `taxi_row` | the taxi's row, 0 at the top |
  | 1 | `taxi_col` | the taxi's column, 0 on the left |
  | 2 | `passenger_location` | 0 Red, 1 Green, 2 Yellow, 3 Blue, 4 in the taxi |
  | 3 | `destination` | 0 Red, 1 Green, 2 Yellow, 3 Blue |
  | 4 | `fuel` (with fuel only) | units in the tank, 0..12 |

  For tabular learners `taxi_core.encode_state` maps a state to one index:
  Gymnasium's `((row * 5 + col) * 5 + passenger) * 4 + destination` (500
  states), plus `fuel * 500` with fuel (6,500 states).

  ## Rewards
  - -1 per action unless another reward is triggered.
  - +20 delivering the passenger (Dropoff with the passenger in the taxi, at
    the destination).
  - -10 executing Pickup or Dropoff illegally (no passenger on the taxi's
    square, nobody aboard, or not at the destination).
  - -20 instead of the action's own reward for any action taken with an empty
    tank, other than Fillup at F.

  Moving into a wall, or Fillup away from F, is a -1 no-op that still burns a
  unit of fuel. Fillup at F costs no fuel and sets the tank to 12, even from 0.

  ## Starting State
  The taxi on a uniformly random square, the passenger at a uniformly random
  station, the destination uniformly one of the other three stations and, with
  fuel, the fuel uniform in 5..12: 300 start states without fuel (as
  Gymnasium's Taxi), 2,400 with fuel.

  `reset(options={"state": [row, col, passenger, destination, fuel]})` (no fuel
  without fuel) starts from that exact state; an impossible state raises a
  `ValueError` naming the field and what is allowed.

  ## Episode End
  The episode ends if the following happens:

  - Termination:
      1. The taxi drops off the passenger at the destination.
      2. An action is taken with an empty tank (other than Fillup at F).

  - Truncation (inside the environment, no wrapper needed):
      1. The length of the episode is 200 actions.

  ## Information
  `step()` and `reset()` return `{"action_mask": ...}`: an int8 array with 1
  for each action that does something on the board (a move not into a wall,
  a legal Pickup or Dropoff, Fillup at F below a full tank), as in Gymnasium's
  Taxi; it ignores the fuel. Sample with
  `env.action_space.sample(info["action_mask"])`.

  ## Arguments

  ```python
  import gymnasium as gym
  import hpg_mj
  gym.make("hpg_mj/TaxiFuel-v0", render_mode="rgb_array")
  gym.make("hpg_mj/Taxi-v0")
  ```

  `render_mode=None`: `"rgb_array"` makes `render()` return an HxWx3 uint8 frame
  of the MuJoCo board.

  `fuel=True`: the fuel task (set by the id).

  `width=480`, `height=480`: the frame's size in pixels (at most 1280 x 960).

  `camera="top"`: `"top"` (orthographic, from above) or `"angled"`.

  `strict=True`: refuse what no episode of the task contains: a start state
  with the passenger waiting at its own destination, and `step()` after the
  episode ended without `reset()`. With `strict=False` both are accepted, as in
  Gymnasium's Taxi.

  `max_steps=200`, `fuel_station=(2, 1)`, `capacity=12`, `start_fuel=(5, 12)`:
  SPEC section 5's defaults for the time limit, the square of F, the tank and
  the start fuel range.

  `level=None`: the task ladder's argument (`hpg_mj/ShipHarbour-v0`...); the taxi
  has no levels, and any level is refused, naming the ids that have.

  ## References
  <a id="hpg_ref"></a>[1] M. Ghavamzadeh and S. Mahadevan, "Hierarchical Policy
  Gradient Algorithms," ICML 2003.

  <a id="taxi_ref"></a>[2] T. G. Dietterich, "Hierarchical Reinforcement
  Learning with the MAXQ Value Function Decomposition," Journal of Artificial
  Intelligence Research, vol. 13, pp. 227-303, 2000, doi: 10.1613/jair.639.

  ## Version History
  * v0: Initial version: the rules of SPEC section 5 (Gymnasium Taxi-v3's map
    and action numbers, Dietterich's Dropoff rule, fuel station F at (2, 1)).
  """

  metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

  model_file = "taxi.xml"    # the MJCF model its frames are drawn from (assets/)
  _MAX_FRAME = (1280, 960)   # the offscreen buffer of assets/taxi.xml (a test checks it)

  def __init__(self, render_mode=None, fuel=True, width=480, height=480, camera="top",
               strict=True, max_steps=taxi_core.MAX_STEPS, fuel_station=taxi_core.FUEL_STATION,
               capacity=taxi_core.FUEL_CAPACITY,
               start_fuel=(taxi_core.START_FUEL_MIN, taxi_core.START_FUEL_MAX), level=None):
    self.name = "hpg_mj/TaxiFuel-v0" if fuel else "hpg_mj/Taxi-v0"
    envs.refuse_level(self.name, level)
    if render_mode is not None and render_mode not in self.metadata["render_modes"]:
      raise ValueError(f"{self.name}: render_mode {render_mode!r} is not supported; "
                       f"allowed: None or one of {self.metadata['render_modes']}")
    for name, value, limit in (("width", width, self._MAX_FRAME[0]),
                               ("height", height, self._MAX_FRAME[1])):
      if not isinstance(value, (int, np.integer)) or not 1 <= value <= limit:
        raise ValueError(f"{self.name}: {name} must be an integer in 1..{limit} pixels, "
                         f"got {value!r}")
    if camera not in ("top", "angled"):
      raise ValueError(f"{self.name}: camera {camera!r} is not one of 'top', 'angled'")
    self.rules = taxi_core.TaxiRules(fuel, fuel_station=fuel_station, capacity=capacity,
                                     start_fuel=start_fuel, max_steps=max_steps, who=self.name)
    self.render_mode = render_mode
    self.width, self.height, self.camera = int(width), int(height), camera
    self.strict = bool(strict)

    nvec = [taxi_core.GRID_SIZE, taxi_core.GRID_SIZE, 5, 4]
    if self.rules.fuel_enabled:
      nvec.append(self.rules.capacity + 1)
    self.observation_space = spaces.MultiDiscrete(nvec, dtype=np.int64)
    self.action_space = spaces.Discrete(self.rules.num_actions)

    self._state = None       # (row, col, passenger, destination, fuel)
    self._steps = 0
    self._episode_over = False
    self._physics = None     # the MuJoCo board, built on the first render()

  @property
  def state(self):
    """The current state `(row, col, passenger, destination, fuel)`, or None before reset."""
    return self._state

  def _observation(self):
    n = len(self.observation_space.nvec)
    return np.array(self._state[:n], dtype=np.int64)

  def _info(self):
    return {"action_mask": self.rules.legal_actions(self._state)}

  def reset(self, *, seed=None, options=None):
    super().reset(seed=seed)
    options = {} if options is None else options
    unknown = set(options) - {"state"}
    if unknown:
      raise ValueError(f"{self.name}: unknown reset option(s) {sorted(unknown)}; "
                       "allowed: 'state'")
    if options.get("state") is not None:
      self._state = self.rules.check_state(options["state"], strict=self.strict)
    else:
      self._state = self.rules.sample_start(self.np_random)
    self._steps = 0
    self._episode_over = False
    return self._observation(), self._info()

  def step(self, action):
    action = _validation.discrete_action(action, self.rules.num_actions, self.name,
                                         self.rules.action_names)
    if self._state is None:
      raise RuntimeError(f"{self.name}: call reset() before step()")
    if self._episode_over and self.strict:
      raise RuntimeError(f"{self.name}: the episode has ended; call reset() before step() "
                         "(strict=False allows stepping on, as Gymnasium's Taxi does)")
    self._state, reward, terminated = self.rules.step(self._state, action)
    self._steps += 1
    # SPEC section 5: 200 primitive steps, then truncated (not terminal).
    truncated = not terminated and self._steps >= self.rules.max_steps
    self._episode_over = terminated or truncated
    return self._observation(), reward, terminated, truncated, self._info()

  def render(self):
    if self.render_mode is None:
      raise ValueError(f"{self.name}: render() needs render_mode='rgb_array' at construction, "
                       "got render_mode=None")
    if self._state is None:
      raise RuntimeError(f"{self.name}: call reset() before render()")
    if self._physics is None:
      from hpg_mj.worlds import taxi  # simulated here, drawn in a worker (SPEC section 9)
      self._physics = taxi.Physics.from_xml_string(*taxi.get_model_and_assets())
      self._physics.set_fuel_station(*self.rules.fuel_station, show=self.rules.fuel_enabled)
    self._physics.set_board_state(self._state, self.rules.fuel_enabled, self.rules.capacity)
    self._physics.forward()
    return self._physics.render(self.height, self.width, camera_id=self.camera)

  def close(self):
    if self._physics is not None:
      self._physics.free()
      self._physics = None
