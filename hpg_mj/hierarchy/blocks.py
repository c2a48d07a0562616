"""The building blocks of a compiled task graph (the open machine, `hierarchy.program`).

A `Subtask` of `hpg_mj.hierarchy.graph` whose learner, view, termination and
internal reward are blocks is data: the open machine finds each block's kind
(`hierarchy.kinds`: one module a kind) and compiles the graph with Algorithm 1
(`hierarchy.algorithm`), fused with a compiled world or step by step under any
environment. These are the shipped blocks; a user adds a kind of their own with
`hierarchy.kinds.register`, and writes rules of their own with
`hierarchy.kinds.rules` (below).

Learners (one instance may serve several nodes, which then share its parameters):

  QTable(n_states, alpha, trace_decay, epsilon, ...)
      Watkins's Q(lambda) over an SMDP with replacing traces (SPEC section 3),
      epsilon-greedy; `epsilon_schedule=True` reads epsilon from the graph's
      `HeldEpsilon` instead of its own constant.
  TiledQTable(coder, alpha, trace_decay, epsilon, ...)
      the same Q(lambda), linear in `coder`'s tiles of its StateTiles view (one
      tiling of non-overlapping tiles is the table; `qlambda.tiled_update`).
  RLearning(n_states, alpha, gain_step, epsilon, epsilon_schedule, planning_every)
      average-reward SMDP Q-learning on a table (`learners.average_reward`, SPEC section
      8): relative values and the gain rho, for the root of a continuing task (its
      termination a `Clock`); with `planning_every` > 0 it also plans (Dyna).
  GaussianCMAC(coder, alpha, trace_gamma, baseline, r_max, width_alpha, sigma_low,
               sigma_high)
      Eq. 3 with a Gaussian-with-sigmoid policy over a CMAC (SPEC section 3),
      optionally with a baseline b(s) over the same tiles and a learned
      exploration width (SPEC section 8); its node's only child is a continuous
      primitive (the value it draws is the action).

  GibbsTable(n_states, alpha, trace_gamma, baseline, start_fraction, delay, ramp)
      Eq. 3 with a Gibbs (softmax) policy over a table (paper section 5.1), optionally
      with a baseline b(s) and a warm-up of its step size (the taxi's HPG); it
      chooses among the children its node's `available` allows.

  ActorCritic(actor_coder, critic_coder, alpha_actor, alpha_critic, trace_decay, r_max)
      Konda's actor-critic (SPEC section 4): a Gaussian-with-sigmoid actor over its
      view's tiles (a StateTiles view over `actor_coder`), a critic linear over
      `critic_coder`'s tiles of (state, action), learned by TD(lambda); its one child
      is a continuous primitive.

Views (what a node's learner sees of the world's state):

  GridCell(cell_m, grid)       the (x, y) cell of a grid over the field
  PatrolCell(heading_sectors, near_gate_m, near_gate_cell_m)
                               the patrol root's: the 50 m cell, finer cells about
                               the gate, the heading's sector (`ship_rules.root_state`)
  LocalTiles(coder)            the ship's state in the call's local 150 m frame
                               (origin: where it was called; rotation: the
                               `direction` argument of its `Child`), as CMAC tiles
  StateTiles(coder)            the world's state itself (its first coder.low numbers),
                               as CMAC tiles (a flat learner, the route's root)
  AimTiles(coder, targets, error_scale, reflect_deg)
                               the heading error, turning rate and distance to the
                               target its `Child`'s `target` argument names (the
                               route's, `GatePoints`), as CMAC tiles; errors beyond
                               `reflect_deg` to one side reflected onto the other,
                               with the drawn turning rate negated (SPEC section 8)
  GateCell(frame, cell_m, grid), GateTiles(frame, coder), GateLocalTiles(frame, coder)
                               GridCell, StateTiles and LocalTiles of the ship in
                               the frame of a gate the observation holds
                               (`GateFrame(at, relative)`: the ladder's goal and
                               regatta), which puts it where the steering task's
                               gate stands; a call's frame is the gate where it began
  TaxiState()                  the taxi's full state, as its index (a flat QTable)
  TaxiAbstraction(subtask)     the taxi hierarchy's abstract state of `subtask`

The children a ship node may choose (its `available`): `NearGateLine(within_m)`,
all within `within_m` of the gate line, else only the first (a TiledQTable's).

A `Child`'s arguments fixed in a gate's frame when its parent calls: `GatePoint(frame,
lateral_m, along_m)` binds (px, py), a point across or along the gate the observation
holds (`GateFrame`), which one shared subtask of (px, py) steers to; `ShipPoint(ahead_m,
starboard_m)` a point fixed where the ship is when its parent calls.

The taxi hierarchy's rules (`hierarchy.taxi_subtasks`), for a program built with the
taxi's world: `TaxiChildren(subtask)` (a node's `available`), `TaxiEnd(subtask)`
(its termination), `TaxiTarget(subtask)` (a `Child`'s `bind`: Navigate's target).

Terminations and internal rewards:

  Never()                      the node ends only with the episode (a root)
  Clock(steps)                 a continuing root: its call (a record row) ends once
                               it has run `steps` primitive steps, between its
                               children's calls; the world's events (a gate pass, a
                               departure and the restart after it) end its children's
                               calls, not it
  LocalGoal(max_steps)         the ship's local subtask (SPEC section 3): its goal
                               within 10 m, its frame left, or max_steps control
                               steps; with `internal_reward=Shaping()` its G is the
                               heading shaping and the local +100 / -100
  GateLocalGoal(frame, max_steps)
                               LocalGoal in the frame of the gate where the call
                               began (`GateFrame`)
  TargetReached(max_steps)     an AimTiles node's end: through the gate or within
                               its GatePoints' `radius_m` of an approach point
                               (success), off the
                               field, across the gate line beside the gate or
                               after max_steps (failure); with `Shaping(weight)`
                               its G is the shaping towards the target, times
                               weight, and +100 / -100

A user's own rule, where the blocks do not reach, is a small `@numba.njit` function
of the observation and the call's record (`call.x` its arguments by name,
`call.origin` the observation where it began, `call.steps` its primitive steps),
compiled into the graph's program (`hierarchy.kinds.rules`): `Abstraction(rule)` a
table's state, `Features(rule)` the numbers a coder tiles, `Termination(rule)` the
call's event, `InternalReward(rule)` G (rule(obs, call, event)).

Rewards a node's learner sees: `reward=SUMMED` (the rewards of the child's run
summed: the root's R) or `reward=STEP` (-1 a primitive step: the low level's R,
SPEC section 3).

The graph-wide epsilon schedule: `HeldEpsilon(epsilon, watch, threshold, window,
every, divisor, per_decision)` (`learners.schedules`): held until every watched node
succeeds in `threshold` of its last `window` runs, then divided by `divisor` every
`every` episodes (with `per_decision`, every `every` decisions of the root: a
continuing task has no episodes); or `LinearEpsilon(start, end, episodes)`, a linear decay over learning
episodes.
"""
import dataclasses
import math

