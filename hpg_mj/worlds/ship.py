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
"""
import collections
import math

import numba
import numpy as np

from hpg_mj import _assets
from hpg_mj import _headless
from hpg_mj import _validation
from hpg_mj import _render_worker as worker
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds.ship_task import ShipRules

with _headless.simulation_imports():   # no GL in the simulating process (SPEC section 9)
  import mujoco as mj
  from dm_control import mujoco
  from dm_control.rl import control
  from dm_control.suite import base
  from dm_control.utils import containers
  from dm_env import specs

SUITE = containers.TaggedTasks()


def get_model_and_assets():
  """Returns the MJCF model of the ship and the (empty) assets dict."""
  return _assets.read_model("ship.xml"), {}


def set_orthographic_extents(model):
  """Applies the custom numerics `ortho_extent_<camera>` to the cameras' fovy.

  MuJoCo's compiler refuses a fovy above 180, also for an orthographic camera,
  whose fovy is its vertical extent in metres; a 1 km field needs more.
  """
  for i in range(model.nnumeric):
    name = mj.mj_id2name(model, mj.mjtObj.mjOBJ_NUMERIC, i)
    if name and name.startswith("ortho_extent_"):
      camera = mj.mj_name2id(model, mj.mjtObj.mjOBJ_CAMERA, name[len("ortho_extent_"):])
      if camera < 0:
        raise ValueError(f"custom numeric {name!r} names no camera in the model")
      model.cam_fovy[camera] = model.numeric_data[model.numeric_adr[i]]


@numba.cfunc(numba.float64(), cache=True)
def _stopped_clock():
  """A clock that always reads 0: as MuJoCo's `mjcb_time`, every profiler timing is 0."""
  return 0.0


def stop_profiler_clock():
  """Stops MuJoCo's built-in profiler (`mjData.timer` then stays at 0) unless the user
  installed a clock of their own with `mujoco.set_mjcb_time`.

  "Installing [mjcb_time] enables the built-in profiler, and keeps timing statistics in
  mjData.timer" (MuJoCo API reference, mjcb_time). The C library's default is none; the
  Python bindings install a steady clock with every MjData (mujoco issue #2354), and
  `set_mjcb_time(None)` brings that clock back. Its 28 readings per mj_step cost this
  small model a third of its step (1.85 against 1.24 us here, hpg-mj bench envs), so a
  C clock that returns 0 (a compiled cfunc, never Python) takes its place: process-wide,
  as the callback is. A clock set by the user is left alone.
  """
  if mj.get_mjcb_time() is None:    # the bindings' default clock (or none)
    mj.set_mjcb_time(_stopped_clock.ctypes)


@numba.njit(cache=True)
def bow_readings(qpos, act, bow, positions, state):
  """The bow's positions (rows of `qpos`: x, y, yaw) into `positions`, and the last
  row's ship state [x, y, theta_deg, theta_dot_deg] into `state`, the turning rate
  being the rudder filter's activation `act[0]`: the arithmetic of `Physics.position`
  and `heading_deg` compiled, one call per control step."""
  for k in range(qpos.shape[0]):
    theta = qpos[k, 2]
    positions[k, 0] = qpos[k, 0] + bow * math.sin(theta)
    positions[k, 1] = qpos[k, 1] + bow * math.cos(theta)
  last = qpos.shape[0] - 1
  state[0] = positions[last, 0]
  state[1] = positions[last, 1]
  state[2] = core.wrap_deg(math.degrees(qpos[last, 2]))
  state[3] = act[0]


