"""The gate views (SPEC section 11): the ship read in the frame of a gate its
observation holds (`blocks.GateFrame`: the goal's desired goal, the regatta's next
gate), a frame that puts that gate where the steering task's stands, its centre at
(400, 400) and its heading north, so that the steering task's hierarchy (SPEC section
3) applies to a gate anywhere.

The frame is a rotation and a translation of the plane, the heading turned with it:
an isometry of Equation 1, so sailing and then mapping equals mapping and then
sailing, as SPEC section 3 asks of the local frames. A ship at (x, y) heading theta,
a gate at (gx, gy) heading phi (sine s, cosine c):

    X = 400 + (x - gx) c - (y - gy) s        (to the gate's starboard)
    Y = 400 + (x - gx) s + (y - gy) c        (along the gate's heading)
    theta' = theta - phi                      (wrapped)

  GateCell(frame, cell_m, grid)      the root's state: the cell of (X, Y), clamped
  GateTiles(frame, coder)            a flat learner's: (X, Y, theta', theta_dot)
  GateLocalTiles(frame, coder)       a subtask's: LocalTiles of the framed ship
  GateLocalGoal(frame, max_steps)    its end: LocalGoal of the framed ship and samples
                                     (with `internal_reward=Shaping()`, its G)

A subtask's frame is the gate of the observation where its call began (`call.origin`):
it holds while the call runs, as its local frame does, though the regatta's next gate
moves on when the ship passes one.
"""
import collections
import math

import numba
import numpy as np

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base
from hpg_mj.hierarchy.kinds import grid_cell
from hpg_mj.hierarchy.kinds import local_frame
from hpg_mj.worlds import ship_core as core

# Where the frame puts the gate's centre: the steering task's (SPEC section 2).
CENTRE_X = 0.5 * float(core.GATE[0, 0] + core.GATE[1, 0])
CENTRE_Y = 0.5 * float(core.GATE[0, 1] + core.GATE[1, 1])

_JIT = dict(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
            no_cfunc_wrapper=True)

Frame = collections.namedtuple("Frame", ("at", "relative", "ship", "origin"))
Frame.__doc__ = """A gate view's settings: where the gate is in the observation, whether
relative, and scratch for the framed ship and the call's framed origin."""
EndSettings = collections.namedtuple("EndSettings", ("at", "relative", "ship", "origin",
                                                     "samples", "max_steps", "local",
                                                     "local_samples"))
EndSettings.__doc__ = """A GateLocalGoal's settings: its frame's (`Frame`), scratch for the
framed samples, the call's control steps at most, and LocalGoal's scratch."""
CellSettings = collections.namedtuple("CellSettings", ("at", "relative", "cell_m", "grid"))
CellSettings.__doc__ = """A GateCell's settings: its frame's, and the grid's (`GridCell`)."""


@numba.njit(cache=True, error_model="numpy", inline="always")
def gate_pose(at, relative, obs):
  """(x, y, sin, cos) of the centre and heading of the gate `obs` holds at `at`."""
  if relative:                     # [ahead, starboard, heading less the ship's]
    rad = math.radians(obs[2])
    s, c = math.sin(rad), math.cos(rad)
    ahead, right = obs[at], obs[at + 1]
    heading = math.radians(obs[2] + obs[at + 2])
    return (obs[0] + ahead * s + right * c, obs[1] + ahead * c - right * s,
            math.sin(heading), math.cos(heading))
  return obs[at], obs[at + 1], obs[at + 2], obs[at + 3]


@numba.njit(cache=True, error_model="numpy", inline="always")
def to_frame(x, y, gx, gy, s, c):
  """(X, Y) of the point (x, y) in the frame of the gate at (gx, gy), heading (s, c)."""
  dx, dy = x - gx, y - gy
  return CENTRE_X + dx * c - dy * s, CENTRE_Y + dx * s + dy * c


@numba.njit(cache=True, error_model="numpy", inline="always")
def framed_ship(obs, gx, gy, s, c, out):
  """The ship's [X, Y, theta', theta_dot] in the gate's frame into `out`."""
  out[0], out[1] = to_frame(obs[0], obs[1], gx, gy, s, c)
  out[2] = core.wrap_deg(obs[2] - math.degrees(math.atan2(s, c)))
  out[3] = obs[3]


@numba.njit(cache=True, error_model="numpy", inline="always")
def _call_frame(P, obs, call):
  """The call's gate (the one where it began): the ship and the call's origin framed
  by it into P.ship and P.origin."""
  gx, gy, s, c = gate_pose(P.at, P.relative, call.origin)
  framed_ship(obs, gx, gy, s, c, P.ship)
  P.origin[0], P.origin[1] = to_frame(call.origin[0], call.origin[1], gx, gy, s, c)
  return gx, gy, s, c


