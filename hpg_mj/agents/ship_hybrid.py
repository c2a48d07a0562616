"""The hierarchical hybrid on ship steering (paper, Figure 3 and section 5.2;
SPEC sections 2-3): a Q(lambda) root over eight directions on a 20 x 20 grid of
50 m cells, and two shared low-level subtasks (diagonal, straight) that steer
with a Gaussian-with-sigmoid CMAC policy learned by Eq. 3.

The agent is its Config, Figure 3's graph of blocks (`graph`) and its metrics: the
open machine (`hierarchy.program`) runs the graph on both paths, fused with the
analytic ship and step by step through any ship environment, with the same
compiled functions.
"""
import dataclasses

from hpg_mj.agents import _ship
from hpg_mj.agents import hierarchy
from hpg_mj import taskfile
from hpg_mj.taskfile import param
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy import ship_rules as rules
from hpg_mj.hierarchy.graph import Child, Primitive, Subtask, TaskGraph
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import tiles
from hpg_mj.worlds import ship_core as core


@dataclasses.dataclass(frozen=True)
class Root(taskfile.Section):
  """[root]: Watkins's Q(lambda) over the SMDP of calls (gamma = 1), replacing traces."""
  learner: str = param("q_lambda", "the root's learner", choices=("q_lambda",))
  alpha: float = param(0.1, "Q(lambda) step size", low=0, low_open=True)
  trace_decay: float = param(0.9, "Q(lambda)'s lambda", low=0, high=1)
  epsilon: float = param(0.1, "exploration, held until both subtasks pass epsilon_threshold",
                         low=0, high=1)
  epsilon_threshold: float = param(0.8, "success rate over epsilon_window runs that starts "
                                   "the decay", low=0, high=1)
  epsilon_window: int = param(1000, "runs per subtask the threshold looks at", low=1)
  epsilon_every: int = param(50, "episodes between divisions of epsilon", low=1)
  epsilon_divisor: float = param(1.01, "epsilon is divided by this", low=1)


@dataclasses.dataclass(frozen=True)
class LowLevel(taskfile.Section):
  """[low_level]: the shared diagonal and straight subtasks, learned by Eq. 3."""
  learner: str = param("policy_gradient", "Eq. 3", choices=("policy_gradient",))
  alpha: float = param(0.01, "Eq. 3 step size", low=0, low_open=True)
  trace_gamma: float = param(1.0, "discount on the Eq. 3 trace (1 = plain Eq. 3)", low=0,
                             high=1, low_open=True)
  baseline: float = param(0.0, "TD(0) step size of a baseline b(s) over the policy's tiles "
                          "(0: none, plain Eq. 3)", low=0, high=1)
  tilings: int = param(9, "CMAC tilings", low=1)
  tiles: tuple = param((5, 5, 36, 5), "tiles per tiling over local x, y, theta, theta_dot",
                       length=4, low=1)
  max_steps: int = param(core.SUBTASK_MAX_STEPS, "control steps, then the subtask has failed",
                         low=1)


@dataclasses.dataclass(frozen=True)
class Config:
  """The task file's schema: its sections [environment], [root] and [low_level]."""
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)
  root: Root = dataclasses.field(default_factory=Root)
  low_level: LowLevel = dataclasses.field(default_factory=LowLevel)


def coder(low):
  """The CMAC of the local frame (SPEC section 3) with [low_level]'s tiles."""
  return tiles.TileCoder((0.0, 0.0, -180.0, -core.MAX_TURN_RATE),
                         (core.LOCAL_SIZE, core.LOCAL_SIZE, 180.0, core.MAX_TURN_RATE),
                         tuple(low.tiles), (False, False, True, False), low.tilings)


