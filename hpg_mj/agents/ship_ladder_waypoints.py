"""Waypoints on the regatta (SPEC section 11): a designed hierarchy of one parameterized
subtask, the open machine's arguments bound at call time (`hierarchy.kinds.base`: a
`Child`'s binding), beside the paper's Figure 3 carried to the ladder
(`ship_ladder_hybrid`). It comes from a newcomer's hierarchy built on the public API
alone, which finished most courses at medium and hard where the hybrid passed almost no
gate; it is not the paper's design.

  root                 Q(lambda) on a table (`blocks.QTable`, the hybrid root's learner,
                       its held epsilon watching the approach's runs) over 96 states of
                       the next gate as the ship sees it (`root_state`: 8 sectors of its
                       bearing x 3 bands of its distance x 4 quadrants of its heading
                       relative to the ship's), choosing among four styles of approach,
                       each a call of the one shared subtask
  approach(px, py)     steers to the point (px, py) its call binds
                       (`blocks.GatePoint`, in the next gate's frame when the root
                       calls): the gate's centre, a point `lateral_m` to either side
                       across it, a line-up point `lineup_m` before it. A Gaussian-with-
                       sigmoid CMAC policy (Eq. 3) over (heading error to the point,
                       turning rate) (`aim`); the call succeeds when a gate is passed or
                       the ship is within 20 m of the point, fails after 150 control
                       steps (`reached`); its pseudo-reward +20 / -20, and -200 for
                       leaving the field (`pseudo`: that ends the episode, and so the
                       call, before its 150 steps, which would otherwise pay)

Its rules read the next gate as the regatta's observation gives it (`envs.ship_regatta`:
at 4-6 as [ahead, starboard, heading less the ship's], the gates left at 10); on the
goal and the current the one gate is seen so from the observation (`SEEN_GATES`: the
goal's desired goal at 8-11, the current's fixed gate of SPEC section 2), and the pass,
which ends the episode, ends the call with it. The approach's points are in that gate's
frame (`_ladder.GATE_FRAMES`; the current's gate stands still, so its points are
numbers).

On the harbour, whose obstacles wreck a ship that only aims, three things change (the
map is fixed, the gate is the steering task's): the root reads where the ship is, its
50 m cell and heading quadrant (`harbour_state`, 1,600 states: the map is learned as
the hybrid's root learns it); its styles are the gate's centre, a line-up point
`lineup_m` before and one after it, and three detours fixed where the ship is when the
root calls (`blocks.ShipPoint`: `DETOURS`, 100 m ahead and 100 m to either side, 150 m
dead ahead, each kept `detour_within_m` inside the field's edges, so that near an edge
a detour leads back in); and the approach also reads the clearance ahead, the nearest of the three
forward rangefinders (`aim_clear`, over a third tile dimension), so that it learns to
swerve, its pseudo-reward -200 where the ship ran aground as where it left the field
(`HARBOUR_PSEUDO`).
"""
import collections
import dataclasses
import math

import numba

from hpg_mj import taskfile
from hpg_mj.agents import _ladder
from hpg_mj.agents import hierarchy
from hpg_mj.agents import ship_hybrid
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import Child, Primitive, Subtask, TaskGraph
from hpg_mj.hierarchy.kinds import gate_frame
from hpg_mj.hierarchy.kinds import grid_cell
from hpg_mj.hierarchy.kinds.rules import Abstraction, Features, InternalReward, Termination
from hpg_mj.learners import tiles
from hpg_mj.taskfile import param
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_harbour_core as harbour_core

N_ROOT_STATES = 8 * 3 * 4        # bearing sectors x distance bands x heading quadrants
NEAR_M, FAR_M = 60.0, 200.0      # the root's distance bands' bounds
RADIUS_M = 20.0                  # the approach succeeds within this of its point
APPROACH_STEPS = 150             # control steps, then the approach has failed
SUCCESS_G, LEFT_G = 20.0, -200.0  # the approach's pseudo-reward: +-20, and leaving the field
_JIT = dict(cache=True, error_model="numpy")


# ---- the next gate, as each task's observation shows it ---------------------------------

@numba.njit(**_JIT)
def seen_from(obs, gx, gy, s, c):
  """[ahead, starboard, heading less the ship's] of the gate at (gx, gy) heading (sine s,
  cosine c), as the regatta's observation gives its next gate (`ship_regatta_core`)."""
  rad = math.radians(obs[2])
  sin, cos = math.sin(rad), math.cos(rad)
  dx, dy = gx - obs[0], gy - obs[1]
  return (dx * sin + dy * cos, dx * cos - dy * sin,
          core.wrap_deg(math.degrees(math.atan2(s, c)) - obs[2]))


