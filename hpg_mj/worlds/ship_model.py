"""The MuJoCo ship (SPEC section 1): its MJCF model and a `Physics` with named
readings in the paper's units, without rendering: the dm_control domain
(`worlds.ship`, which draws through the render worker) and the render worker's own
drawing (`render.drawing`) both build on it, so neither imports the other.

Creating a `ShipPhysics` stops MuJoCo's built-in profiler for the whole process (its
`mjData.timer` stays 0) unless the user installed a clock (`stop_profiler_clock`).
"""
import ctypes
import math
import os

import numba
import numpy as np
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from hpg_mj import _assets
from hpg_mj import _headless
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_harbour_core as harbour_core

with _headless.simulation_imports():   # no GL in the simulating process (SPEC section 9)
  import mujoco as mj
  from dm_control import mujoco


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
  Python bindings install a steady clock with every MjData
  ([mujoco#2354](https://github.com/google-deepmind/mujoco/issues/2354)), and
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


def _mj_address(function="mj_step"):
  """The address of MuJoCo's C function `function` (of an mjModel and an mjData) in the
  library the bindings loaded (loading a library already loaded gives the same one), or
  0 where it is not found."""
  folder = os.path.dirname(mj.__file__)
  for name in sorted(os.listdir(folder)):
    if name.startswith("libmujoco") or name == "mujoco.dll":
      try:
        return ctypes.cast(getattr(ctypes.CDLL(os.path.join(folder, name)), function),
                           ctypes.c_void_p).value or 0
      except (OSError, AttributeError):
        return 0
  return 0


# `mj_step` called from compiled code (`sail`); 0: through the bindings (`ShipPhysics.step`).
MJ_STEP = _mj_address("mj_step")
# The harbour's rangefinders cast from compiled code after a step (`ship_harbour`).
MJ_KINEMATICS = _mj_address("mj_kinematics")
MJ_SENSOR_POS = _mj_address("mj_sensorPos")


def disableflags_view(model):
  """A numpy int32 array of one element over `model.opt.disableflags` in the mjModel's own
  memory (its offset found by changing the field through the bindings and seeing which
  word changed), for compiled code to switch a stage on and off; None where no single
  word follows the field."""
  words = (ctypes.c_int32 * 512).from_address(model._address)   # mjModel starts with
  # its sizes, then mjOption: within its first 2 KB (the struct holds ~600 pointers more)
  saved = int(model.opt.disableflags)
  before = np.frombuffer(words, dtype=np.int32).copy()
  model.opt.disableflags = saved ^ 0x2A5A5A5
  after = np.frombuffer(words, dtype=np.int32).copy()
  model.opt.disableflags = saved
  changed = np.flatnonzero(before != after)
  if len(changed) != 1 or before[changed[0]] != saved:
    return None
  return np.frombuffer(words, dtype=np.int32)[changed[0]:changed[0] + 1]


@intrinsic
def _c_call(typingctx, address, first, second):
  """The C function `void f(void*, void*)` at `address`, called with two addresses."""
  def codegen(context, builder, signature, args):
    pointer = ir.IntType(8).as_pointer()
    function = builder.inttoptr(args[0], ir.FunctionType(ir.VoidType(), [pointer, pointer])
                                .as_pointer())
    builder.call(function, [builder.inttoptr(args[1], pointer),
                            builder.inttoptr(args[2], pointer)])
    return context.get_dummy_value()
  return types.void(types.int64, types.int64, types.int64), codegen


@numba.njit(cache=True)
def sail(mj_step, model, data, substeps, qpos, act, bow, rows, positions, state):
  """One control step of the MuJoCo ship in compiled code: `mj_step` (the C function at
  that address) on the mjModel and mjData at `model` and `data`, `substeps` times per
  sample; the joint positions `qpos` before and after each sample into `rows`; then
  `bow_readings`. The same MuJoCo steps as the bindings' `mj_step`, bit for bit, without
  a Python call for each."""
  for j in range(3):
    rows[0, j] = qpos[j]
  for k in range(1, rows.shape[0]):
    for _ in range(substeps):
      _c_call(mj_step, model, data)
    for j in range(3):
      rows[k, j] = qpos[j]
  bow_readings(rows, act, bow, positions, state)


_HIDDEN_Z = -50.0        # m: below the sea, where a hidden marker waits
# The course's gates, (post, line) colours: passed, next (SPEC section 2's gate), later.
_COURSE_RGBA = (((0.2, 0.2, 0.2, 1.0), (0.2, 0.2, 0.2, 1.0), (0.12, 0.12, 0.12, 0.9)),
                ((0.95, 0.75, 0.1, 1.0), (0.95, 0.75, 0.1, 1.0), (1.0, 0.9, 0.3, 0.8)),
                ((0.92, 0.92, 0.92, 1.0), (0.92, 0.92, 0.92, 1.0), (1.0, 1.0, 1.0, 0.6)))


def _course_geoms(model):
  """Rows of (left post, right post, line) geom ids of the gates `course<k>_...` of a
  model, k = 0, 1, ... as long as they exist."""
  rows = []
  while True:
    ids = [mj.mj_name2id(model, mj.mjtObj.mjOBJ_GEOM, f"course{len(rows)}_{part}")
           for part in ("post_left", "post_right", "line")]
    if min(ids) < 0:
      return rows
    rows.append(ids)


def _move_gate(model, ids, posts):
  """Puts a gate's geoms `ids` (two posts, then the line between them) at `posts`, rows
  (x, y), their heights as the model has them (posts standing, the line on the sea), the
  line as long as the posts are apart (the goal's hard gate is half the others')."""
  (x0, y0), (x1, y1) = posts
  model.geom_pos[ids[0]] = (x0, y0, 5.0)
  model.geom_pos[ids[1]] = (x1, y1, 5.0)
  half_angle = 0.5 * math.atan2(y1 - y0, x1 - x0)
  model.geom_pos[ids[2]] = (0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.3)
  model.geom_size[ids[2]][0] = 0.5 * math.hypot(x1 - x0, y1 - y0)
  model.geom_rbound[ids[2]] = float(np.linalg.norm(model.geom_size[ids[2]]))
  model.geom_quat[ids[2]] = (math.cos(half_angle), 0.0, 0.0, math.sin(half_angle))
  # The compiler marked the line's frame as its body's turned by nothing, and MuJoCo
  # then never reads its geom_quat: it must read it now.
  model.geom_sameframe[ids[2]] = mj.mjtSameFrame.mjSAMEFRAME_NONE


def harbour_obstacle_geoms(model, level):
  """(island geom ids, pier geom ids) of the harbour's `level` (`ship_harbour_core`) in a
  model of assets/ship_harbour.xml."""
  islands, piers = harbour_core.level_obstacles(level)
  name = lambda kind, k: mj.mj_name2id(model, mj.mjtObj.mjOBJ_GEOM, f"{level}_{kind}{k}")
  return [name("island", k) for k in range(len(islands))], [name("pier", k)
                                                            for k in range(len(piers))]


def place_harbour_obstacles(model, level):
  """Shows the harbour `level`'s obstacles where the model has them (up from the sea) and
  hides every other level's below the sea and the rays (`_HIDDEN_Z`), transparent: a
  ray skips a transparent geom before any arithmetic (MuJoCo's mj_ray), and seven rays
  over every level's geoms were most of a MuJoCo control step."""
  for other in harbour_core.LEVELS:
    islands, piers = harbour_obstacle_geoms(model, other)
    for i in islands + piers:
      shown = other == level
      model.geom_pos[i][2] = 10.0 if shown else _HIDDEN_Z
      model.geom_rgba[i][3] = 1.0 if shown else 0.0


class ShipPhysics(mujoco.Physics):
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
    # `step` in compiled code (`sail`): the mjModel's and mjData's addresses, and the
    # entry point of `sail`, made at the first step.
    self._addresses = (self._model_ptr._address, self._data_ptr._address)
    self._sailing = None
    # The geoms of a course's gates (assets/ship_regatta.xml), rows of (left post, right
    # post, line) ids, looked up once; none in a model without a course.
    self._course_geoms = _course_geoms(self._model_ptr)

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

  def place_gate(self, posts=None):
    """Moves the gate's geoms (its two posts and the line between them) to `posts`,
    rows (x, y) (the goal task's gate), or back to SPEC section 2's when None."""
    posts = core.GATE if posts is None else np.asarray(posts, dtype=np.float64)
    _move_gate(self._model_ptr, [self.model.name2id(name, "geom") for name in
                                 ("gate_post_west", "gate_post_east", "gate_line")], posts)

  def place_course(self, posts, next_gate=0):
    """Moves the course's gate geoms (assets/ship_regatta.xml) to `posts`, (gates, 2, 2)
    rows (x, y) of each gate's posts, and colours them: the gates before `next_gate`
    passed (dark grey), the next as SPEC section 2's gate, the later ones white; the model's
    gates beyond the course and SPEC section 2's own gate hidden below the sea."""
    posts = np.asarray(posts, dtype=np.float64)
    geoms = self._course_geoms
    if len(posts) > len(geoms):
      raise ValueError(f"a course of {len(posts)} gates does not fit the model's "
                       f"{len(geoms)} course gates (assets/ship_regatta.xml)")
    model = self._model_ptr
    for name in ("gate_post_west", "gate_post_east", "gate_line"):
      model.geom_pos[self.model.name2id(name, "geom")][2] = _HIDDEN_Z
    for k, ids in enumerate(geoms):
      if k >= len(posts):
        for i in ids:
          model.geom_pos[i] = (-5000.0, -5000.0, _HIDDEN_Z)
        continue
      _move_gate(model, ids, posts[k])
      look = _COURSE_RGBA[0 if k < next_gate else (1 if k == next_gate else 2)]
      for i, rgba in zip(ids, look):
        model.geom_rgba[i] = rgba

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
    # New arrays each step: callers keep the last step's samples and state.
    self._samples = positions = np.empty((rows.shape[0], 2))
    self.stepped_state = state = np.empty(4)   # `ship_state()` after this step, read with it
    self._sail(substeps, rows, positions, state)

  def _sail(self, substeps, rows, positions, state):
    """The MuJoCo steps of one `step`: `substeps` per sample, the joint positions of
    each sample into `rows`, then `bow_readings` (a ship on other water overrides it)."""
    if MJ_STEP:
      args = (MJ_STEP, self._addresses[0], self._addresses[1], substeps, self._qpos, self._act,
              self._bow, rows, positions, state)
      if self._sailing is None:      # numba's code for these types, typed once
        self._sailing = sail.compile(tuple(numba.typeof(a) for a in args))
      self._sailing(*args)
      return
    model, data, qpos = self._model_ptr, self._data_ptr, self._qpos
    rows[0] = qpos
    for k in range(1, rows.shape[0]):
      mj.mj_step(model, data, substeps)
      rows[k] = qpos
    bow_readings(rows, self._act, self._bow, positions, state)