from hpg_mj.hierarchy import ship_rules
from hpg_mj.learners import tiles as tiles_mod

SUMMED = "summed"
STEP = "step"


@dataclasses.dataclass(eq=False)
class QTable:
  """Watkins's Q(lambda) on a table of `n_states` states x the node's children.

  `n_states` the number of states its view gives (an integer in [0, n_states));
  `alpha` the step size; `trace_decay` lambda; `epsilon` the epsilon-greedy choice's
  chance of a uniform child, or, `epsilon_schedule` True, the graph's `schedule`
  instead (`HeldEpsilon`, `LinearEpsilon`); `gamma` the discount per decision;
  `trace_capacity` the most (state, child) entries its trace holds at once."""
  n_states: int
  alpha: float = 0.1
  trace_decay: float = 0.9
  epsilon: float = 0.1
  gamma: float = 1.0
  epsilon_schedule: bool = False
  trace_capacity: int = 4096


def check_width(width_alpha, sigma_low, sigma_high, where="GaussianCMAC"):
  """Refuses a learned width's option out of range, naming it and what is allowed."""
  if not (isinstance(width_alpha, (int, float)) and math.isfinite(width_alpha)
          and width_alpha >= 0):
    raise ValueError(f"{where} width_alpha = {width_alpha!r}: must be a finite number >= 0 "
                     "(0: the paper's fixed sigma = 1)")
  if not (0 < sigma_low <= 1.0 <= sigma_high and math.isfinite(sigma_high)):
    raise ValueError(f"{where} sigma_low = {sigma_low!r}, sigma_high = {sigma_high!r}: need "
                     "0 < sigma_low <= 1 <= sigma_high < inf (sigma starts at 1)")


