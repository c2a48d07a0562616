"""The GatePoint binding (`hierarchy.kinds.gate_point`): a point bound in a gate's frame
lies where the gate views' frame (`kinds.gate_frame`) puts it, on the regatta's relative
gate and the goal's absolute one; a bad one is refused in one line naming the subtask,
the field and what is allowed."""
import math

import numba
import numpy as np
import pytest

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy import kinds
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import gate_frame
from hpg_mj.hierarchy.kinds import gate_point
from hpg_mj.learners.tiles import TileCoder

REGATTA = blocks.GateFrame(at=4, relative=True)
GOAL = blocks.GateFrame(at=8)


@numba.njit
def _bound(P, obs):
  return gate_point.bind(P, obs, 0)


def _settings(block, name="root", obs_size=12):
  return kinds.kind_of(block, "binding", name).settings(name, block, obs_size)


@pytest.mark.parametrize("lateral,along", [(0.0, 0.0), (30.0, 0.0), (-30.0, 0.0),
                                           (0.0, -80.0), (12.5, 40.0)])
def test_a_gate_point_lies_where_its_gate_frame_puts_it(lateral, along):
  """Mapped into its gate's frame (`gate_frame.to_frame`, the gate views'), the bound
  point is `lateral` m to the gate's starboard and `along` m along its heading."""
  gate = (612.0, 233.0, -131.0)                  # x, y, heading_deg
  ship = np.array([480.0, 310.0, 37.0, -4.0])
  # The regatta's observation: the gate as the ship sees it (ahead, starboard, heading).
  th = math.radians(ship[2])
  dx, dy = gate[0] - ship[0], gate[1] - ship[1]
  regatta = np.concatenate([ship, [dx * math.sin(th) + dy * math.cos(th),
                                   dx * math.cos(th) - dy * math.sin(th), gate[2] - ship[2]],
                            np.zeros(4)])
  # The goal's: the gate's [x, y, sin, cos] at 8.
  phi = math.radians(gate[2])
  goal = np.concatenate([ship, np.zeros(4), [gate[0], gate[1], math.sin(phi), math.cos(phi)]])
  for frame, obs in ((REGATTA, regatta), (GOAL, goal)):
    px, py = _bound(_settings(blocks.GatePoint(frame, lateral, along)), obs)
    pose = gate_frame.gate_pose(frame.at, frame.relative, obs)
    x, y = gate_frame.to_frame(px, py, *pose)
    assert x == pytest.approx(gate_frame.CENTRE_X + lateral, abs=1e-9)
    assert y == pytest.approx(gate_frame.CENTRE_Y + along, abs=1e-9)


@pytest.mark.parametrize("block,message", [
    (blocks.GatePoint((4, True)), r"subtask 'root': GatePoint.frame = \(4, True\): must be "
                                  r"a GateFrame\(at, relative\)"),
    (blocks.GatePoint(blocks.GateFrame(at=2)), r"GateFrame.at = 2: must be an integer >= 4"),
    (blocks.GatePoint(REGATTA, lateral_m=float("nan")),
     r"subtask 'root': GatePoint.lateral_m = nan: must be a finite number of metres"),
    (blocks.GatePoint(REGATTA, along_m="80"),
     r"subtask 'root': GatePoint.along_m = '80': must be a finite number of metres"),
])
def test_a_bad_gate_point_is_refused_in_one_line(block, message):
  with pytest.raises(GraphError, match=message) as err:
    _settings(block)
  assert "\n" not in str(err.value)


def test_a_gate_past_the_observations_end_is_refused_in_one_line():
  """The regatta's observation holds 11 numbers: a relative gate at 8 would be read at
  8-10 (fits), one at 9 past its end; the goal's absolute gate at 8 needs 12."""
  _settings(blocks.GatePoint(blocks.GateFrame(at=8, relative=True)), obs_size=11)
  for frame, size, reads in ((blocks.GateFrame(at=9, relative=True), 11, "9-11"),
                             (GOAL, 11, "8-11")):
    with pytest.raises(GraphError, match=rf"subtask 'root': GatePoint's GateFrame\(at="
                       rf"{frame.at}, relative={frame.relative}\) reads observation numbers "
                       rf"{reads}; the observation holds {size} \(0-10\)") as err:
      _settings(blocks.GatePoint(frame), obs_size=size)
    assert "\n" not in str(err.value)


def test_a_program_refuses_a_gate_view_past_its_observation():
  """Built for the regatta's 11-number observation, a graph whose view reads a gate at
  9-11 is refused when its program is made, before anything compiles."""
  from hpg_mj.hierarchy.graph import Primitive, Subtask, TaskGraph
  from hpg_mj.hierarchy.program import Program
  from hpg_mj.learners.tiles import TileCoder
  coder = TileCoder(low=(0, 0, -180, -15), high=(1000, 1000, 180, 15), n_tiles=(4, 4, 4, 2),
                    wrap=(False, False, True, False))
  graph = TaskGraph("policy", [
      Subtask("policy", children=["turn"], learner=blocks.GaussianCMAC(coder, 0.01, 0.99, 0.0, 15.0),
              view=blocks.GateTiles(blocks.GateFrame(at=9, relative=True), coder),
              termination=blocks.Never()),
      Primitive("turn")])
  with pytest.raises(GraphError, match=r"subtask 'policy': GateTiles's GateFrame\(at=9, "
                                       r"relative=True\) reads observation numbers 9-11; the "
                                       r"observation holds 11"):
    Program(graph, obs_size=11)


def test_a_binding_kinds_own_check_runs_when_the_program_is_made():
  """A user's binding kind refuses a block in its `check` (as views and ends do), given
  the parent's call's arguments; the machine calls it as it builds the graph."""
  import dataclasses
  from hpg_mj.hierarchy.graph import Child, Primitive, Subtask, TaskGraph
  from hpg_mj.hierarchy.kinds import base
  from hpg_mj.hierarchy.kinds.rules import Abstraction, Features
  from hpg_mj.hierarchy.program import Program

  @dataclasses.dataclass(frozen=True)
  class FarPoint:
    metres: float

  class FarPointKind(gate_point.GatePointKind):
    block = FarPoint

    def check(self, name, block, arguments):
      if block.metres > 500:
        raise GraphError(f"subtask {name!r}: FarPoint.metres = {block.metres!r}: at most "
                         f"500 (the parent's call binds {sorted(arguments)})")

    def settings(self, name, block, obs_size):
      return gate_point.Settings(np.int64(4), np.int64(1), float(block.metres), 0.0)

  kinds.register(FarPointKind())
  assert isinstance(kinds.kind_of(FarPoint(1.0), "binding", "root"), base.BindingKind)
  coder = TileCoder(low=(-180, -15), high=(180, 15), n_tiles=(4, 2), wrap=(True, False))

  @numba.njit
  def aim(obs, call):
    return (obs[2] - call.px, obs[3] + call.py)

  graph = TaskGraph("root", [
      Subtask("root", children=[Child("go", bind=FarPoint(900.0))],
              learner=blocks.QTable(1), view=Abstraction(numba.njit(lambda obs, call: 0)),
              termination=blocks.Never()),
      Subtask("go", children=["turn"], learner=blocks.GaussianCMAC(coder, 0.01, 0.99, 0.0, 15.0),
              view=Features(aim), termination=blocks.Never()),
      Primitive("turn")])
  with pytest.raises(GraphError, match=r"subtask 'root': FarPoint.metres = 900.0: at most 500 "
                                       r"\(the parent's call binds \[\]\)"):
    Program(graph, obs_size=11)
