"""The goal-conditioned ship as a Gymnasium environment with a dictionary observation
(`observation`, `achieved_goal`, `desired_goal`, and the rangefinders' `ranges`) and
`compute_reward`, as Stable-Baselines3's `HerReplayBuffer` expects, and its native batch."""
import functools

import gymnasium
import numba
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from hpg_mj.envs import ship as ship_env
from hpg_mj.envs import ship_harbour as harbour_env
from hpg_mj.envs import vector
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_goal_core as goal_core
from hpg_mj.worlds import ship_harbour_core as harbour_core


def spaces_of(rules):
  """(observation space, action space): the steering ship's state under `observation`,
  goals [x, y, sin(heading), cos(heading)] on the field (with one control step's margin)
  under `achieved_goal` and `desired_goal`, and the rangefinders' ranges, 0 to
  MAX_RANGE_M, under `ranges`."""
  state, action = ship_env.spaces_of(rules)
  goal = spaces.Box(low=np.append(state.low[:2], [-1.0, -1.0]),
                    high=np.append(state.high[:2], [1.0, 1.0]), dtype=np.float64)
  ranges = spaces.Box(low=0.0, high=harbour_core.MAX_RANGE_M, shape=(goal_core.RAYS,),
                      dtype=np.float64)
  return spaces.Dict({"observation": state, "achieved_goal": goal, "desired_goal": goal,
                      "ranges": ranges}), action


def mujoco_backend(level):
  """The MuJoCo ship of a goal `level`: among obstacles, the harbour's
  (assets/ship_harbour.xml, its rangefinders, the obstacles of `OBSTACLES[level]`); in
  open water the steering ship of assets/ship.xml, whose rays would meet nothing."""
  if goal_core.OBSTACLES[level] is None:
    return ship_env.MujocoBackend()
  return harbour_env.MujocoHarbourBackend(goal_core.OBSTACLES[level])


def aground_in(info, shape):
  """Where a step's `info` says its track touched an obstacle (`event` "obstacle"),
  as booleans of the goals' batch `shape`: `info` an environment's (a dictionary, of
  names or of arrays of names) or a sequence of them (what Stable-Baselines3's
  `HerReplayBuffer` passes); None or no `event`: nowhere."""
  if info is None:
    return np.zeros(shape, dtype=np.bool_)
  if isinstance(info, dict):
    names = np.asarray(info.get("event", None), dtype=object)
  else:
    names = np.array([i.get("event", None) if isinstance(i, dict) else None
                      for i in np.asarray(info, dtype=object).reshape(-1)],
                     dtype=object).reshape(np.shape(info))
  return np.broadcast_to(names == "obstacle", shape)


