"""Ship steering as a Gymnasium environment, on the MuJoCo or the analytic ship."""
import gymnasium
import numpy as np
from gymnasium import spaces

from hpg_mj import _assets
from hpg_mj import envs
from hpg_mj import _validation
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_task

BACKENDS = ("mujoco", "analytic")


class AnalyticBackend:
  """Equation 1 exactly as written (explicit Euler, 0.2 s): the paper's ship."""

  name = "analytic"

  def __init__(self):
    self._state = np.zeros(4)

  def set_state(self, state):
    """Puts the ship at `state` [x, y, theta_deg, theta_dot_deg]."""
    self._state[:] = state

  def state(self):
    """The ship's state [x, y, theta_deg, theta_dot_deg] (a copy)."""
    return self._state.copy()

  def control(self, r_deg):
    """Sails one 0.6 s control interval; returns (the sampled positions, the state
    at its end), new arrays, as the MuJoCo ship's."""
    samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
    # Every argument given: numba dispatches a call that omits defaulted
    # arguments through its slow Python path (~30 us, 200 times Equation 1).
    core.euler_control(self._state, r_deg, samples, core.SPEED, core.TIME_CONSTANT,
                       core.SAMPLING_INTERVAL)
    return samples, self._state.copy()


class MujocoBackend:
  """The MJCF ship of assets/ship.xml (the physics behind the dm_control tasks)."""

  name = "mujoco"

  def __init__(self):
    from hpg_mj.worlds import ship   # MuJoCo and dm_control only for this backend
    self.physics = ship.Physics.from_xml_string(*ship.get_model_and_assets())
    self._nstep = core.SAMPLES_PER_CONTROL * self.physics._substeps_per_sample()

  def set_state(self, state):
    """Puts the ship at `state` [x, y, theta_deg, theta_dot_deg]."""
    self.physics.set_ship_state(state)

  def state(self):
    """The ship's state [x, y, theta_deg, theta_dot_deg]."""
    return self.physics.ship_state()

  def control(self, r_deg):
    """One control step at turning command `r_deg` (deg/s): (the positions sampled,
    the state after)."""
    physics = self.physics
    physics.set_turn_command(r_deg)
    physics.step(self._nstep)
    # Both read in the step, new arrays each step: the caller's to keep.
    return physics.sampled_positions(), physics.stepped_state


def spaces_of(rules):
  """(observation space, action space) of one ship on `rules`' task: the field (or
  local frame) with the margin one control step can overshoot it by, and r."""
  margin = core.SPEED * core.CONTROL_INTERVAL
  size = rules.size
  observation = spaces.Box(
      low=np.array([-margin, -margin, -180.0, -core.MAX_TURN_RATE]),
      high=np.array([size + margin, size + margin, 180.0, core.MAX_TURN_RATE]),
      dtype=np.float64)
  action = spaces.Box(-core.MAX_TURN_RATE, core.MAX_TURN_RATE, (1,), np.float64)
  return observation, action


def make_backend(name):
  """The ship backend `name`: "analytic" or "mujoco"."""
  if name == "mujoco":
    return MujocoBackend()
  if name == "analytic":
    return AnalyticBackend()
  raise ValueError(f"unknown ship backend {name!r}; valid backends: {list(BACKENDS)}")


