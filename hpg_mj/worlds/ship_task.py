"""The start, reward and ending of each ship task (SPEC sections 2-3), shared by
the analytic and the MuJoCo backend; free of MuJoCo, so that the analytic ship
imports neither mujoco nor dm_control (SPEC section 9)."""
import functools

import numba
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
    # `task_outcome`'s arguments after the step's own, its code (`judge`), and its event
    # codes by name.
    self._task = (self.goal is None, np.zeros(2) if self.goal is None else self.goal,
                  self.size, self.max_steps, self.success_reward, self.failure_reward)
    self._outcome = None
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
    """`state` as a float64 [x, y, theta_deg, theta_dot_deg] on its field, or
    raises naming `task_name` (`ship_core.check_state`)."""
    return core.check_state(state, task_name, 0.0, self.size)

  def evaluate(self, samples, end_state, steps):
    """(reward, terminated, truncated, event name) after a control step.

    `samples` are the positions sampled during the step, `end_state` the state
    at its end, `steps` the control steps taken so far, this one included.
    """
    samples = np.ascontiguousarray(samples, dtype=np.float64)
    end_state = np.ascontiguousarray(end_state, dtype=np.float64)
    if samples.ndim != 2 or samples.shape[1] != 2 or end_state.shape != (4,):
      raise ValueError("ShipRules.evaluate: samples must be rows of (x, y) and end_state "
                       f"[x, y, theta_deg, theta_dot_deg], got shapes {samples.shape} and "
                       f"{end_state.shape}")
    return self.judge(samples, end_state, int(steps))

  def judge(self, samples, end_state, steps):
    """`evaluate` of a backend's own arrays, float64 in C order (each backend's new
    arrays of a step), and an int: `task_outcome`'s compiled code for these kinds is
    called directly (numba's dispatcher would type all nine arguments again at each
    step, about half of the call)."""
    outcome = self._outcome
    if outcome is None:
      outcome = self._outcome = _task_outcome()
    event, reward, terminated, truncated = outcome(samples, end_state, steps, *self._task)
    if self.continuing:        # SPEC section 8: nothing ends the process but the clock
      terminated, truncated = False, steps >= self.max_steps
    return reward, terminated, truncated, self.event_names[event]


@functools.cache
def _task_outcome():
  """`core.task_outcome`'s entry point for a backend's arrays (`ShipRules.judge`),
  compiled or loaded from numba's cache at the first step of the process."""
  f64 = numba.float64
  return core.task_outcome.compile(
      (f64[:, ::1], f64[::1], numba.int64, numba.boolean, f64[::1], f64, numba.int64, f64, f64))
