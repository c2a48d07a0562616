"""The ship's local subtasks (SPEC section 3): the call's local 150 m frame, its origin
where the call began and its rotation by the call's `direction` argument
(`ship_core.global_to_local`).

  LocalTiles(coder)   the view: the ship's state in the local frame, 4 numbers that
                      the node's learner tiles (over the same `coder`)
  LocalGoal(max_steps)
                      the termination: its goal within 10 m (success), the frame
                      left or `max_steps` control steps (failure), judged on the
                      positions sampled in the step (`ship_core.low_level_outcome`);
                      with `internal_reward=Shaping()` its G is the heading shaping
                      and the local +100 / -100
"""
import collections

import numba
import numpy as np

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base
from hpg_mj.worlds import ship_core as core

EndSettings = collections.namedtuple("EndSettings", ("max_steps", "local", "local_samples"))
EndSettings.__doc__ = """A LocalGoal's settings: the call's control steps at most, and
scratch for the frame's numbers (the local state, the local samples)."""


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def view(P, obs, call, samples, out):
  """The ship's state in the call's local frame, into out[:4]
  (`ship_core.global_to_local`)."""
  core.global_to_local(obs, call.origin, call.direction, out)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def end(P, obs, call, samples):
  """(event, G: the shaping and the local +100 / -100)."""
  return core.low_level_outcome(samples, obs, call.origin, call.direction, call.steps,
                                P.local_samples, P.local, P.max_steps)


def _direction(name, arguments):
  if arguments.get("direction") is not True:
    raise GraphError(f"subtask {name!r}: the local frame turns by the call's integer argument "
                     "`direction` (0-7); bind it in each Child: Child(..., direction=d)")


class LocalTilesKind(base.ViewKind):
  """Runs a `LocalTiles` view: 4 features."""
  block = blocks.LocalTiles
  gives = "features"
  writes = True
  view = staticmethod(view)

  def size(self, block):
    return 4

  def check(self, name, block, arguments):
    _direction(name, arguments)

class LocalGoalKind(base.TerminationKind):
  """Runs a `LocalGoal` termination, which gives its G."""
  block = blocks.LocalGoal
  end = staticmethod(end)
  gives_internal = True

  def check(self, name, block, arguments):
    _direction(name, arguments)

  def settings(self, name, block, node):
    shaping = node.internal_reward
    if isinstance(shaping, blocks.Shaping) and shaping.weight != 1.0:
      raise GraphError(f"subtask {name!r}: a LocalGoal's Shaping has weight 1; got "
                       f"{shaping.weight!r}")
    return EndSettings(np.int64(base.check_positive_int(block, "max_steps", block.max_steps)),
                       np.zeros(4), np.zeros((core.SAMPLES_PER_CONTROL + 1, 2)))


class ShapingKind(base.RewardKind):
  """G from the node's termination (a LocalGoal's, a TargetReached's): its shaping
  (times the weight, which the termination reads from its node) and +100 / -100."""
  block = blocks.Shaping
  from_termination = True
