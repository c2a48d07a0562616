"""A route past the paper's (SPEC section 8): a root that sees
its cell and the ship's coarse heading, and chooses a point to steer to; one
low-level subtask, *aim*, that steers straight to a continuous target.

Why: the paper's root can only chain whole 100 / 141 m legs along eight compass
directions, and each leg begins by turning onto its direction (SPEC section 2:
~265-270 control steps against the ~205-step straight line). Here the root has
four choices: *gate*, steer to the point of the gate nearest the ship (a
continuous target, followed as the ship moves), or one of three *approach*
points before the gate line on the ship's side (for starts from which the
straight line to the gate runs along its line or past its posts). One call sails
the whole way from most starts. The root sees its cell and the heading's sector,
through several offset tilings of them (Q(lambda) linear in the tiles,
`qlambda.tiled_update`): why, see `tasks/ship_hybrid_beyond.toml` (with a table of
cells, the value of a choice the root had stopped making stayed where a few early
returns had put it, far below what it would now earn).

The *aim* subtask's state is the heading error to its target (wrapped), the
turning rate and the distance (clipped), over a CMAC, with errors beyond
`reflect_deg` on one side reflected onto the other (the turning rate negated, and
the policy's r with it), so that one set of tiles learns every large turn and the
ship turns the short way round; its policy is the paper's
Gaussian with sigmoid, learned by Eq. 3 with R + G (G the paper's heading shaping
towards the target, +100 within `radius` of it or through the gate, -100 off the
field or after `max_steps`), the discounted trace and the learned baseline b(s)
of `ship_hybrid`, and optionally the learned exploration width
(`policies.gaussian_choose` with a width). The map from the world to this state is an
isometry of Equation 1 (a translation and a rotation, and for the reflected
errors a reflection with r -> -r), as SPEC section 3 asks of the paper's local
frames. Only the -1s, the gate's reward and the field's penalty
reach the root (Watkins's Q(lambda) over the SMDP of calls, as the hybrid's).

Its compiled rules are `hpg_mj.hierarchy.ship_rules`' (the targets, the aim state
and its end), run as blocks (kinds `tiled_q`, `gate_route`) by the open machine
(`hierarchy.program`).
"""
import dataclasses
import math

from hpg_mj.agents import _ship
from hpg_mj.agents import hierarchy
from hpg_mj.taskfile import param
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy import ship_rules
from hpg_mj.hierarchy.graph import Child, Primitive, Subtask, TaskGraph
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core as core

SHIPPED = ship_rules.SHIPPED_TARGETS


# ---- the task file's schema --------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Root:
  """[root]: Watkins's Q(lambda) over tiles of (position, heading), choosing a target."""
  learner: str = param("q_lambda", "the root's learner", choices=("q_lambda",))
  alpha: float = param(0.1, "Q(lambda) step size", low=0, low_open=True)
  trace_decay: float = param(0.9, "Q(lambda)'s lambda", low=0, high=1)
  epsilon: float = param(0.3, "exploration, held until the aim subtask passes "
                         "epsilon_threshold", low=0, high=1)
  epsilon_threshold: float = param(0.8, "aim success rate over epsilon_window runs that "
                                   "starts the decay", low=0, high=1)
  epsilon_window: int = param(1000, "aim runs the threshold looks at", low=1)
  epsilon_every: int = param(50, "episodes between divisions of epsilon", low=1)
  epsilon_divisor: float = param(1.01, "epsilon is divided by this", low=1)
  cell_m: float = param(50.0, "side of the root's square cells (m)", low=10, high=1000)
  headings: int = param(8, "sectors of the heading the root sees (1: none)", low=1, high=72)
  tilings: int = param(1, "tilings of the cells and sectors, each offset by k/tilings of a "
                       "tile (1: the table; more: Q generalises between neighbours and "
                       "resolves finer)", low=1, high=64)
  inset_m: float = param(SHIPPED.inset_m, "the gate action aims at the gate with its posts moved in "
                         "by this (m)", low=0, high=49)
  approach_m: float = param(SHIPPED.approach_m, "how far before the gate line the approach points lie (m)",
                            low=0, low_open=True, high=300)
  approach_within_m: float = param(1000.0, "the approach points are offered only within "
                                   "this distance of the gate line (1000: everywhere); "
                                   "beyond it the root's one choice is the gate", low=0,
                                   high=1000)


