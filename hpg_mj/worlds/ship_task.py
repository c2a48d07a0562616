"""The start, reward and ending of each ship task (SPEC sections 2-3), shared by
the analytic and the MuJoCo backend; free of MuJoCo, so that the analytic ship
imports neither mujoco nor dm_control (SPEC section 9)."""
import numpy as np

from hpg_mj.worlds import ship_core as core


class ShipRules:
  """The start, reward and ending of one ship task, shared by every backend.

  `kind` is "steer" (SPEC section 2), "diagonal" or "straight" (SPEC section 3,
  the local frame), or "patrol", the continuing task of SPEC section 8: the
  gate and field of "steer", but nothing terminates it: each pass of the gate
  gives its reward and the ship sails on, and leaving the field gives the
  penalty and restarts the ship at a fresh uniform start (`restarts`: the
  environment then calls `sample_start`); it is truncated after `max_steps`
  (one hour of sailing by default). The Gymnasium environment and the
  dm_control tasks both call these, so the rules live in one place.
  """

  KINDS = ("steer", "diagonal", "straight", "patrol")

  def __init__(self, kind, max_steps=None, gate_reward=core.GATE_REWARD,
               out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD):
    if kind not in self.KINDS:
      raise ValueError(f"unknown ship task {kind!r}; valid tasks: {list(self.KINDS)}")
    self.kind = kind
    self.continuing = kind == "patrol"
    if kind in ("steer", "patrol"):
      self.size = core.FIELD_SIZE
      self.start = None
      self.goal = None
      default_steps = core.PATROL_MAX_STEPS if self.continuing else core.STEER_MAX_STEPS
    else:
      self.size = core.LOCAL_SIZE
      diagonal = kind == "diagonal"
      self.start = (core.DIAGONAL_START if diagonal else core.STRAIGHT_START).copy()
      self.goal = (core.DIAGONAL_GOAL if diagonal else core.STRAIGHT_GOAL).copy()
      default_steps = core.SUBTASK_MAX_STEPS
    self.max_steps = default_steps if max_steps is None else int(max_steps)
    # SPEC section 2's +100 / -100 (and the subtasks' local +100 / -100).
    self.success_reward = float(gate_reward)
    self.failure_reward = float(out_of_bounds_reward)
    # `task_outcome`'s arguments, and its event codes by name.
    self._goal = np.zeros(2) if self.goal is None else self.goal
    success = "gate" if self.goal is None else "goal"
    self.event_names = {core.NO_EVENT: None, core.SUCCESS: success,
                        core.FAILURE: "out_of_bounds", core.TIMEOUT: "timeout"}
    if self.max_steps < 1:
      raise ValueError(f"max_steps must be a positive number of control steps, got {max_steps!r}")

  def restarts(self, event_name):
    """Whether the ship is put at a fresh start after a step that ended by
    `event_name` (the continuing task, after leaving the field)."""
    return self.continuing and event_name == "out_of_bounds"

  def sample_start(self, random):
    """A random start; `random` is a np.random.RandomState or Generator."""
    theta = random.uniform(-180.0, 180.0)
    theta_dot = random.uniform(-core.MAX_TURN_RATE, core.MAX_TURN_RATE)
    if self.start is None:
      x, y = random.uniform(0.0, self.size), random.uniform(0.0, self.size)
    else:
      x, y = self.start
    return np.array([x, y, core.wrap_deg(theta), theta_dot])

  def check_state(self, state, task_name):
    return core.check_state(state, task_name, 0.0, self.size)

  def evaluate(self, samples, end_state, steps):
    """(reward, terminated, truncated, event name) after a control step.

    `samples` are the positions sampled during the step, `end_state` the state
    at its end, `steps` the control steps taken so far, this one included.
    """
    event, reward, terminated, truncated = core.task_outcome(
        samples, end_state, steps, self.goal is None, self._goal, self.size, self.max_steps,
        self.success_reward, self.failure_reward)
    if self.continuing:        # SPEC section 8: nothing ends the process but the clock
      terminated, truncated = False, steps >= self.max_steps
    return reward, terminated, truncated, self.event_names[event]