@numba.njit(**_JIT)
def regatta_gate(obs):
  """The regatta's next gate, as its observation gives it, and the gates left."""
  return obs[4], obs[5], obs[6], obs[10]


@numba.njit(**_JIT)
def goal_gate(obs):
  """The goal's gate, its desired goal [x, y, sin, cos] at 8-11; one gate left (its pass
  ends the episode)."""
  ahead, starboard, heading = seen_from(obs, obs[8], obs[9], obs[10], obs[11])
  return ahead, starboard, heading, 1.0


@numba.njit(**_JIT)
def current_gate(obs):
  """The current's gate, the steering task's fixed one (SPEC section 2): its centre
  (400, 400), heading north; one gate left (its pass ends the episode)."""
  ahead, starboard, heading = seen_from(obs, gate_frame.CENTRE_X, gate_frame.CENTRE_Y,
                                        0.0, 1.0)
  return ahead, starboard, heading, 1.0


# The tasks the waypoints sail, and how each one's observation shows the next gate: a
# function of the observation -> (ahead_m, starboard_m, heading less the ship's in deg,
# the gates left), which the rules of `_rules` read.
SEEN_GATES = {"ship_current": current_gate, "ship_goal": goal_gate,
              "ship_regatta": regatta_gate, "ship_harbour": current_gate}


# ---- the rules -----------------------------------------------------------------------

