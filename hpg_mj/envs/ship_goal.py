"""The goal-conditioned ship as a Gymnasium environment with a dictionary observation
(`observation`, `achieved_goal`, `desired_goal`) and `compute_reward`, as
Stable-Baselines3's `HerReplayBuffer` expects, and its native batch."""
import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from hpg_mj.envs import ship as ship_env
from hpg_mj.envs import vector
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_goal_core as goal_core


def spaces_of(rules):
  """(observation space, action space): the steering ship's state under `observation`,
  and goals [x, y, sin(heading), cos(heading)] on the field (with one control step's
  margin) under `achieved_goal` and `desired_goal`."""
  state, action = ship_env.spaces_of(rules)
  goal = spaces.Box(low=np.append(state.low[:2], [-1.0, -1.0]),
                    high=np.append(state.high[:2], [1.0, 1.0]), dtype=np.float64)
  return spaces.Dict({"observation": state, "achieved_goal": goal,
                      "desired_goal": goal}), action


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
  | hard | uniform on [100, 900] m | any | 50 m, 30 deg |

  ## Action space
  `Box(-15, 15, (1,), float64)`: the desired turning rate r in deg/s, held for one
  0.6 s control interval (clipped, or refused with `strict=True`).

  ## Observation space
  `Dict` of three `Box(float64, (4,))`: `observation`, the ship's state as in
  `hpg_mj/ShipSteering-v0`; `achieved_goal`, the ship's position and heading as a
  goal; `desired_goal`, the same of the gate: its centre and heading (its posts
  stand 50 m either side of the centre, across the heading; 25 m at `hard`).

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

  ## Rewards
  `compute_reward(achieved_goal, desired_goal, info)` (any batch shape): -1 per
  control step, +100 more when the goal is reached, -100 more when the achieved
  position is off the field. Reached: in the gate's frame the ship is between the posts
  (|lateral| <= 50 m; 25 m at `hard`), at most one control step of sailing past the
  gate line (0 <= forward < 1.8 m) and heading within 45 degrees of the gate's heading
  (30 at `hard`). A ship
  sails 1.8 m in a control step, so every pass between the posts with the gate's
  heading is seen at the end of the step that crosses the line.

  ## Starting state
  The ship as in `hpg_mj/ShipSteering-v0` (uniform on the field, any heading and
  turning rate), then the gate drawn from the level's ranges.
  `reset(options={"state": [x, y, theta_deg, theta_dot_deg], "gate": [x, y,
  heading_deg]})` fixes either (a gate whose posts leave the field is refused).

  ## Episode end
  Terminated when the gate is reached or the ship is off the field at the end of a
  control step; truncated after 5,000 control steps (`max_steps`; the environment
  truncates itself, without Gymnasium's `TimeLimit`).

  ## Information
  `reset()` returns `{"event": None, "is_success": False}`. `step()` returns:
  - `is_success`: whether the step reached the gate (what `HerReplayBuffer` and
    Gymnasium-Robotics' goal environments read).
  - `event`: "gate", "out_of_bounds" or None.
  - `positions`: a `(4, 2)` array, the positions sampled every 0.2 s during the
    step (row 0 where it began).

  ## Arguments
  - `level="easy"`: "easy", "medium" or "hard".
  - `backend="mujoco"`: assets/ship.xml, its gate's geoms moved to the episode's
    gate; or "analytic" (Equation 1).
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
  - v0: initial release.
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
    self._judge = goal_core.OneShip(self.rules, self.tolerance)

  def _observation(self, state):
    return {"observation": state, "achieved_goal": goal_core.goal_of(state),
            "desired_goal": self._desired.copy()}

  def reset(self, *, seed=None, options=None):
    gymnasium.Env.reset(self, seed=seed)    # the steering task's reset knows no gate
    state, options = self._start(options, "gate")
    if options.get("gate") is not None:
      self._desired = goal_core.check_gate(options["gate"], self._name)
    else:
      self._desired = goal_core.sample_gate(self.np_random, self.level_range)
    self.backend.set_state(state)
    if hasattr(self.backend, "physics"):     # the MuJoCo ship's gate geoms, where the rule's is
      self.backend.physics.place_gate(goal_core.gate_posts(self._desired, self.tolerance[0]))
    self._steps = 0
    state = self.backend.state()
    self._trail = [state[:2].copy()]
    return self._observation(state), {"event": None, "is_success": False}

  def step(self, action):
    samples, state = self._sail(action)
    event, reward, terminated, truncated, name = self._judge(state, self._steps, self._desired)
    info = {"event": name, "positions": samples, "is_success": event == core.SUCCESS}
    return self._observation(state), reward, terminated, truncated, info

  def compute_reward(self, achieved_goal, desired_goal, info):
    """The reward of achieved and desired goals of any batch shape (`info` unused)."""
    return goal_core.compute_reward(achieved_goal, desired_goal, self.rules.success_reward,
                                    self.rules.failure_reward, self.tolerance)

  def _drawn(self):
    return {"gate": goal_core.gate_posts(self._desired, self.tolerance[0])}


class ShipGoalVectorEnv(vector.ShipSteeringVectorEnv):
  """A batch of `num_envs` goal-conditioned ships (`ShipGoalEnv`'s manual; the batch as
  `ShipSteeringVectorEnv`'s): `gymnasium.make_vec("hpg_mj/ShipGoal-v0", num_envs=N,
  level="hard", backend="analytic")`. Observations: a dictionary of `(N, 4)` arrays;
  infos add `is_success`. Reset options add `gate` (one `[x, y, heading_deg]` for
  every copy reset, or one per copy, `(N, 3)`)."""

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
    self.tolerance = goal_core.level_tolerance(level)

  def _start(self, indices, options):
    super()._start(indices, options)
    given = self._option_rows(options, "gate", 3, "gate")
    for i in indices.tolist():
      if given is None:
        self._desired[i] = goal_core.sample_gate(self._rngs[i], self.level_range)
      else:
        self._desired[i] = goal_core.check_gate(given if given.ndim == 1 else given[i],
                                                f"{self.who} copy {i}")
      self._achieved[i] = goal_core.goal_of(self._states[i])

  def _advance(self, r, active):
    super()._advance(r, active)     # sails the ships (and judges them by ship/steer's gate)
    goal_core.judge_batch(self._states, active, self._steps, self._desired,
                          self.rules.max_steps, self.rules.success_reward,
                          self.rules.failure_reward, self.tolerance, self._achieved,
                          (self._event, self._reward, self._terminated, self._truncated))
    return self._reward.copy(), self._terminated.copy(), self._truncated.copy()

  def _observations(self):
    return {"observation": self._states.copy(), "achieved_goal": self._achieved.copy(),
            "desired_goal": self._desired.copy()}

  def _observation_of(self, observations, i):
    return {key: value[i] for key, value in observations.items()}

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
    return goal_core.compute_reward(achieved_goal, desired_goal, self.rules.success_reward,
                                    self.rules.failure_reward, self.tolerance)