class Physics(mujoco.Physics):
  """The MuJoCo ship with named readings in the paper's units."""

  # Sampled positions of the last step: row 0 is where it began, row k the
  # position after sampling interval k (SPEC section 2 checks each segment).
  _samples = None

  def _reload_from_data(self, data):
    super()._reload_from_data(data)
    set_orthographic_extents(self.model.ptr)
    stop_profiler_clock()   # after MjData's creation, which installs the bindings' clock
    # The raw MuJoCo structures and the bow's offset, read once: the readings
    # below run several times per control step, and dm_control's named and
    # wrapped access costs microseconds each (hpg-mj bench envs).
    self._model_ptr, self._data_ptr = self.model.ptr, self.data.ptr
    # Views of mjData's arrays, taken once for this data: the bindings build a new
    # numpy view at each attribute access.
    self._qpos, self._act, self._ctrl = self._data_ptr.qpos, self._data_ptr.act, self._data_ptr.ctrl
    self._bow = float(self.named.model.site_pos["bow", 1])
    # (nstep, MuJoCo steps per 0.2 s sample, the joint positions at each sample) of
    # the last `step`, checked when nstep first differs from the step before.
    self._sampling = None

  def _substeps_per_sample(self):
    substeps = core.SAMPLING_INTERVAL / self._model_ptr.opt.timestep
    n = int(round(substeps))
    if n < 1 or abs(n - substeps) > 1e-9:
      raise ValueError(f"ship model timestep {self._model_ptr.opt.timestep} s must divide the "
                       f"{core.SAMPLING_INTERVAL} s sampling interval")
    return n

  def bow_offset(self):
    """Distance (m) from the joint origin to the bow site, the reported position."""
    return self._bow

  def heading_deg(self):
    """Heading, degrees clockwise from +y, wrapped to [-180, 180)."""
    return (math.degrees(self._data_ptr.qpos[2]) + 180.0) % 360.0 - 180.0   # core.wrap_deg

  def turning_rate_deg(self):
    """Actual turning rate theta_dot (deg/s): the state of the rudder filter."""
    return float(self._data_ptr.act[0])

  def _position(self):
    x, y, theta = self._data_ptr.qpos.tolist()
    return x + self._bow * math.sin(theta), y + self._bow * math.cos(theta)

  def position(self):
    """(x, y) of the ship in metres (the bow site, see assets/ship.xml)."""
    return np.array(self._position())

  def ship_state(self):
    """[x, y, theta_deg, theta_dot_deg] as a new array."""
    data = self._data_ptr
    state = np.empty(4)
    bow_readings(data.qpos.reshape(1, 3), data.act, self._bow, np.empty((1, 2)), state)
    return state

  def set_ship_state(self, state):
    """Places the ship at [x, y, theta_deg, theta_dot_deg], sailing at speed V."""
    x, y, theta_deg, theta_dot_deg = (float(v) for v in state)
    theta = np.radians(theta_deg)
    c = self.bow_offset()
    sin, cos = np.sin(theta), np.cos(theta)
    self.data.qpos[:] = (x - c * sin, y - c * cos, theta)
    self.data.qvel[:] = (core.SPEED * sin, core.SPEED * cos, np.radians(theta_dot_deg))
    self.data.act[:] = theta_dot_deg
    self.data.ctrl[:2] = theta_dot_deg
    mj.mj_kinematics(self.model.ptr, self.data.ptr)

  def set_turn_command(self, r_deg):
    """Sets the desired turning rate r (deg/s) on both rudder filters."""
    ctrl = self._ctrl
    ctrl[0] = r_deg
    ctrl[1] = r_deg

  def place_target(self, xy):
    """Shows a subtask's goal disc at `xy`, or hides it when `xy` is None."""
    pos = (-5000.0, -5000.0, -50.0) if xy is None else (xy[0], xy[1], 0.3)
    self.named.data.mocap_pos["target"] = pos

  def sampled_positions(self):
    """Positions sampled during the last `step` (rows: start, then each 0.2 s)."""
    if self._samples is None:
      return self.position()[None, :]
    return self._samples

  def _sampling_of(self, nstep):
    """`self._sampling` for steps of `nstep` MuJoCo steps, or ValueError."""
    substeps = self._substeps_per_sample()
    if nstep % substeps:
      raise ValueError(f"the ship steps whole 0.2 s sampling intervals ({substeps} MuJoCo "
                       f"steps each), got nstep={nstep}")
    return nstep, substeps, np.empty((nstep // substeps + 1, 3))

  def step(self, nstep=1):
    """Advances `nstep` MuJoCo steps, sampling the position every 0.2 s."""
    sampling = self._sampling
    if sampling is None or sampling[0] != nstep:
      sampling = self._sampling = self._sampling_of(nstep)
    _, substeps, rows = sampling
    model, data, qpos = self._model_ptr, self._data_ptr, self._qpos
    rows[0] = qpos
    for k in range(1, rows.shape[0]):
      mj.mj_step(model, data, substeps)
      rows[k] = qpos
    # New arrays each step: callers keep the last step's samples and state.
    self._samples = np.empty((rows.shape[0], 2))
    self.stepped_state = np.empty(4)   # `ship_state()` after this step, read with it
    bow_readings(rows, self._act, self._bow, self._samples, self.stepped_state)

  def render(self, height=240, width=320, camera_id=-1, **options):
    """dm_control's `render`, drawn in a worker process (SPEC section 9)."""
    return worker.render_physics(self, "ship.xml", height, width, camera_id, **options)

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
    super().initialize_episode(physics)

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
    self._outcome = self.rules.evaluate(physics.sampled_positions(), physics.ship_state(),
                                        self._steps)
    if self.rules.restarts(self._outcome[3]):   # SPEC section 8: the process goes on
      physics.set_ship_state(self.rules.sample_start(self.random))

  def get_observation(self, physics):
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
    """What ended the last step: "gate", "goal", "out_of_bounds", "timeout" or None."""
    return self._outcome[3]


def _environment(kind, random, initial_state, strict, max_steps, environment_kwargs,
                 **rewards):
  physics = Physics.from_xml_string(*get_model_and_assets())
  task = ShipTask(kind, random=random, initial_state=initial_state, strict=strict,
                  max_steps=max_steps, **rewards)
  environment_kwargs = dict(environment_kwargs or {})
  # The task owns the episode's length (truncation vs. failure differ by task).
  environment_kwargs.setdefault("time_limit", float("inf"))
  environment_kwargs.setdefault("control_timestep", core.CONTROL_INTERVAL)
  return control.Environment(physics, task, **environment_kwargs)


@SUITE.add("benchmarking")
def steer(random=None, initial_state=None, strict=False, max_steps=None,
          environment_kwargs=None, gate_reward=core.GATE_REWARD,
          out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD):
  """The full ship steering task (SPEC section 2); the gate's and the bounds' rewards
  are those of SPEC section 2 unless given (a task file's [environment] does)."""
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