class ShipGoalEnv(ship_env.ShipSteeringEnv):
  """Ship steering to a gate drawn each episode (`hpg_mj/ShipGoal-v0`), goal-conditioned.

  ## Description
  The ship of `hpg_mj/ShipSteering-v0` (3 m/s, its turning rate following the command
  with a 5 s lag, on the 1 km field) must pass a 100 m gate whose centre and heading
  are drawn at each reset, heading within 45 degrees of the gate's heading (at `hard`
  a 50 m gate, within 30 degrees). The
  observation is Gymnasium's goal-conditioned dictionary, and `compute_reward` gives
  the reward of any achieved and desired goals, so that Hindsight Experience Replay
  [3] (Stable-Baselines3's `HerReplayBuffer`) trains on it as it is.

  | level | gate centre, each way | gate heading | gate width, heading tolerance |
  |---|---|---|---|
  | easy | uniform on [300, 500] m (around `ShipSteering`'s gate) | within 30 deg of north | 100 m, 45 deg |
  | medium | uniform on [200, 800] m | within 90 deg of north | 100 m, 45 deg |
  | hard | uniform on [100, 900] m, clear of the obstacles | any | 50 m, 30 deg |

  At `hard` the water holds the obstacles of `hpg_mj/ShipHarbour-v0`'s `medium` level
  (four islands and two breakwaters along y = 400 m, a 120 m gap between them at
  x = 340-460 m); touching one ends the episode as leaving the field does. Each gate is
  drawn again until its posts' line and the 150 m before its centre keep 10 m from every
  obstacle.

  ## Action space
  `Box(-15, 15, (1,), float64)`: the desired turning rate r in deg/s, held for one
  0.6 s control interval (clipped, or refused with `strict=True`).

  ## Observation space
  `Dict` of three `Box(float64, (4,))` and one `Box(float64, (7,))`: `observation`, the
  ship's state as in `hpg_mj/ShipSteering-v0`; `achieved_goal`, the ship's position and
  heading as a goal; `desired_goal`, the same of the gate: its centre and heading (its
  posts stand 50 m either side of the centre, across the heading; 25 m at `hard`);
  `ranges`, the seven rangefinders of `hpg_mj/ShipHarbour-v0` (the distance to the
  first obstacle along rays at -90, -60, ..., 90 deg from the heading, 150 m where none
  is nearer: always 150 m in the open water of `easy` and `medium`).

  | Num | Observation | Unit |
  |---|---|---|
  | `observation[0]` | `x`: the ship's position east | m |
  | `observation[1]` | `y`: the ship's position north | m |
  | `observation[2]` | `theta_deg`: heading, clockwise from north (+y), in [-180, 180) | deg |
  | `observation[3]` | `theta_dot_deg`: turning rate | deg/s |
  | `achieved_goal[0]` | the ship's `x` | m |
  | `achieved_goal[1]` | the ship's `y` | m |
  | `achieved_goal[2]` | `sin(theta)` of the ship's heading (clockwise from north: east is `sin` 1) | |
  | `achieved_goal[3]` | `cos(theta)` of the ship's heading (north is `cos` 1) | |
  | `desired_goal[0]` | the gate centre's `x` | m |
  | `desired_goal[1]` | the gate centre's `y` | m |
  | `desired_goal[2]` | `sin` of the gate's heading (the heading to pass it with, clockwise from north as `theta`) | |
  | `desired_goal[3]` | `cos` of the gate's heading | |
  | `ranges[0]` | the range along the ray 90 deg to port (left) of the heading | m |
  | `ranges[1]` | the range along the ray 60 deg to port | m |
  | `ranges[2]` | the range along the ray 30 deg to port | m |
  | `ranges[3]` | the range along the heading | m |
  | `ranges[4]` | the range along the ray 30 deg to starboard (right) | m |
  | `ranges[5]` | the range along the ray 60 deg to starboard | m |
  | `ranges[6]` | the range along the ray 90 deg to starboard | m |

  ## Rewards
  `compute_reward(achieved_goal, desired_goal, info)` (any batch shape): -1 per
  control step, +100 more when the goal is reached (99 in all), -100 more (-101) when
  the achieved position is off the field or when `info` says the step's track touched
  an obstacle (its `event` "obstacle", whatever the goals: a dictionary, or a
  sequence of them as `HerReplayBuffer` gives). Never both: a touched obstacle gives
  -101 though the goal be reached; a goal reached off the field, 99. Reached: in the gate's frame the ship is between the posts
  (|lateral| <= 50 m; 25 m at `hard`), at most one control step of sailing past the
  gate line (0 <= forward < 1.8 m) and heading within 45 degrees of the gate's heading
  (30 at `hard`). A ship
  sails 1.8 m in a control step, so every pass between the posts with the gate's
  heading is seen at the end of the step that crosses the line.

  ## Starting state
  The ship as in `hpg_mj/ShipSteering-v0` (uniform on the field, any heading and
  turning rate; at `hard` drawn again while it lies on an obstacle), then the gate
  drawn from the level's ranges (at `hard` until it stands clear of the obstacles).
  `reset(options={"state": [x, y, theta_deg, theta_dot_deg], "gate": [x, y,
  heading_deg]})` fixes either (a gate whose posts leave the field or that is not clear
  of the obstacles, or a start on one, is refused).

  ## Episode end
  Terminated when the gate is reached or the ship is off the field at the end of a
  control step, or when a segment of its track sampled every 0.2 s touches an obstacle
  (the ship a point, the obstacle's boundary included); truncated after 5,000 control
  steps (`max_steps`; the environment truncates itself, without Gymnasium's
  `TimeLimit`).

  ## Information
  `reset()` returns `{"event": None, "is_success": False}`. `step()` returns:
  - `is_success`: whether the step reached the gate (what `HerReplayBuffer` and
    Gymnasium-Robotics' goal environments read).
  - `event`: "gate", "out_of_bounds", "obstacle" or None.
  - `positions`: a `(4, 2)` array, the positions sampled every 0.2 s during the
    step (row 0 where it began).

  ## Arguments
  - `level="easy"`: "easy", "medium" or "hard".
  - `backend="mujoco"`: assets/ship.xml, its gate's geoms moved to the episode's
    gate (at `hard` assets/ship_harbour.xml: the obstacles as geoms, the ranges its
    rangefinder sensors); or "analytic" (Equation 1, the rays in closed form).
  - `render_mode=None`: or "rgb_array"; the frame shows the episode's gate.
  - `strict=False`: True refuses out-of-range turning rates instead of clipping
    them.
  - `max_steps=None`: the episode's length in control steps; None is 5,000.
  - `width=640`, `height=480`: the frame's size in pixels, at most 1280 x 960.
  - `camera=None`: "top", "local", "overview" or "chase"; None is "top".
  - `gate_reward=100.0`, `out_of_bounds_reward=-100.0`: the +100 for reaching the
    goal and the -100 for leaving the field.

  ## References
  [1] M. Ghavamzadeh and S. Mahadevan, "Hierarchical Policy Gradient
  Algorithms," Proceedings of the 20th International Conference on Machine
  Learning (ICML), 2003 (the ship steering task with its one gate).

  [2] W. T. Miller, R. S. Sutton and P. J. Werbos (eds.), *Neural Networks for
  Control*, MIT Press, 1990.

  [3] M. Andrychowicz, F. Wolski, A. Ray, J. Schneider, R. Fong, P. Welinder,
  B. McGrew, J. Tobin, P. Abbeel and W. Zaremba, "Hindsight Experience Replay,"
  Advances in Neural Information Processing Systems 30 (NIPS), 2017.

  ## Version history
  - v0: the first release (not yet tagged: until then a v0 task may still change;
    each change is dated in docs/changelog.md, and scores made before it are not
    comparable with later ones).
  - v0, 2026-12-06: `hard`'s gate is drawn among the harbour's medium obstacles;
    the observation gains `ranges` at every level.
  - v0, 2026-12-07: frames no longer draw the rangefinders' rays; a step before the
    first reset is refused, one after the episode's end warned of (refused with
    `strict=True`).
  """

  def __init__(self, level=goal_core.DEFAULT_LEVEL, backend="mujoco", render_mode=None,
               strict=False, max_steps=None, width=640, height=480, camera=None,
               gate_reward=core.GATE_REWARD, out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD):
    self.level = level
    self.level_range = goal_core.level_range(level, "ShipGoalEnv")
    super().__init__("steer", backend, render_mode, strict,
                     goal_core.episode_steps(level, max_steps), width, height, camera,
                     gate_reward, out_of_bounds_reward)
    self._name = f"ShipGoal({level}, backend={backend})"
    self.observation_space, self.action_space = spaces_of(self.rules)
    self._desired = np.zeros(4)
    self.tolerance = goal_core.level_tolerance(level)
    self._judge = goal_core.OneShip(self.rules, level)
    if goal_core.OBSTACLES[level] is not None:
      self.model_file = harbour_env.ShipHarbourEnv.model_file

  def _make_backend(self, name):
    if name == "mujoco":
      return mujoco_backend(self.level)
    return ship_env.make_backend(name)

  def _observation(self, state):
    readings = self.backend.readings() if hasattr(self.backend, "readings") else None
    return {"observation": state, "achieved_goal": goal_core.goal_of(state),
            "desired_goal": self._desired.copy(), "ranges": self._judge.ranges(state, readings)}

  def _start(self, options, *extra):
    options = dict(options or {})
    unknown = set(options) - {"state", "gate"}
    if unknown:
      raise ValueError(f"{self._name}: unknown reset options {sorted(unknown)}; allowed: "
                       "['gate', 'state']")
    if options.get("state") is not None:
      return goal_core.check_start(self.rules, options["state"], self.level,
                                   self._name), options
    return goal_core.sample_start(self.rules, self.np_random, self.level), options

  def reset(self, *, seed=None, options=None):
    gymnasium.Env.reset(self, seed=seed)    # the steering task's reset knows no gate
    state, options = self._start(options)
    if options.get("gate") is not None:
      self._desired = goal_core.check_gate(options["gate"], self._name, self.level)
    else:
      self._desired = goal_core.sample_gate(self.np_random, self.level)
    self.backend.set_state(state)
    if hasattr(self.backend, "physics"):     # the MuJoCo ship's gate geoms, where the rule's is
      self.backend.physics.place_gate(goal_core.gate_posts(self._desired, self.tolerance[0]))
    state = self._begun()
    return self._observation(state), {"event": None, "is_success": False}

  def step(self, action):
    samples, state = self._sail(action)
    event, reward, terminated, truncated, name = self._judge(samples, state, self._steps,
                                                             self._desired)
    info = {"event": name, "positions": samples, "is_success": event == core.SUCCESS}
    return self._result(self._observation(state), reward, terminated, truncated, info)

  def compute_reward(self, achieved_goal, desired_goal, info):
    """The reward of achieved and desired goals of any batch shape, aground where `info`
    says so (`aground_in`)."""
    shape = np.broadcast_shapes(np.shape(achieved_goal)[:-1], np.shape(desired_goal)[:-1])
    return goal_core.compute_reward(achieved_goal, desired_goal, self.rules.success_reward,
                                    self.rules.failure_reward, self.tolerance,
                                    aground_in(info, shape))

  def _drawn(self):
    drawn = {"gate": goal_core.gate_posts(self._desired, self.tolerance[0])}
    if goal_core.OBSTACLES[self.level] is not None:
      drawn["obstacles"] = goal_core.OBSTACLES[self.level]
    return drawn