@dataclasses.dataclass(eq=False)
class TiledQTable:
  """Watkins's Q(lambda) linear in `coder`'s tiles x the node's children (its view: a
  StateTiles over `coder`); the settings are QTable's, `trace_capacity` None: every
  weight once."""
  coder: tiles_mod.TileCoder
  alpha: float = 0.1
  trace_decay: float = 0.9
  epsilon: float = 0.1
  gamma: float = 1.0
  epsilon_schedule: bool = False
  trace_capacity: int = None


@dataclasses.dataclass(eq=False)
class RLearning:
  """Average-reward SMDP Q-learning on a table of `n_states` states x the node's
  children (`learners.average_reward`): relative values Q (step size `alpha`) and the
  gain rho (Schwartz's update, step size `gain_step`); epsilon-greedy; with
  `planning_every` > 0 one planning sweep every that many decisions."""
  n_states: int
  alpha: float = 0.1
  gain_step: float = 0.0001
  epsilon: float = 0.1
  epsilon_schedule: bool = False
  planning_every: int = 0


@dataclasses.dataclass(eq=False)
class GaussianCMAC:
  """Eq. 3 with a Gaussian-with-sigmoid policy over `coder`'s tiles; with
  `width_alpha` > 0, its exploration width sigma(s) learned too, in
  [sigma_low, sigma_high] (`policies.gaussian_width_act`; 0: the paper's sigma = 1).

  `coder` the tiles of the node's view (a `Features` view gives it its numbers);
  `alpha` Eq. 3's step size; `trace_gamma` the decay of Eq. 3's trace z per step (1:
  the whole episode's); `baseline` the step size of a baseline b(s) over the same
  tiles (0: none); `r_max` the largest action: u ~ Normal(m(s), sigma) is acted as
  r_max (2 sigmoid(u) - 1), for the ship's turning rate 15 deg/s; `width_alpha`,
  `sigma_low`, `sigma_high` the learned width's step size and bounds."""
  coder: tiles_mod.TileCoder
  alpha: float = 0.01
  trace_gamma: float = 1.0
  baseline: float = 0.0
  r_max: float = 15.0
  width_alpha: float = 0.0
  sigma_low: float = 0.25
  sigma_high: float = 4.0

  def __post_init__(self):
    check_width(self.width_alpha, self.sigma_low, self.sigma_high)


@dataclasses.dataclass(eq=False)
class ActorCritic:
  """Konda's actor-critic: the actor over `actor_coder`'s tiles of the state, the
  critic over `critic_coder`'s tiles of (state, r). `alpha_actor` and `alpha_critic`
  their step sizes, `trace_decay` the critic's lambda, `r_max` the largest action, as
  GaussianCMAC's."""
  actor_coder: tiles_mod.TileCoder
  critic_coder: tiles_mod.TileCoder
  alpha_actor: float = 1e-4
  alpha_critic: float = 0.01
  trace_decay: float = 0.9
  r_max: float = 15.0


@dataclasses.dataclass(eq=False)
class GibbsTable:
  """Eq. 3 with a Gibbs (softmax) policy over a table of `n_states` states x the
  node's children (paper section 5.1), optionally with a baseline b(s) learned by
  TD(0) with step size `baseline` (0: none, Eq. 3 exactly); its step size is alpha
  times a warm-up: `start_fraction` for the first `delay` learning episodes, then a
  linear rise to 1 over `ramp` episodes. `trace_gamma` the decay of Eq. 3's trace per
  step, as GaussianCMAC's."""
  n_states: int
  alpha: float = 0.1
  trace_gamma: float = 1.0
  baseline: float = 0.0
  start_fraction: float = 1.0
  delay: int = 0
  ramp: int = 1


@dataclasses.dataclass(frozen=True)
class GridCell:
  """The cell i * grid + j of (x, y) on a grid of `cell_m` cells, clamped to it."""
  cell_m: float = 50.0
  grid: int = 20


