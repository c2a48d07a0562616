"""Ship steering domain (SPEC sections 1-3), in the style of dm_control's suite.

Tasks:
  steer:    the full task: sail through the gate (350, 400)-(450, 400) from a
            random start in the 1 km field (SPEC section 2).
  diagonal: the low-level subtask in its 150 m local frame, from (40, 40) to
            within 10 m of (140, 140), with its internal reward (SPEC section 3).
  straight: likewise from (40, 75) to (140, 75).
  patrol:   the continuing task (SPEC section 8): the field and gate of steer,
            but the ship sails on after each pass (+100 each, either way);
            leaving the field costs the penalty and restarts it at a fresh
            uniform start. Only the clock ends it: one hour (6,000 control
            steps), then a LAST step with discount 1 (a truncation).

One control step is 0.6 s: the desired turning rate r (deg/s) is held for three
0.2 s sampling intervals, and the rules look at each sampled position.

Creating a `Physics` stops MuJoCo's built-in profiler for the whole process (its
`mjData.timer` stays 0) unless the user installed a clock (`stop_profiler_clock`).
The model and its readings are `worlds.ship_model`'s; this module adds the tasks and
the drawing through the render worker.
"""
import collections

import numpy as np

from hpg_mj import _headless
from hpg_mj import _validation
from hpg_mj import _render_worker as worker
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_model
from hpg_mj.worlds.ship_task import ShipRules

with _headless.simulation_imports():   # no GL in the simulating process (SPEC section 9)
  from dm_control.rl import control
  from dm_control.suite import base
  from dm_control.utils import containers
  from dm_env import specs

SUITE = containers.TaggedTasks()


get_model_and_assets = ship_model.get_model_and_assets
set_orthographic_extents = ship_model.set_orthographic_extents
stop_profiler_clock = ship_model.stop_profiler_clock


class Physics(ship_model.ShipPhysics):
  """The MuJoCo ship (`ship_model.ShipPhysics`), drawn by the render worker."""

  # The model of assets/ the render worker draws (a world with markers of its own names
  # its file; the ship in a current draws as the steering ship).
  model_file = "ship.xml"

  def render(self, height=240, width=320, camera_id=-1, **options):
    """dm_control's `render`, drawn in a worker process (SPEC section 9)."""
    return worker.render_physics(self, self.model_file, height, width, camera_id, **options)

  def free(self):
    worker.close_physics_worker(self)
    super().free()


class ShipTask(base.Task):
  """A ship task on the MuJoCo ship (see `ShipRules` for the rules)."""

  def __init__(self, kind, random=None, initial_state=None, strict=False, max_steps=None,
               **rewards):
    """Args:
      kind: "steer", "diagonal", "straight" or "patrol".
      random: seed, np.random.RandomState or None.
      initial_state: optional fixed start [x, y, theta_deg, theta_dot_deg].
      strict: if True, a turning rate outside [-15, 15] deg/s is an error; by
        default it is clipped. NaN and infinity are always errors.
      max_steps: control steps before the episode ends (truncated for steer
        and patrol, failed for the subtasks); SPEC defaults 5,000, 300 and,
        for patrol, 6,000 (one hour).
    """
    self.rules = ShipRules(kind, max_steps, **rewards)
    self.name = f"ship-{kind}"
    self.strict = strict
    self.initial_state = initial_state
    self._steps = 0
    self._outcome = (0.0, False, False, None)
    self._state_after_step = None
    super().__init__(random=random)

  @property
  def initial_state(self):
    """A fixed start [x, y, theta_deg, theta_dot_deg] for the next episodes, or None."""
    return self._initial_state

  @initial_state.setter
  def initial_state(self, state):
    self._initial_state = None if state is None else self.rules.check_state(state, self.name)

  def initialize_episode(self, physics):
    state = (self._initial_state if self._initial_state is not None
             else self.rules.sample_start(self.random))
    physics.set_ship_state(state)
    physics.place_target(self.rules.goal)
    physics._samples = None
    self._steps = 0
    self._outcome = (0.0, False, False, None)
    self._state_after_step = None
    # Not `base.Task.initialize_episode`: all it does is call `after_step`, which here
    # counts a control step and judges it (a reset counted as one ended every episode
    # a step before its `max_steps`).

  def action_spec(self, physics):
    return specs.BoundedArray((1,), np.float64, -core.MAX_TURN_RATE, core.MAX_TURN_RATE,
                              name="turning_rate_deg")

  def before_step(self, action, physics):
    r = _validation.bounded_scalar_action(action, -core.MAX_TURN_RATE, core.MAX_TURN_RATE,
                                          strict=self.strict, task=self.name,
                                          name="turning rate r (deg/s)")
    physics.set_turn_command(r)

  def after_step(self, physics):
    self._steps += 1
    state = physics.stepped_state      # `ship_state()` after the step just taken
    self._outcome = self.rules.judge(physics.sampled_positions(), state, self._steps)
    if self.rules.restarts(self._outcome[3]):   # SPEC section 8: the process goes on
      physics.set_ship_state(self.rules.sample_start(self.random))
      state = physics.ship_state()
    # `control.Environment.step` asks for the observation next (after the reward): the
    # state is handed to that one call, not read again.
    self._state_after_step = state

  def get_observation(self, physics):
    state, self._state_after_step = self._state_after_step, None
    if state is None:
      state = physics.ship_state()
    obs = collections.OrderedDict()
    obs["position"] = state[:2]
    obs["heading_deg"] = state[2:3]
    obs["turning_rate_deg"] = state[3:4]
    return obs

  def get_reward(self, physics):
    return self._outcome[0]

  def get_termination(self, physics):
    _, terminated, truncated, _ = self._outcome
    if terminated:
      return 0.0
    if truncated:
      return 1.0
    return None

  @property
  def last_event(self):
    """What ended the last step: "gate", "goal", "out_of_bounds", "timeout" (a
    subtask's 300 control steps without success) or None (the step ended nothing, or
    the episode's step limit truncated it: `get_termination`'s discount tells)."""
    return self._outcome[3]