def figure3(root, view, termination, low, coder, max_steps, epsilon, per_decision=False,
            frame=None):
  """Figure 3's graph of blocks (SPEC section 3): the root (learner `root`, its `view`
  and `termination`) calls, for each of eight directions, the diagonal or the
  straight subtask (the GaussianCMACs `low`) in its local frame (`coder`'s tiles,
  `max_steps` control steps), under the held epsilon of `epsilon` (a [root] section:
  its epsilon, threshold, window, every and divisor). With a `frame`
  (`blocks.GateFrame`) the local frames stand in the frame of the gate where each call
  began (`blocks.GateLocalTiles`, `blocks.GateLocalGoal`: the ladder's goal, regatta)."""
  def subtask(name, learner):
    local_view, local_end = (blocks.LocalTiles(coder), blocks.LocalGoal(max_steps)) \
        if frame is None else (blocks.GateLocalTiles(frame, coder),
                               blocks.GateLocalGoal(frame, max_steps))
    return Subtask(name, children=["turn"], learner=learner, view=local_view,
                   termination=local_end, internal_reward=blocks.Shaping(),
                   reward=blocks.STEP)  # only the -1s

  return TaskGraph("root", [
      Subtask("root", learner=root, view=view, termination=termination,
              children=[Child("diagonal" if d % 2 else "straight", direction=d)
                        for d in range(rules.N_DIRECTIONS)]),
      subtask("diagonal", low[rules.DIAGONAL]),
      subtask("straight", low[rules.STRAIGHT]),
      Primitive("turn"),          # the turning rate r, drawn by the low level
  ], schedule=blocks.HeldEpsilon(epsilon.epsilon, ("diagonal", "straight"),
                                 epsilon.epsilon_threshold, epsilon.epsilon_window,
                                 epsilon.epsilon_every, epsilon.epsilon_divisor, per_decision))


def low_arrays(agent):
  """(diagonal trace, its baseline, straight trace, its baseline) of an agent with
  Figure 3's subtasks (the hybrid's, the patrol's): the live arrays."""
  state = agent.machine.state()
  return tuple(x for name in ("diagonal", "straight") for x in (
      el.Trace(*[state[f"{name}.{f}"] for f in el.Trace._fields]), state[f"{name}.values"]))


def subtask_metrics(w):
  """Calls per episode and the diagonal and straight subtasks' success rates over the
  record rows `w` (Figure 3's graph's counters)."""
  diag_runs, str_runs = w["diagonal_runs"].sum(), w["straight_runs"].sum()
  return {
      "calls_per_episode": float(w["calls"].mean()) if len(w) else None,
      "diagonal_success_rate": float(w["diagonal_successes"].sum() / diag_runs)
                               if diag_runs else None,
      "straight_success_rate": float(w["straight_successes"].sum() / str_runs)
                               if str_runs else None,
  }


class ShipHybrid(hierarchy.ShipHierarchy):
  """Figure 3's graph of blocks, run by the open machine (`hierarchy.program`) on both
  paths; its state is the program's, by node name (`root.q`, `diagonal.theta`, ...,
  `schedule.state`), and `parameters()` its learners' (`ShipHierarchy`)."""

  name = "ship_hybrid"
  Config = Config
  record_fields = ("passed", "steps", "calls", "diagonal_runs", "diagonal_successes",
                   "straight_runs", "straight_successes", "return")

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    root, low = self.config.root, self.config.low_level
    self.coder = coder(low)
    self.root = blocks.QTable(rules.ROOT_GRID ** 2, alpha=root.alpha,
                              trace_decay=root.trace_decay, epsilon=root.epsilon,
                              epsilon_schedule=True)
    self.low = [blocks.GaussianCMAC(self.coder, low.alpha, low.trace_gamma, low.baseline,
                                    core.MAX_TURN_RATE)
                for _ in (rules.DIAGONAL, rules.STRAIGHT)]

  def graph(self):
    """Figure 3 (SPEC section 3): the root over 50 m cells calls, for each of eight
    directions, the diagonal or the straight subtask in its local frame."""
    return figure3(self.root, blocks.GridCell(rules.ROOT_CELL_M, rules.ROOT_GRID),
                   blocks.Never(), self.low, self.coder, self.config.low_level.max_steps,
                   self.config.root)

  def baselines(self):
    """The two subtasks' baseline values b over their tiles (the live arrays)."""
    state = self.machine.state()
    return [state["diagonal.values"], state["straight.values"]]

  def low_arrays(self):
    """(diagonal trace, its baseline, straight trace, its baseline): the live arrays."""
    return low_arrays(self)

  # ---- metrics ------------------------------------------------------------------

  def metrics(self, record):
    """The ship's metrics, with calls per episode and the diagonal and straight
    subtasks' success rates over the last `metric_window` episodes."""
    return {**super().metrics(record), **subtask_metrics(record[-self.metric_window:])}