@dataclasses.dataclass(eq=False)
class LocalTiles:
  """The ship's state in the call's local frame, coded by `coder`."""
  coder: tiles_mod.TileCoder


@dataclasses.dataclass(eq=False)
class StateTiles:
  """The world's state as it is, coded by `coder`."""
  coder: tiles_mod.TileCoder


@dataclasses.dataclass(frozen=True)
class GateFrame:
  """Where the observation holds a gate (SPEC section 11's goal and regatta), whose frame
  the gate views read the ship in: at `at`, [x, y, sin, cos] of its centre and heading
  (the goal's desired goal), or, `relative`, [ahead, starboard, heading less the
  ship's] (the regatta's next gate). The frame puts the gate where the steering task's
  stands, its centre at (400, 400), its heading north (`kinds.gate_frame`)."""
  at: int
  relative: bool = False


@dataclasses.dataclass(frozen=True)
class GateCell:
  """GridCell of the ship's (x, y) in the gate's frame (`GateFrame`) of the observation."""
  frame: GateFrame
  cell_m: float = 50.0
  grid: int = 20


@dataclasses.dataclass(eq=False)
class GateTiles:
  """The ship's state in the gate's frame of the observation, coded by `coder`."""
  frame: GateFrame
  coder: tiles_mod.TileCoder


@dataclasses.dataclass(eq=False)
class GateLocalTiles:
  """LocalTiles in the gate's frame of the observation where the call began."""
  frame: GateFrame
  coder: tiles_mod.TileCoder


@dataclasses.dataclass(frozen=True)
class GateLocalGoal:
  """LocalGoal in the gate's frame of the observation where the call began."""
  frame: GateFrame
  max_steps: int = 300


@dataclasses.dataclass(frozen=True)
class GatePoint:
  """A `Child`'s binding: a point of the field, (px, py), fixed in the frame of the gate
  the observation holds when the parent calls (`GateFrame`), `lateral_m` across it (to
  the gate's starboard, negative to port) and `along_m` along its heading (negative:
  before it); `kinds.gate_point`. Each style of approach one point, one subtask."""
  frame: GateFrame
  lateral_m: float = 0.0
  along_m: float = 0.0


@dataclasses.dataclass(frozen=True)
class ShipPoint:
  """A `Child`'s binding: a point of the field, (px, py), fixed where the ship is when the
  parent calls, `ahead_m` along its heading and `starboard_m` across it (negative: to
  port); `kinds.gate_point`. A detour the parent may choose. With `within_m` > 0 the
  point is moved, coordinate by coordinate, to lie at least `within_m` inside the
  field's edges (a detour never leads off the field)."""
  ahead_m: float = 0.0
  starboard_m: float = 0.0
  within_m: float = 0.0


@dataclasses.dataclass(frozen=True)
class GatePoints:
  """The route's targets by number (`ship_rules.target_of`): 0 the point of the gate,
  its posts moved in by `inset_m`, nearest the ship; 1-3 points `approach_m` before
  the gate line on the side where the call began; a TargetReached ends a call
  within `radius_m` of an approach point."""
  inset_m: float = 2.0
  approach_m: float = 80.0
  radius_m: float = 15.0


@dataclasses.dataclass(eq=False)
class AimTiles:
  """The aim subtask's state towards its target (`ship_rules.aim_view`), coded by
  `coder`: heading error on a "sqrt" or "linear" `error_scale`, turning rate,
  distance; errors beyond `reflect_deg` (180: never) to the negative side reflected."""
  coder: tiles_mod.TileCoder
  targets: GatePoints = GatePoints()
  error_scale: str = "sqrt"
  reflect_deg: float = 180.0

  def __post_init__(self):
    if self.error_scale not in ("sqrt", "linear"):
      raise ValueError(f"AimTiles: error_scale {self.error_scale!r}; allowed: 'sqrt', 'linear'")
    if not 0.0 <= self.reflect_deg <= 180.0:
      raise ValueError(f"AimTiles: reflect_deg = {self.reflect_deg!r}; allowed: 0 to 180")


@dataclasses.dataclass(frozen=True)
class NearGateLine:
  """A node's available children: all within `within_m` of the gate line, else only
  its first (an option's initiation set)."""
  within_m: float = 1000.0