class ShipSteeringEnv(gymnasium.Env):
  """Ship steering (Ghavamzadeh & Mahadevan 2003 [1]; Miller et al. 1990 [2]).

  ## Description
  A ship sails at a constant 3 m/s on a 1 km x 1 km sea and must be steered
  through a 100 m gate between (350, 400) and (450, 400). Its turning rate
  follows the commanded rate with a 5 s lag (the paper's Equation 1), so every
  decision acts slowly. `task="diagonal"` and `task="straight"` are the two
  low-level subtasks of the paper's hierarchy, in their own 150 m frame.
  `task="patrol"` (`hpg_mj/ShipPatrol-v0`) is the continuing task of SPEC
  section 8, the paper's section 6 "continuing root": the same field and gate,
  but the ship sails on after each pass and may pass again; its measure is
  gate passes per hour of sailing (6,000 control steps).

  ## Action space
  `Box(-15, 15, (1,), float64)`: the desired turning rate r in deg/s, held for
  one 0.6 s control interval (three 0.2 s sampling intervals). A rate outside
  [-15, 15] is clipped (an error with `strict=True`); NaN, infinity or a wrong
  shape raise `ValueError`.

  ## Observation space
  `Box(float64, (4,))`, the ship's state; for the subtasks in the local 150 m
  frame. After the ship leaves the field the last position may lie up to 1.8 m
  (one control interval of sailing) outside it, which the bounds allow.

  | Num | Observation | Unit |
  |---|---|---|
  | 0 | `x`: position east | m |
  | 1 | `y`: position north | m |
  | 2 | `theta_deg`: heading, clockwise from north (+y), in [-180, 180) | deg |
  | 3 | `theta_dot_deg`: turning rate | deg/s |

  ## Rewards
  - `steer`: -1 per control step, +100 more for passing the gate (in either
    direction, between the posts), -100 more for leaving the field.
  - `patrol`: as `steer`, for every pass of the gate and every time the ship
    leaves the field.
  - `diagonal`, `straight`: -1 per control step plus the shaping reward
    `exp(-(theta - theta_hat)^2 / 30^2) - 1` (theta_hat the bearing to the
    local goal), +100 more on reaching the goal, -100 more on failing.

  ## Starting state
  - `steer`, `patrol`: x, y uniform on [0, 1000] m, heading uniform on
    [-180, 180) deg, turning rate uniform on [-15, 15] deg/s.
  - `diagonal`: at (40, 40) with random heading and turning rate; goal
    (140, 140). `straight`: at (40, 75); goal (140, 75).
  `reset(options={"state": [x, y, theta_deg, theta_dot_deg]})` starts from an
  exact state (refused if off the field or the turning rate is out of range).

  ## Episode end
  - Terminated: `steer`: the gate is passed or the field is left.
    Subtasks: within 10 m of the goal, leaving [0, 150]^2, or 300 control
    steps without success (a failure). `info["event"]` says which.
    `patrol` never terminates: after leaving the field (`info["event"] ==
    "out_of_bounds"`, the penalty paid) the observation is a fresh uniform
    start drawn from the environment's generator, and the process goes on;
    `info["state_before_restart"]` is where the ship was when it left.
  - Truncated: `steer` after 5,000 control steps (3,000 s); `patrol` after
    6,000 (one hour). The environment truncates itself (`max_steps`); the ids
    are registered without Gymnasium's `TimeLimit`.

  ## Information
  `reset()` returns `{"event": None}`. `step()` returns:
  - `event`: what happened in the step: "gate" (`steer`, `patrol`: the gate
    passed), "goal" (a subtask's goal reached), "out_of_bounds" (the field
    left), "timeout" (a subtask's 300 control steps without success) or None
    (nothing ended, or the step limit truncated the episode: `truncated` says).
  - `positions`: a `(4, 2)` array, the positions sampled every 0.2 s during the
    step (row 0 where it began), on which the gate and the bounds are checked.
  - `state_before_restart` (`patrol`, after leaving the field): the state where
    the ship left, before the fresh start that the observation shows.

  ## Arguments
  - `task="steer"`: "steer", "diagonal", "straight" or "patrol" (each id sets it).
  - `backend="mujoco"`: the MJCF ship of assets/ship.xml, or "analytic"
    (Equation 1 exactly, the paper's discretisation).
  - `render_mode=None`: or "rgb_array", a top-down orthographic view with the
    ship's wake.
  - `strict=False`: True refuses out-of-range turning rates instead of clipping
    them.
  - `max_steps=None`: the episode's length in control steps; None is the task's
    own (5,000 for `steer`, 6,000 for `patrol`, 300 for the subtasks).
  - `width=640`, `height=480`: the frame's size in pixels, at most 1280 x 960
    (the model's offscreen buffer).
  - `camera=None`: "top", "local", "overview" or "chase"; None is "top" for
    `steer` and `patrol`, "local" for the subtasks.
  - `gate_reward=100.0`, `out_of_bounds_reward=-100.0`: the +100 and -100 of
    SPEC section 2 (for the subtasks: reaching and failing the local goal).
  - `level=None`: the task ladder's argument (`hpg_mj/ShipHarbour-v0`...); these
    tasks have no levels, and any level is refused, naming the ids that have.

  ## References
  [1] M. Ghavamzadeh and S. Mahadevan, "Hierarchical Policy Gradient
  Algorithms," Proceedings of the 20th International Conference on Machine
  Learning (ICML), 2003.

  [2] W. T. Miller, R. S. Sutton and P. J. Werbos (eds.), *Neural Networks for
  Control*, MIT Press, 1990.

  ## Version history
  - v0: initial release (SPEC sections 1-3); `patrol` (SPEC section 8).
  - v0, 2026-12-07: a step before the first reset is refused, one after the episode's
    end warned of (refused with `strict=True`).
  """

  metadata = {"render_modes": ["rgb_array"], "render_fps": 10}
  model_file = "ship.xml"      # the MJCF model its frames are drawn from (assets/)

  def __init__(self, task="steer", backend="mujoco", render_mode=None, strict=False,
               max_steps=None, width=640, height=480, camera=None,
               gate_reward=core.GATE_REWARD, out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD,
               level=None):
    envs.refuse_level(f"ShipSteeringEnv(task={task!r})", level)
    self.rules = ship_task.ShipRules(task, max_steps, gate_reward, out_of_bounds_reward)
    if render_mode not in (None, "rgb_array"):
      raise ValueError(f"unknown render_mode {render_mode!r}; valid: None, 'rgb_array'")
    self.backend = self._make_backend(backend)
    self.task = task
    self.strict = bool(strict)
    self.render_mode = render_mode
    self._name = f"ShipSteering({task}, backend={backend})"
    self.observation_space, self.action_space = spaces_of(self.rules)
    if render_mode is not None:      # refused here, not by the render worker later
      _assets.check_frame_size(self.model_file, width, height, self._name)
    self._width, self._height = int(width), int(height)
    self._camera = camera or ("top" if task in ("steer", "patrol") else "local")
    self._renderer = None
    self._trail = []
    self._steps = 0
    self._episode = None       # None before the first reset, then "on", "ended", "warned"

  def _make_backend(self, name):
    """The ship this environment sails (a task on other water brings its own)."""
    return make_backend(name)

  def _start(self, options, *extra):
    """The reset's start (`options["state"]`, checked, or drawn) and its options,
    refused in one line when it names one but "state" and `extra` (a task's own)."""
    options = dict(options or {})
    unknown = set(options) - {"state", *extra}
    if unknown:
      raise ValueError(f"{self._name}: unknown reset options {sorted(unknown)}; allowed: "
                       f"{sorted({'state', *extra})}")
    if options.get("state") is not None:
      return self.rules.check_state(options["state"], self._name), options
    return self.rules.sample_start(self.np_random), options

  def reset(self, *, seed=None, options=None):
    super().reset(seed=seed)
    state, _ = self._start(options)
    self.backend.set_state(state)
    obs = self._begun()
    return obs, {"event": None}

  def _begun(self):
    """An episode begun from the backend's state (set): its steps counted from 0, its
    wake from the ship; returns the state."""
    self._steps = 0
    self._episode = "on"
    state = self.backend.state()
    self._trail = [state[:2].copy()]
    return state

  def _sail(self, action):
    """One control step of the ship under `action` (checked, clipped as `strict` says):
    the step counted and, when rendering, the wake drawn on. Returns (the positions
    sampled in it, the state after it). Before the first reset it is refused; after the
    episode ended, refused with `strict`, else warned of once (Gymnasium's CartPole's
    words) and sailed on."""
    if self._episode is None:
      raise RuntimeError(f"{self._name}: call reset() before step()")
    if self._episode != "on":
      if self.strict:
        raise RuntimeError(f"{self._name}: the episode has ended; call reset() before step() "
                           "(strict=False sails on, with a warning)")
      if self._episode == "ended":
        gymnasium.logger.warn(
            f"{self._name}: step() called after the episode ended (terminated or "
            "truncated); call reset() first: any further steps are undefined behavior")
        self._episode = "warned"
    r = _validation.bounded_scalar_action(action, -core.MAX_TURN_RATE, core.MAX_TURN_RATE,
                                          strict=self.strict, task=self._name,
                                          name="turning rate r (deg/s)")
    samples, state = self.backend.control(r)
    self._steps += 1
    if self.render_mode is not None:
      self._trail.extend(samples[1:].copy())
    return samples, state

  def step(self, action):
    samples, obs = self._sail(action)
    reward, terminated, truncated, event = self.rules.judge(samples, obs, self._steps)
    info = {"event": event, "positions": samples}   # each backend's new array
    if event is not None and self.rules.restarts(event):   # SPEC section 8: a fresh start
      info["state_before_restart"] = obs   # where it left (a learner's last step sees it)
      self.backend.set_state(self.rules.sample_start(self.np_random))
      obs = self.backend.state()
      self._trail = [obs[:2].copy()]   # the wake starts again there
    return self._result(obs, float(reward), terminated, truncated, info)

  def _result(self, obs, reward, terminated, truncated, info):
    """A step's five values, the episode marked ended where they end it."""
    if (terminated or truncated) and self._episode == "on":
      self._episode = "ended"
    return obs, reward, terminated, truncated, info

  def render(self):
    if self.render_mode is None:
      gymnasium.logger.warn("render() called without a render_mode; pass render_mode='rgb_array'")
      return None
    from hpg_mj.render import scenes  # drawn in a worker process (SPEC section 9)
    if self._renderer is None:
      self._renderer = scenes.ShipScene(self._width, self._height, self.model_file)
    return self._renderer.render(self.backend.state(), np.asarray(self._trail),
                                 camera=self._camera, **self._drawn())

  def _drawn(self):
    """What the frame shows beside the ship: a subtask's goal disc (a task with a gate of
    its own draws it)."""
    return {"target": self.rules.goal}

  def close(self):
    if self._renderer is not None:
      self._renderer.close()
      self._renderer = None