def environment(physics, task, environment_kwargs=None):
  """`control.Environment` of a ship `task` on `physics`: a control step of 0.6 s, and
  the episode's length the task's own (truncation and failure differ by task)."""
  environment_kwargs = dict(environment_kwargs or {})
  environment_kwargs.setdefault("time_limit", float("inf"))
  environment_kwargs.setdefault("control_timestep", core.CONTROL_INTERVAL)
  return control.Environment(physics, task, **environment_kwargs)


def _environment(kind, random, initial_state, strict, max_steps, environment_kwargs,
                 **rewards):
  physics = Physics.from_xml_string(*get_model_and_assets())
  task = ShipTask(kind, random=random, initial_state=initial_state, strict=strict,
                  max_steps=max_steps, **rewards)
  return environment(physics, task, environment_kwargs)


@SUITE.add("benchmarking")
def steer(random=None, initial_state=None, strict=False, max_steps=None,
          environment_kwargs=None, gate_reward=core.GATE_REWARD,
          out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD):
  """The full ship steering task (SPEC section 2); the rewards at the gate and off the
  field are those of SPEC section 2 unless given (a task file's [environment] does)."""
  return _environment("steer", random, initial_state, strict, max_steps, environment_kwargs,
                      gate_reward=gate_reward, out_of_bounds_reward=out_of_bounds_reward)


@SUITE.add("benchmarking", "subtask")
def diagonal(random=None, initial_state=None, strict=False, max_steps=None,
             environment_kwargs=None):
  """The diagonal low-level subtask in its local frame (SPEC section 3)."""
  return _environment("diagonal", random, initial_state, strict, max_steps, environment_kwargs)


@SUITE.add("benchmarking", "subtask")
def straight(random=None, initial_state=None, strict=False, max_steps=None,
             environment_kwargs=None):
  """The straight low-level subtask in its local frame (SPEC section 3)."""
  return _environment("straight", random, initial_state, strict, max_steps, environment_kwargs)


@SUITE.add("benchmarking", "continuing")
def patrol(random=None, initial_state=None, strict=False, max_steps=None,
           environment_kwargs=None, gate_reward=core.GATE_REWARD,
           out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD):
  """The continuing ship task: pass the gate as often as possible (SPEC section 8)."""
  return _environment("patrol", random, initial_state, strict, max_steps, environment_kwargs,
                      gate_reward=gate_reward, out_of_bounds_reward=out_of_bounds_reward)