class ShipGoalVectorEnv(vector.ShipSteeringVectorEnv):
  """A batch of `num_envs` goal-conditioned ships (`ShipGoalEnv`'s manual; the batch as
  `ShipSteeringVectorEnv`'s): `gymnasium.make_vec("hpg_mj/ShipGoal-v0", num_envs=N,
  level="hard", backend="analytic")`. Observations: a dictionary of `(N, 4)` arrays and
  the `(N, 7)` ranges; infos add `is_success`. Reset options add `gate` (one `[x, y,
  heading_deg]` for every copy reset, or one per copy, `(N, 3)`)."""

  RESET_OPTIONS = ("reset_mask", "state", "gate")

  def __init__(self, num_envs=1, level=goal_core.DEFAULT_LEVEL, backend="mujoco",
               strict=False, max_steps=None, gate_reward=core.GATE_REWARD,
               out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD,
               autoreset_mode=AutoresetMode.NEXT_STEP, render_mode=None):
    self.level = level
    self.level_range = goal_core.level_range(level, "ShipGoalVectorEnv")
    super().__init__(num_envs, "steer", backend, strict,
                     goal_core.episode_steps(level, max_steps), gate_reward,
                     out_of_bounds_reward, autoreset_mode, render_mode)
    self.who = f"ShipGoalVectorEnv({level}, backend={backend})"
    self.single_observation_space, _ = spaces_of(self.rules)
    self.observation_space = batch_space(self.single_observation_space, self.num_envs)
    self._desired = np.zeros((self.num_envs, 4))
    self._achieved = np.zeros((self.num_envs, 4))
    self._ranges = np.full((self.num_envs, goal_core.RAYS), harbour_core.MAX_RANGE_M)
    self.tolerance = goal_core.level_tolerance(level)
    self._params = goal_core.env_params(level, self.rules.success_reward,
                                        self.rules.failure_reward, self.rules.max_steps)
    self._step = None

  def _make_ships(self, backend):
    if backend == "mujoco":
      return vector._MujocoShips(self.num_envs, functools.partial(mujoco_backend, self.level))
    return super()._make_ships(backend)

  def _start(self, indices, options):
    given = self._option_rows(options, "state", 4, "state")
    gates = self._option_rows(options, "gate", 3, "gate")
    rows = np.empty((len(indices), 3))
    for k, i in enumerate(indices.tolist()):     # each copy's generator: its ship, its gate
      if given is None:
        state = goal_core.sample_start(self.rules, self._rngs[i], self.level)
      else:
        state = goal_core.check_start(self.rules, given if given.ndim == 1 else given[i],
                                      self.level, f"{self.who} copy {i}")
      self._ships.set_state(self._states, i, state)
      if gates is None:
        rows[k] = goal_core.draw_gate(self._rngs[i], self.level)
      else:
        rows[k] = gates if gates.ndim == 1 else gates[i]
        goal_core.check_gate(rows[k], f"{self.who} copy {i}", self.level)
    self._steps[indices] = 0
    goal_core.place_batch(self._states, rows, np.ascontiguousarray(indices, dtype=np.int64),
                          self._desired, self._achieved)

  def _advance(self, r, active):
    # The ships sail (ship/steer's judge, which `ShipSteeringVectorEnv` would run, is not
    # this task's), count the step, and are judged by the goal's rule: one compiled call,
    # typed once (numba's dispatcher would type its ten arguments at every step).
    self._ships.control(self._states, r, active, self._samples)
    args = (self._states, r, active, self._samples, self._steps, self._ships.integrate,
            self._desired, self._params, self._achieved,
            (self._event, self._reward, self._terminated, self._truncated))
    if self._step is None:
      self._step = goal_core.step_batch.compile(tuple(numba.typeof(a) for a in args))
    self._step(*args)
    return self._reward.copy(), self._terminated.copy(), self._truncated.copy()

  def _observations(self):
    if goal_core.OBSTACLES[self.level] is not None:
      if self._ships.integrate:
        goal_core.entries()[2](self._states, *goal_core.level_shapes(self.level), self._ranges)
      else:
        for i, ship in enumerate(self._ships.ships):
          harbour_core.seen_ranges(ship.readings(), self._ranges[i], 0)
    return {"observation": self._states.copy(), "achieved_goal": self._achieved.copy(),
            "desired_goal": self._desired.copy(), "ranges": self._ranges.copy()}

  def _observation_of(self, observations, i):
    return {key: value[i] for key, value in observations.items()}

  def _event_table(self):
    """The goal's events' names by number (an obstacle touched among them)."""
    return goal_core.EVENT_NAMES

  def _step_info(self, active):
    info = super()._step_info(active)
    info["is_success"] = active & (self._event == core.SUCCESS)
    info["_is_success"] = active.copy()
    return info

  def _reset_info(self, indices):
    info = super()._reset_info(indices)
    info["is_success"] = np.zeros(self.num_envs, dtype=np.bool_)
    info["_is_success"] = info["_event"].copy()
    return info

  def compute_reward(self, achieved_goal, desired_goal, info):
    """`ShipGoalEnv.compute_reward`."""
    shape = np.broadcast_shapes(np.shape(achieved_goal)[:-1], np.shape(desired_goal)[:-1])
    return goal_core.compute_reward(achieved_goal, desired_goal, self.rules.success_reward,
                                    self.rules.failure_reward, self.tolerance,
                                    aground_in(info, shape))
