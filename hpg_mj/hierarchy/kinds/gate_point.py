"""The point bindings (SPEC section 11). GatePoint: a point of the field fixed in the frame of a
gate the observation holds (`blocks.GateFrame`: the regatta's next gate, the goal's
desired goal), bound as a call's float arguments (px, py) when the parent calls. One
shared subtask of (px, py) then serves every point a parent may name: the gate's
centre, a point across it, a line-up point before it
(`Child("approach", bind=GatePoint(frame, lateral_m=30.0))`), each a style of
approach the parent chooses among (`agents.ship_ladder_waypoints`).

The gate's pose is the gate views' (`gate_frame.gate_pose`); a gate at (gx, gy) heading
phi (sine s, cosine c) puts the point

    px = gx + lateral_m c + along_m s        (lateral_m to the gate's starboard)
    py = gy - lateral_m s + along_m c        (along_m along its heading)

in the field's own coordinates, fixed for the call: the next gate moves on when the
ship passes one, the point does not.

ShipPoint: a point fixed where the ship is when the parent calls, `ahead_m` along its
heading theta and `starboard_m` across it (a detour round what lies ahead):

    px = x + ahead_m sin(theta) + starboard_m cos(theta)
    py = y + ahead_m cos(theta) - starboard_m sin(theta)

each then moved to [within_m, 1000 - within_m] where `within_m` > 0 (the field's
edges; a detour the parent chooses near an edge then leads back into the field).
"""
import collections
import math

import numba

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base
from hpg_mj.hierarchy.kinds import gate_frame
from hpg_mj.worlds import ship_core as core

Settings = collections.namedtuple("Settings", ("at", "relative", "lateral", "along"))
Settings.__doc__ = """A GatePoint's settings: where the gate is in the observation and
whether relative (its `GateFrame`), and the point's offsets across and along it (m)."""


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def bind(P, obs, call):
  """GatePoint's binding: (px, py), the point `P.lateral` m across and `P.along` m along
  the gate `obs` holds, in the field's coordinates."""
  gx, gy, s, c = gate_frame.gate_pose(P.at, P.relative, obs)
  return (gx + P.lateral * c + P.along * s, gy - P.lateral * s + P.along * c)


def _metres(name, block, field):
  value = getattr(block, field)
  if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
    raise GraphError(f"subtask {name!r}: {type(block).__name__}.{field} = {value!r}: must be "
                     "a finite number of metres")
  return float(value)


class GatePointKind(base.BindingKind):
  """Runs a `GatePoint`: the called subtask's float arguments px and py."""
  block = blocks.GatePoint
  bind = staticmethod(bind)

  def names(self, block):
    return {"px": False, "py": False}

  def settings(self, name, block, obs_size):
    at, relative = gate_frame._frame(name, block, obs_size)
    return Settings(at, relative, _metres(name, block, "lateral_m"),
                    _metres(name, block, "along_m"))


ShipPointSettings = collections.namedtuple("ShipPointSettings", ("ahead", "starboard",
                                                                 "within"))
ShipPointSettings.__doc__ = """A ShipPoint's offsets along and across the ship's heading,
and how far inside the field's edges the point is kept (0: anywhere) (m)."""


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def bind_ship(P, obs, call):
  """ShipPoint's binding: (px, py), the point `P.ahead` m along and `P.starboard` m across
  the ship's heading from where it is, in the field's coordinates."""
  rad = math.radians(obs[2])
  s, c = math.sin(rad), math.cos(rad)
  px, py = obs[0] + P.ahead * s + P.starboard * c, obs[1] + P.ahead * c - P.starboard * s
  if P.within > 0.0:
    low, high = P.within, core.FIELD_SIZE - P.within
    px, py = min(max(px, low), high), min(max(py, low), high)
  return px, py


class ShipPointKind(base.BindingKind):
  """Runs a `ShipPoint`: the called subtask's float arguments px and py."""
  block = blocks.ShipPoint
  bind = staticmethod(bind_ship)

  def names(self, block):
    return {"px": False, "py": False}

  def settings(self, name, block):
    within = _metres(name, block, "within_m")
    if not 0.0 <= within < core.FIELD_SIZE / 2:
      raise GraphError(f"subtask {name!r}: ShipPoint.within_m = {within!r}: must be >= 0 "
                       f"and below half the field ({core.FIELD_SIZE / 2:g} m)")
    return ShipPointSettings(_metres(name, block, "ahead_m"), _metres(name, block, "starboard_m"),
                             within)


KINDS = (GatePointKind(), ShipPointKind())