@dataclasses.dataclass(frozen=True)
class LowLevel:
  """[low_level]: the aim subtask, learned by Eq. 3."""
  learner: str = param("policy_gradient", "Eq. 3", choices=("policy_gradient",))
  alpha: float = param(0.01, "Eq. 3 step size", low=0, low_open=True)
  trace_gamma: float = param(0.99, "discount on the Eq. 3 trace (1 = plain Eq. 3)", low=0,
                             high=1, low_open=True)
  baseline: float = param(0.3, "TD(0) step size of a baseline b(s) over the policy's tiles "
                          "(0: none)", low=0, high=1)
  width_alpha: float = param(0.0, "Eq. 3 step size of the learned exploration width "
                             "log sigma(s) (0: the paper's sigma = 1)", low=0)
  sigma_low: float = param(0.25, "the learned width's lower clip", low=0, low_open=True,
                           high=1)
  sigma_high: float = param(1.0, "the learned width's upper clip", low=1, high=100)
  shaping: float = param(1.0, "weight of the heading shaping G (1: SPEC section 3's G, "
                         "0: none)", low=0, high=10)
  radius_m: float = param(SHIPPED.radius_m, "within this distance of its target a call has succeeded",
                          low=0, low_open=True)
  error_scale: str = param("sqrt", "the heading error's scale on the tiles: sqrt (finer "
                           "near 0) or linear", choices=("sqrt", "linear"))
  tilings: int = param(9, "CMAC tilings", low=1)
  reflect_deg: float = param(180.0, "beyond this heading error (deg) on the ship's negative "
                             "side the aim state is reflected to the positive side (180: "
                             "never)", low=0, high=180)
  tiles: tuple = param((36, 6, 4), "tiles per tiling over heading error (wraps; reflected, "
                       "over [-reflect_deg, 180], not wrapping), turning rate, distance",
                       length=3, low=1)
  max_steps: int = param(600, "control steps, then the call has failed", low=1)


@dataclasses.dataclass(frozen=True)
class Config:
  """The task file's schema: its sections [environment], [root] and [low_level]."""
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)
  root: Root = dataclasses.field(default_factory=Root)
  low_level: LowLevel = dataclasses.field(default_factory=LowLevel)


def root_coder(root):
  """The root's tiles over (x, y, heading): `cell_m` squares and `headings` sectors
  (the first centred on north), `tilings` of them offset along SPEC section 3's
  displacement. One tiling is the table of cells and sectors."""
  grid = int(math.ceil(core.FIELD_SIZE / root.cell_m))
  half = 180.0 / root.headings
  side = grid * root.cell_m
  return tiles_mod.TileCoder((0.0, 0.0, -half), (side, side, 360.0 - half),
                             (grid, grid, int(root.headings)), (False, False, True),
                             int(root.tilings))


def aim_coder(low):
  """The aim state's tiles: heading error (wrapping; reflected, over [-reflect_deg,
  180] on its scale), turning rate, distance."""
  reflected = low.reflect_deg < 180.0
  low_error = -ship_rules.error_coordinate(low.reflect_deg, low.error_scale)
  return tiles_mod.TileCoder((low_error, -core.MAX_TURN_RATE, 0.0),
                             (180.0, core.MAX_TURN_RATE, ship_rules.DISTANCE_CLIP),
                             tuple(low.tiles), (not reflected, False, False), low.tilings)


class ShipBeyond(hierarchy.ShipHierarchy):
  """A root over (cell, heading) that picks points; an aim subtask that steers there.
  Its state by node name (`root.q`, `aim.theta`, `aim.values`, `schedule.state`, ...)."""

  name = "ship_beyond"
  Config = Config
  record_fields = ("passed", "steps", "calls", "aim_runs", "aim_successes", "return")

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    root, low = self.config.root, self.config.low_level
    blocks.check_width(low.width_alpha, low.sigma_low, low.sigma_high, "[low_level]")
    self.coder = aim_coder(low)
    self.root_coder = root_coder(root)
    self.root = blocks.TiledQTable(self.root_coder, root.alpha, root.trace_decay, root.epsilon,
                                   epsilon_schedule=True)
    self.low = blocks.GaussianCMAC(self.coder, low.alpha, low.trace_gamma, low.baseline,
                                   core.MAX_TURN_RATE, low.width_alpha, low.sigma_low,
                                   low.sigma_high)

  def graph(self):
    """The root (Q(lambda) over tiles of position and heading) chooses a target; aim
    steers there (Eq. 3 over the tiles of its error, turning rate and distance)."""
    root, low = self.config.root, self.config.low_level
    targets = blocks.GatePoints(root.inset_m, root.approach_m, low.radius_m)
    return TaskGraph("root", [
        Subtask("root", learner=self.root, view=blocks.StateTiles(self.root_coder),
                available=blocks.NearGateLine(root.approach_within_m),
                termination=blocks.Never(),
                children=[Child("aim", target=a) for a in range(ship_rules.N_TARGETS)]),
        Subtask("aim", children=["turn"], learner=self.low,
                view=blocks.AimTiles(self.coder, targets, low.error_scale, low.reflect_deg),
                termination=blocks.TargetReached(low.max_steps),
                internal_reward=blocks.Shaping(low.shaping), reward=blocks.STEP),  # the -1s
        Primitive("turn"),
    ], schedule=blocks.HeldEpsilon(root.epsilon, ("aim",), root.epsilon_threshold,
                                   root.epsilon_window, root.epsilon_every,
                                   root.epsilon_divisor))

  def metrics(self, record):
    """The ship's metrics, with calls per episode and the aim subtask's success rate
    over the last `metric_window` episodes."""
    out = super().metrics(record)
    w = record[-self.metric_window:]
    runs = w["aim_runs"].sum()
    out.update({
        "calls_per_episode": float(w["calls"].mean()) if len(w) else None,
        "aim_success_rate": float(w["aim_successes"].sum() / runs) if runs else None,
    })
    return out