@dataclasses.dataclass(frozen=True)
class PatrolCell:
  """The patrol root's state (`ship_rules.root_state`): the 50 m cell of (x, y) or,
  within `near_gate_m` of the gate's centre, a `near_gate_cell_m` cell; times
  `heading_sectors` sectors of the heading."""
  heading_sectors: int = 1
  near_gate_m: float = 0.0
  near_gate_cell_m: float = 25.0

  def n_states(self):
    """The number of states it gives: the cells times the heading's sectors."""
    return ship_rules.n_root_cells(self.near_gate_m, self.near_gate_cell_m) * self.heading_sectors




@dataclasses.dataclass(frozen=True)
class TaxiState:
  """A QTable's view of the taxi: the full state's index (`taxi_core.encode_state`),
  in a machine built with the taxi's world."""


TAXI_SUBTASKS = ("root", "get", "put", "refuel", "navigate")


def _taxi_subtask(block):
  if block.subtask not in TAXI_SUBTASKS:
    raise ValueError(f"{type(block).__name__}: subtask {block.subtask!r} is not a taxi "
                     f"subtask; allowed: {list(TAXI_SUBTASKS)}")


@dataclasses.dataclass(frozen=True)
class TaxiAbstraction:
  """A table's view of the taxi: the abstract state of one of the taxi hierarchy's
  subtasks (`hierarchy.taxi_subtasks`; Navigate's includes its target)."""
  subtask: str
  __post_init__ = _taxi_subtask


@dataclasses.dataclass(frozen=True)
class TaxiChildren:
  """The children available to a taxi subtask in a state (its `available`)."""
  subtask: str
  __post_init__ = _taxi_subtask


@dataclasses.dataclass(frozen=True)
class TaxiEnd:
  """A taxi subtask's termination (a success when it ends by it)."""
  subtask: str
  __post_init__ = _taxi_subtask


@dataclasses.dataclass(frozen=True)
class TaxiTarget:
  """A `Child`'s binding: Navigate's target t, the station that Get, Put or Refuel
  (`subtask`) goes to: the passenger's, the destination, or F."""
  subtask: str
  __post_init__ = _taxi_subtask


@dataclasses.dataclass(frozen=True)
class Never:
  """Ends only with the episode."""


@dataclasses.dataclass(frozen=True)
class LocalGoal:
  """The ship's local subtask's end: success, frame left, or `max_steps` steps."""
  max_steps: int = 300


@dataclasses.dataclass(frozen=True)
class Clock:
  """A continuing root's end: a record row of `steps` primitive steps, ended between
  its children's calls (the row in which a call starts holds it)."""
  steps: int = 6000


@dataclasses.dataclass(frozen=True)
class TargetReached:
  """An AimTiles node's end (`ship_rules.aim_outcome`); `max_steps` control steps,
  then a failure."""
  max_steps: int = 600






@dataclasses.dataclass(frozen=True)
class Shaping:
  """G: the heading shaping towards the subtask's goal, times `weight` (1 with a
  LocalGoal), and the local +100 / -100 (SPEC section 3)."""
  weight: float = 1.0


@dataclasses.dataclass(frozen=True)
class HeldEpsilon:
  """The root's epsilon schedule (SPEC section 3), watching the named nodes' runs."""
  epsilon: float = 0.1
  watch: tuple = ()
  threshold: float = 0.8
  window: int = 1000
  every: int = 50
  divisor: float = 1.01
  per_decision: bool = False


@dataclasses.dataclass(frozen=True)
class LinearEpsilon:
  """Epsilon decayed linearly from `start` to `end` over the first `episodes` learning
  episodes (`end` from then on), for the QTables with `epsilon_schedule=True`."""
  start: float = 0.1
  end: float = 0.0
  episodes: int = 50_000


# The earlier machine's rules of (obs, origin, arg, steps), and what replaced them.
_EARLIER_RULES = {"CellRule": "Abstraction", "EndRule": "Termination",
                  "RewardRule": "InternalReward"}


def __getattr__(name):
  if name in _EARLIER_RULES:
    raise AttributeError(f"hpg_mj.hierarchy.blocks.{name} is gone: write "
                         f"hpg_mj.hierarchy.kinds.rules.{_EARLIER_RULES[name]}(rule), the rule "
                         "taking (obs, call) (call.origin, call.steps, its arguments by name)")
  raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