@numba.njit(**_JIT)
def cell_view(P, obs, call, samples):
  """The cell of the ship's (X, Y) in the frame of the observation's gate."""
  gx, gy, s, c = gate_pose(P.at, P.relative, obs)
  x, y = to_frame(obs[0], obs[1], gx, gy, s, c)
  return grid_cell.grid_cell(x, y, P.cell_m, P.grid)


@numba.njit(**_JIT)
def tiles_view(P, obs, call, samples, out):
  """The ship's [X, Y, theta', theta_dot] in the frame of the observation's gate."""
  gx, gy, s, c = gate_pose(P.at, P.relative, obs)
  framed_ship(obs, gx, gy, s, c, out)


@numba.njit(**_JIT)
def local_view(P, obs, call, samples, out):
  """The framed ship in the call's local frame (`ship_core.global_to_local`)."""
  _call_frame(P, obs, call)
  core.global_to_local(P.ship, P.origin, call.direction, out)


@numba.njit(**_JIT)
def local_end(P, obs, call, samples):
  """(event, G) of the framed ship and samples (`ship_core.low_level_outcome`)."""
  gx, gy, s, c = _call_frame(P, obs, call)
  for k in range(samples.shape[0]):
    P.samples[k, 0], P.samples[k, 1] = to_frame(samples[k, 0], samples[k, 1], gx, gy, s, c)
  return core.low_level_outcome(P.samples, P.ship, P.origin, call.direction, call.steps,
                                P.local_samples, P.local, P.max_steps)


def check_reach(name, what, frame, obs_size):
  """Refuses a frame whose gate lies past the end of the observation (`obs_size`
  numbers): the compiled view would read beyond it. A relative gate is 3 numbers
  (ahead, starboard, heading), an absolute one 4 (x, y, sin, cos)."""
  width = 3 if frame.relative else 4
  if obs_size is not None and frame.at + width > obs_size:
    raise GraphError(f"subtask {name!r}: {what}'s GateFrame(at={frame.at}, relative="
                     f"{bool(frame.relative)}) reads observation numbers {frame.at}-"
                     f"{frame.at + width - 1}; the observation holds {obs_size} (0-"
                     f"{obs_size - 1})")


def _frame(name, block, obs_size=None):
  frame = block.frame
  if not isinstance(frame, blocks.GateFrame):
    raise GraphError(f"subtask {name!r}: {type(block).__name__}.frame = {frame!r}: must be a "
                     "GateFrame(at, relative)")
  base.check_positive_int(frame, "at", frame.at, low=4)      # after the ship's state
  check_reach(name, type(block).__name__, frame, obs_size)
  return np.int64(frame.at), np.int64(bool(frame.relative))


class GateCellKind(base.ViewKind):
  """Runs a `GateCell` view: grid ** 2 states."""
  block = blocks.GateCell
  gives = "state"
  view = staticmethod(cell_view)

  def size(self, block):
    return int(block.grid) ** 2

  def settings(self, name, block, obs_size):
    base.check_positive_int(block, "grid", block.grid)
    return CellSettings(*_frame(name, block, obs_size), float(block.cell_m), np.int64(block.grid))


class GateTilesKind(base.ViewKind):
  """Runs a `GateTiles` view: 4 features."""
  block = blocks.GateTiles
  gives = "features"
  writes = True
  view = staticmethod(tiles_view)

  def size(self, block):
    return 4

  def settings(self, name, block, obs_size):
    return Frame(*_frame(name, block, obs_size), np.zeros(4), np.zeros(2))


class GateLocalTilesKind(GateTilesKind):
  """Runs a `GateLocalTiles` view: 4 features, in the local frame of the call's
  `direction`."""
  block = blocks.GateLocalTiles
  view = staticmethod(local_view)

  def check(self, name, block, arguments):
    local_frame._direction(name, arguments)


class GateLocalGoalKind(base.TerminationKind):
  """Runs a `GateLocalGoal` termination, which gives its G (a `Shaping` takes it)."""
  block = blocks.GateLocalGoal
  end = staticmethod(local_end)
  gives_internal = True

  def check(self, name, block, arguments):
    local_frame._direction(name, arguments)

  def settings(self, name, block, node, obs_size):
    shaping = node.internal_reward
    if isinstance(shaping, blocks.Shaping) and shaping.weight != 1.0:
      raise GraphError(f"subtask {name!r}: a GateLocalGoal's Shaping has weight 1; got "
                       f"{shaping.weight!r}")
    samples = (core.SAMPLES_PER_CONTROL + 1, 2)
    return EndSettings(*_frame(name, block, obs_size), np.zeros(4), np.zeros(2), np.zeros(samples),
                       np.int64(base.check_positive_int(block, "max_steps", block.max_steps)),
                       np.zeros(4), np.zeros(samples))


KINDS = (GateCellKind(), GateTilesKind(), GateLocalTilesKind(), GateLocalGoalKind())
