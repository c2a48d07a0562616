"""The route's kinds (`agents.ship_beyond`): a subtask that steers to one of the gate's
points, chosen by number (`ship_rules.target_of`; its call's integer argument
`target`), and a root that may choose the approach points only near the gate line.

  AimTiles(coder, targets, error_scale, reflect_deg)
                      the view: heading error to the target, turning rate, distance
                      (`ship_rules.aim_view`), which its learner tiles; a large error
                      on the negative side is reflected, and the learner's action with it
  TargetReached(max_steps)
                      the termination: through the gate, within `radius_m` of an
                      approach point, off the field or after `max_steps`
                      (`ship_rules.aim_outcome`); its G, with `internal_reward=
                      Shaping(weight)`, the heading shaping times `weight` and +100 / -100.
                      The targets are its node's AimTiles'.
  NearGateLine(within_m)
                      the root's `available`: all its children within `within_m` of
                      the gate line, else only the first (the gate)
"""
import collections

import numba
import numpy as np

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy import ship_rules
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base

ViewSettings = collections.namedtuple("ViewSettings", ("inset_m", "approach_m", "sqrt_error",
                                                       "reflect_at"))
ViewSettings.__doc__ = """An AimTiles' settings: the targets' (`blocks.GatePoints`, in
m), whether the heading error is on a square-root scale, and where it is reflected."""
EndSettings = collections.namedtuple("EndSettings", ("inset_m", "approach_m", "radius_m",
                                                     "max_steps", "shaping"))
EndSettings.__doc__ = """A TargetReached's settings: the targets' (m), the radius in m
that reaches an approach point, the call's control steps at most and the shaping's
weight."""
OfferSettings = collections.namedtuple("OfferSettings", ("within_m",))
OfferSettings.__doc__ = """A NearGateLine's settings: the distance in m from the gate
line within which every child is offered."""


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _target(P, obs, call):
  return ship_rules.target_of(call.target, obs, ship_rules.side_of(call.origin[1]), P.inset_m,
                              P.approach_m)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def aim_view(P, obs, call, samples, out):
  """The aim state into out[:3], and its side (1, or -1 reflected) into out[3]."""
  tx, ty = _target(P, obs, call)
  out[3] = ship_rules.aim_view(obs, tx, ty, out[:3], P.sqrt_error != 0, P.reflect_at)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def target_reached(P, obs, call, samples):
  """TargetReached's `end`: (event, G) of the call steering to its target
  (`ship_rules.aim_outcome`)."""
  tx, ty = _target(P, obs, call)
  return ship_rules.aim_outcome(samples, obs, call.target, tx, ty, call.steps, P.max_steps,
                                P.radius_m, P.shaping)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def near_gate_line(P, obs, call, mask):
  """NearGateLine's `offer`: the first child (the gate) always; the others only when
  the ship is within `within_m` of the gate line."""
  near = abs(obs[1] - ship_rules.GATE_Y) <= P.within_m
  mask[0] = True
  for i in range(1, mask.shape[0]):
    mask[i] = near


def _needs_target(name, block, arguments):
  if arguments.get("target") is not True:
    raise GraphError(f"subtask {name!r}: its {type(block).__name__} steers to its call's "
                     "integer argument `target` (0-3: ship_rules.target_of); bind it in each "
                     "Child: Child(..., target=t)")


class AimTilesKind(base.ViewKind):
  """Runs an `AimTiles` view: 3 features, reflected."""
  block = blocks.AimTiles
  gives = "features"
  writes = True
  reflects = True
  view = staticmethod(aim_view)

  def size(self, block):
    return 3

  def check(self, name, block, arguments):
    _needs_target(name, block, arguments)

  def settings(self, name, block):
    return ViewSettings(float(block.targets.inset_m), float(block.targets.approach_m),
                        np.int64(block.error_scale == "sqrt"),
                        ship_rules.error_coordinate(block.reflect_deg, block.error_scale))


class TargetReachedKind(base.TerminationKind):
  """Runs a `TargetReached` termination, which gives its G."""
  block = blocks.TargetReached
  end = staticmethod(target_reached)
  gives_internal = True

  def check(self, name, block, arguments):
    _needs_target(name, block, arguments)

  def settings(self, name, block, node):
    if not isinstance(node.view, blocks.AimTiles):
      raise GraphError(f"subtask {name!r}: a TargetReached ends a call at its AimTiles' "
                       f"target; its view is {type(node.view).__name__}")
    shaping = node.internal_reward
    weight = float(shaping.weight) if isinstance(shaping, blocks.Shaping) else 1.0
    t = node.view.targets
    return EndSettings(float(t.inset_m), float(t.approach_m), float(t.radius_m),
                       np.int64(base.check_positive_int(block, "max_steps", block.max_steps)),
                       weight)


class NearGateLineKind(base.AvailableKind):
  """Runs a `NearGateLine` root's `available`."""
  block = blocks.NearGateLine
  offer = staticmethod(near_gate_line)
  prefix = True

  def settings(self, name, block):
    return OfferSettings(float(block.within_m))


KINDS = (AimTilesKind(), TargetReachedKind(), NearGateLineKind())