@numba.njit(**_JIT)
def gate_state(ahead, starboard, heading):
  """The root's state of the next gate seen so: 8 sectors of its bearing from the bow x
  3 bands of its distance (60 m, 200 m) x 4 quadrants of its heading relative to the
  ship's."""
  bearing = math.degrees(math.atan2(starboard, ahead))        # -180..180, 0 dead ahead
  sector = min(int((bearing + 180.0) // 45.0), 7)
  d = math.hypot(ahead, starboard)
  band = 0 if d < NEAR_M else (1 if d < FAR_M else 2)
  quadrant = min(int(((heading + 180.0) % 360.0) // 90.0), 3)
  return (sector * 3 + band) * 4 + quadrant


Rules = collections.namedtuple("Rules", ("root_state", "reached"))
Rules.__doc__ = """The rules that read the next gate, compiled for one task."""


def _rules(world, seen):
  """The root's state and the approach's end on the task `world`, whose observation
  `seen` reads (`SEEN_GATES`); each named for its task, so that a graph's compiled
  module (`hierarchy.graph_module`, named by its rules' names) is the task's own."""

  def root_state(obs, call):
    """The root's state (`gate_state`) of the next gate the observation shows."""
    ahead, starboard, heading, _ = seen(obs)
    return gate_state(ahead, starboard, heading)

  def reached(obs, call):
    """The approach's end: 1 when a gate was passed during the call (fewer gates left
    than where it began) or the ship is within 20 m of its point; -1 after 150 control
    steps."""
    if seen(obs)[3] < seen(call.origin)[3]:
      return 1
    if math.hypot(call.px - obs[0], call.py - obs[1]) < RADIUS_M:
      return 1
    return -1 if call.steps >= APPROACH_STEPS else 0

  # Not cached on their own: a closure's key in numba's cache holds the function it
  # captured, which differs in every process; the graph's module, which calls them,
  # caches their machine code with its own.
  for rule in (root_state, reached):
    rule.__qualname__ = f"{rule.__name__}_{world}"
  return Rules(*(numba.njit(error_model="numpy")(rule) for rule in (root_state, reached)))


RULES = {world: _rules(world, seen) for world, seen in SEEN_GATES.items()}


@numba.njit(**_JIT)
def aim(obs, call):
  """The approach's view: the heading error to (call.px, call.py) in degrees (wrapped),
  and the turning rate."""
  bearing = math.degrees(math.atan2(call.px - obs[0], call.py - obs[1]))
  return ((obs[2] - bearing + 180.0) % 360.0 - 180.0, obs[3])


@numba.njit(**_JIT)
def pseudo(obs, call, event):
  """The approach's G: +20 on success, -20 on failure, -200 off the field (which ends the
  episode, and so the call, before its 150 steps: without it, leaving pays)."""
  if not (0.0 <= obs[0] <= core.FIELD_SIZE and 0.0 <= obs[1] <= core.FIELD_SIZE):
    return LEFT_G
  return SUCCESS_G * event


# ---- the harbour: the map fixed, obstacles to clear --------------------------------------

N_HARBOUR_STATES = 20 * 20 * 4   # the ship's 50 m cell x its heading quadrant
DETOURS = ((100.0, -100.0), (100.0, 100.0), (150.0, 0.0))  # (ahead, starboard) of the ship, m
# The observation's places of the rangefinders at -30, 0 and +30 degrees (after the ship's 4).
PORT_RAY, AHEAD_RAY, STARBOARD_RAY = (4 + harbour_core.BEARINGS_DEG.index(b)
                                      for b in (-30.0, 0.0, 30.0))


@numba.njit(**_JIT)
def harbour_state(obs, call):
  """The root's state on the harbour: the ship's 50 m cell (`grid_cell`) x its heading's
  quadrant."""
  quadrant = min(int(((obs[2] + 180.0) % 360.0) // 90.0), 3)
  return grid_cell.grid_cell(obs[0], obs[1], 50.0, 20) * 4 + quadrant


@numba.njit(**_JIT)
def aim_clear(obs, call):
  """The approach's view on the harbour: `aim`'s, and the clearance ahead in m (the
  nearest of the rangefinders at -30, 0 and +30 degrees)."""
  error, rate = aim(obs, call)
  return (error, rate, min(obs[PORT_RAY], min(obs[AHEAD_RAY], obs[STARBOARD_RAY])))


def _harbour_pseudo(level):
  """The approach's G on the harbour at `level`: `pseudo`'s, and -200 where the ship lies
  on an obstacle (ran aground, which ends the episode); named for its level."""
  islands, piers = harbour_core.level_shapes(level)

  def harbour_pseudo(obs, call, event):
    if harbour_core.inside(obs[0], obs[1], islands, piers):
      return LEFT_G
    return pseudo(obs, call, event)
  harbour_pseudo.__qualname__ = f"harbour_pseudo_{level}"
  return numba.njit(error_model="numpy")(harbour_pseudo)


HARBOUR_PSEUDO = {level: _harbour_pseudo(level) for level in harbour_core.LEVELS}


# ---- the task file ---------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class WaypointsEnvironment(_ladder.LadderEnvironment):
  """[environment]: the ladder's (`agents._ladder`), on a task whose next gate the rules
  see (`SEEN_GATES`): the current, the goal, the regatta or the harbour."""
  world: str = param("ship_regatta", "the ladder's task, whose next gate the rules see",
                     choices=tuple(SEEN_GATES))


@dataclasses.dataclass(frozen=True)
class Root(ship_hybrid.Root):
  """[root]: the hybrid's root (Watkins's Q(lambda) over the SMDP of calls, its held
  epsilon), and where the styles of approach put their points."""
  lateral_m: float = param(30.0, "the points to either side across the gate, m (not on "
                           "the harbour)", low=0)
  lineup_m: float = param(80.0, "the line-up point before the gate (the harbour: and one "
                          "after it), m", low=0)
  detour_within_m: float = param(60.0, "the harbour's: each detour moved to lie at least "
                                 "this far inside the field's edges, m (0: not moved; a "
                                 "file without the key, written before it: 0)",
                                 low=0, high=400, absent=0.0)


@dataclasses.dataclass(frozen=True)
class Approach(taskfile.Section):
  """[approach]: the shared approach(px, py), learned by Eq. 3 over its CMAC."""
  alpha: float = param(0.005, "Eq. 3 step size", low=0, high=1, low_open=True)
  trace_gamma: float = param(0.99, "discount on the Eq. 3 trace", low=0, high=1,
                             low_open=True)
  baseline: float = param(0.3, "TD(0) step size of a baseline b(s) over the policy's tiles "
                          "(0: none)", low=0, high=1)
  tilings: int = param(9, "CMAC tilings", low=1)
  tiles: tuple = param((12, 6), "tiles per tiling over the heading error, turning rate",
                       length=2, low=1)
  clearance_tiles: int = param(4, "the harbour's: tiles over the clearance ahead, 0 to "
                               "150 m", low=1)


@dataclasses.dataclass(frozen=True)
class Config:
  """The task file's schema: [environment] (the task and its level), [root] and
  [approach]."""
  environment: WaypointsEnvironment = dataclasses.field(
      default_factory=WaypointsEnvironment)
  root: Root = dataclasses.field(default_factory=Root)
  approach: Approach = dataclasses.field(default_factory=Approach)


def coder(approach, world=None):
  """The approach's CMAC over (heading error, turning rate), [approach]'s tiles; on the
  harbour also over the clearance ahead."""
  if world == "ship_harbour":
    return tiles.TileCoder((-180.0, -core.MAX_TURN_RATE, 0.0),
                           (180.0, core.MAX_TURN_RATE, harbour_core.MAX_RANGE_M),
                           (*approach.tiles, approach.clearance_tiles), (True, False, False),
                           approach.tilings)
  return tiles.TileCoder((-180.0, -core.MAX_TURN_RATE), (180.0, core.MAX_TURN_RATE),
                         tuple(approach.tiles), (True, False), approach.tilings)


# ---- the agent --------------------------------------------------------------------------

class ShipLadderWaypoints(hierarchy.ShipLadderHierarchy):
  """The root over styles of approach and the shared approach(px, py) (the module
  docstring), run by the open machine fused with its task's world and step by step
  through its environments; its state by node name (`root.q`, `approach.theta`, ...,
  `schedule.state`)."""

  name = "ship_ladder_waypoints"
  Config = Config
  record_fields = ("passed", "steps", "gates", "calls", "approach_runs",
                   "approach_successes", "return")

  def __init__(self, config=None, seed=0, task=None):
    # (Another world is refused as its [environment] is made: `WaypointsEnvironment`'s
    # choices, from a task file or in Python.)
    super().__init__(config, seed, task)
    root, approach = self.config.root, self.config.approach
    self.harbour = self.config.environment.world == "ship_harbour"
    self.coder = coder(approach, self.config.environment.world)
    self.root = blocks.QTable(N_HARBOUR_STATES if self.harbour else N_ROOT_STATES,
                              alpha=root.alpha, trace_decay=root.trace_decay,
                              epsilon=root.epsilon, epsilon_schedule=True)
    self.approach = blocks.GaussianCMAC(self.coder, approach.alpha, approach.trace_gamma,
                                        approach.baseline, core.MAX_TURN_RATE)

  def styles(self):
    """The root's children, each a call of the approach to a point in the next gate's
    frame (`blocks.GatePoint`, `_ladder.GATE_FRAMES`): the gate's centre, `lateral_m` to
    port and to starboard across it, `lineup_m` before it. The current's gate stands
    still, so its points are the same numbers at every call. On the harbour: the
    centre, `lineup_m` before and after it, and the `DETOURS` (`blocks.ShipPoint`, kept
    `detour_within_m` inside the field)."""
    world, r = self.config.environment.world, self.config.root
    frame = _ladder.GATE_FRAMES[world]
    if self.harbour:                # the centre, a line-up point either side, the detours
      return [Child("approach", px=gate_frame.CENTRE_X, py=gate_frame.CENTRE_Y + along)
              for along in (0.0, -r.lineup_m, r.lineup_m)] + [
          Child("approach", bind=blocks.ShipPoint(ahead, starboard, r.detour_within_m))
          for ahead, starboard in DETOURS]
    offsets = [{}, {"lateral_m": -r.lateral_m}, {"lateral_m": r.lateral_m},
               {"along_m": -r.lineup_m}]
    if frame is not None:
      return [Child("approach", bind=blocks.GatePoint(frame, **o)) for o in offsets]
    # `kinds.gate_point`'s point of the gate at (400, 400) heading north (sine 0, cosine 1).
    return [Child("approach", px=gate_frame.CENTRE_X + o.get("lateral_m", 0.0),
                  py=gate_frame.CENTRE_Y + o.get("along_m", 0.0)) for o in offsets]

  def graph(self):
    """root -> approach(px, py) x its styles -> the turning rate (the module docstring)."""
    r, env = self.config.root, self.config.environment
    rules = RULES[env.world]
    root_view, view, g = rules.root_state, aim, pseudo
    if self.harbour:
      root_view, view, g = harbour_state, aim_clear, HARBOUR_PSEUDO[env.level]
    return TaskGraph("root", [
        Subtask("root", children=self.styles(), learner=self.root,
                view=Abstraction(root_view), termination=blocks.Never()),
        Subtask("approach", children=["turn"], learner=self.approach, view=Features(view),
                termination=Termination(rules.reached), internal_reward=InternalReward(g),
                reward=blocks.STEP),            # only the -1s
        Primitive("turn"),                      # the turning rate r, drawn by the approach
    ], schedule=blocks.HeldEpsilon(r.epsilon, ("approach",), r.epsilon_threshold,
                                   r.epsilon_window, r.epsilon_every, r.epsilon_divisor))

  def metrics(self, record):
    """The task's benchmark metrics (`ShipLadderHierarchy`), with the approach's calls
    per episode and its success rate over the last `metric_window` episodes."""
    w = record[-self.metric_window:]
    runs = w["approach_runs"].sum()
    return {**super().metrics(record),
            "calls_per_episode": float(w["calls"].mean()) if len(w) else None,
            "approach_success_rate": float(w["approach_successes"].sum() / runs)
                                     if runs else None}
