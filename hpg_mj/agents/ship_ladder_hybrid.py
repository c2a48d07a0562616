"""The hierarchical hybrid (paper, Figure 3; SPEC section 3) carried to the task ladder
(SPEC section 11): one agent for every ladder task, its task and level named by its
task file's [environment] (`world = "ship_goal"`, `level = "hard"`), with the steering
hybrid's sections, defaults and graph. The graph is Figure 3's: a Q(lambda) root over a
20 x 20 grid of 50 m cells choosing, for each of eight directions, the diagonal or the
straight subtask, two shared Gaussian-with-sigmoid CMAC policies (Eq. 3) in their
local 150 m frame, the shaping G and the local +100 / -100. Only where its views read
the ship changes with the task, so that the steering task's hierarchy applies:

  current   the ship's pose as on the steering task (the same gate): the root's cell
            of (x, y), the subtasks' local frame; the water drifts the ship and is not
            in the views (the low level corrects its heading towards its local goal,
            whose shaping bearing moves as it drifts)
  goal      the ship's pose in the frame of the episode's gate (`blocks.GateFrame`: the
            desired goal of the flattened observation, obs[8:12]), which puts the gate
            where the steering task's stands, heading north: the root's cell there
            (clamped to the grid), the subtasks' local frames turned with it (a call's
            frame the gate where it began). The field's edges move in that frame: the
            root's cells do not see them
  regatta   the same in the frame of the next gate (obs[4:7], as the ship sees it): one
            gate after another, each approached as the steering task's; a call keeps the
            gate where it began after the ship passes it
  harbour   the ship's pose as on the steering task: the obstacles are the level's own,
            fixed, so the root learns the map over its cells (the route round an island
            as a sequence of legs, as SPEC section 11 intends); the rays are not read

The open machine runs the graph fused with the task's analytic world
(`Program.run_world`) and step by step through its environments; its state is the
program's by node name (`root.q`, `diagonal.theta`, ..., `schedule.state`).
"""
import dataclasses

from hpg_mj.agents import _ladder
from hpg_mj.agents import hierarchy
from hpg_mj.agents import ship_hybrid
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy import ship_rules as rules
from hpg_mj.worlds import ship_core as core

@dataclasses.dataclass(frozen=True)
class Config:
  """The task file's schema: [environment] (the ladder's task and level), and the
  steering hybrid's [root] and [low_level]."""
  environment: _ladder.LadderEnvironment = dataclasses.field(
      default_factory=_ladder.LadderEnvironment)
  root: ship_hybrid.Root = dataclasses.field(default_factory=ship_hybrid.Root)
  low_level: ship_hybrid.LowLevel = dataclasses.field(default_factory=ship_hybrid.LowLevel)


class ShipLadderHybrid(hierarchy.ShipLadderHierarchy):
  """Figure 3's graph on a ladder task (see the module docstring), run by the open
  machine fused with the task's world and step by step through its environments."""

  name = "ship_ladder_hybrid"
  Config = Config
  record_fields = ("passed", "steps", "gates", "calls", "diagonal_runs", "diagonal_successes",
                   "straight_runs", "straight_successes", "return")

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    root, low = self.config.root, self.config.low_level
    self.coder = ship_hybrid.coder(low)
    self.root = blocks.QTable(rules.ROOT_GRID ** 2, alpha=root.alpha,
                              trace_decay=root.trace_decay, epsilon=root.epsilon,
                              epsilon_schedule=True)
    self.low = [blocks.GaussianCMAC(self.coder, low.alpha, low.trace_gamma, low.baseline,
                                    core.MAX_TURN_RATE)
                for _ in (rules.DIAGONAL, rules.STRAIGHT)]

  def graph(self):
    """Figure 3 (SPEC section 3) with the task's views (the module docstring)."""
    frame = _ladder.GATE_FRAMES[self.config.environment.world]
    view = blocks.GridCell(rules.ROOT_CELL_M, rules.ROOT_GRID) if frame is None else \
        blocks.GateCell(frame, rules.ROOT_CELL_M, rules.ROOT_GRID)
    return ship_hybrid.figure3(self.root, view, blocks.Never(), self.low, self.coder,
                               self.config.low_level.max_steps, self.config.root, frame=frame)

  def low_arrays(self):
    """(diagonal trace, its baseline, straight trace, its baseline): the live arrays."""
    return ship_hybrid.low_arrays(self)

  def metrics(self, record):
    """The task's benchmark metrics (`ShipLadderHierarchy`), with calls per episode and
    the diagonal and straight subtasks' success rates over the last `metric_window`
    episodes."""
    return {**super().metrics(record),
            **ship_hybrid.subtask_metrics(record[-self.metric_window:])}
