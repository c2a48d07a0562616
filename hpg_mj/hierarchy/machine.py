"""One compiled Algorithm 1 for any task graph built from blocks (`hierarchy.blocks`).

A task graph whose subtasks' learners, views, terminations and internal rewards
are blocks is data: `Machine(graph)` turns it into arrays (the node table, each
learner kind's parameters stacked in one bank, the call stack) and the compiled
functions below run it. The same functions serve both paths:

* fused with a compiled world (`Machine.run`, the analytic ship; `Machine.run_continuing`,
  its continuing task's record rows; `Machine.run_taxi`, the taxi): the world's step
  and the machine's `step` alternate inside one compiled loop;
* resumable under any environment (`Machine.run_stepwise`, `Machine.begin` and
  `Machine.advance(obs, reward, terminated, truncated, info) -> action`): the
  environment steps in Python and the machine takes each outcome,

so a graph gives the same numbers bit for bit on both, and a user's graph trains
at the shipped agents' speed. The call stack is explicit (arrays indexed by
depth), which is what makes the machine resumable after every primitive step.

Algorithm 1 of the paper, line by line:

```
Function HPG(Task i, State s)                         -> call(d, node, arg, obs)
  if i is primitive: execute it, return its reward    -> descend() returns the action;
                                                         the world / environment steps
  while i has not terminated:                         -> step(): _end_of(d) ... done
    choose a with mu^i(s, theta^i)                    -> _choose(d): act (draws, and
                                                         z <- z + psi for Eq. 3)
    R = HPG(Task a, State s)                          -> rewards summed per level
                                                         (stack REWARD) until a returns
    observe s' and internal reward G^i(s'|s, a)       -> _end_of(d): event and G
    z, theta updates (Eq. 3)                          -> _observe(d, R + G)
```

Every subtask also returns when the episode ends (terminated or truncated); a
continuing root (a `Clock`) returns only by its clock, between its children's calls,
and a world's event (the patrol's gate pass or departure) ends the calls below it.
A subtask's *run* is a call that ended by its own termination; a call cut short
by the end of the episode is counted as a call but no run (`counters`).
"""
import collections
import math

import numba
import numpy as np
from numba import types
from numba.extending import overload

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy import rules as rules_mod
from hpg_mj.hierarchy import ship_rules
from hpg_mj.hierarchy.graph import Child, GraphError, Primitive, Subtask
from hpg_mj.learners import actor_critic
from hpg_mj.learners import arrays
from hpg_mj.learners import average_reward
from hpg_mj.learners import banks as banks_mod
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import jit
from hpg_mj.learners import policies
from hpg_mj.learners import qlambda
from hpg_mj.learners import schedules
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.hierarchy import taxi_subtasks
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import taxi_core
from hpg_mj.worlds import taxi_rules

# ---- the graph as arrays --------------------------------------------------------

# Node kinds, learner kinds, views, ends, internal rewards, rewards seen.
PRIMITIVE, SUBTASK = 0, 1
NO_LEARNER, Q_TABLE, GAUSSIAN_CMAC, ACTOR_CRITIC, GIBBS_TABLE, TILED_Q, AVERAGE_REWARD = range(7)
(NO_VIEW, VIEW_GRID_CELL, VIEW_LOCAL_TILES, VIEW_STATE_TILES, VIEW_RULE, VIEW_TAXI_STATE,
 VIEW_TAXI_ABSTRACT, VIEW_AIM_TILES, VIEW_PATROL_CELL) = range(9)
END_NEVER, END_LOCAL_GOAL, END_RULE, END_TAXI, END_TARGET, END_CLOCK = range(6)
OFFER_ALL, OFFER_NEAR_GATE = 0, 1
G_NONE, G_SHAPING, G_RULE = 0, 1, 2
SEEN_SUMMED, SEEN_STEP = 0, 1

# Columns of the node table (int64[n_nodes, N_INT]).
# VIEW_SLOT: a tiles view's coder, a CellRule's number among the graph's rules, or a
# TaxiAbstraction's subtask id (`taxi_subtasks`); END_AT and G_AT: an EndRule's and a
# RewardRule's number, or a TaxiEnd's subtask id; N_STATES: a table's states.
# WIDTH_SLOT: the row of a GaussianCMAC's learned width in GaussianBank.widths (-1: none).
# AVAILABLE_AT: the subtask id of a TaxiChildren (-1: every child is available).
# OFFER: how many of a TiledQTable's children a state offers (OFFER_ALL; OFFER_NEAR_GATE,
# a NearGateLine's).
(KIND, LEARNER, SLOT, VIEW, VIEW_SLOT, END, INTERNAL, SEEN, MAX_STEPS, FIRST_CHILD,
 N_CHILDREN, WATCH, EPS_SCHEDULE, CRITIC_SLOT, END_AT, G_AT, N_STATES, WIDTH_SLOT,
 AVAILABLE_AT, OFFER) = range(20)
N_INT = 20
# Columns of the node parameters (float64[n_nodes, N_FLOAT]); START_FRACTION, DELAY and
# RAMP: a GibbsTable's warm-up; INSET_M ... REFLECT_AT: an AimTiles' GatePoints and
# scale, SHAPING_WEIGHT: a Shaping's weight; WITHIN_M: a NearGateLine's; GAIN_STEP and
# PLANNING_EVERY: an RLearning's; SECTORS, NEAR_GATE_M, NEAR_GATE_CELL_M: a PatrolCell's.
(ALPHA, DECAY, GAMMA, BETA, R_MAX, EPSILON, CELL_M, GRID, ACTION, ALPHA_ACTOR, WIDTH_ALPHA,
 LOG_SIGMA_LOW, LOG_SIGMA_HIGH, START_FRACTION, DELAY, RAMP, INSET_M, APPROACH_M, RADIUS_M,
 SQRT_ERROR, REFLECT_AT, SHAPING_WEIGHT, WITHIN_M, GAIN_STEP, PLANNING_EVERY, SECTORS,
 NEAR_GATE_M, NEAR_GATE_CELL_M) = range(28)
N_FLOAT = 28
# Columns of the children table (int64[n_children, 3]): the child's node, its
# argument (`direction` or `target`; -1: none), the subtask id of its TaxiTarget
# binding (-1: none).
ARGUMENTS = ("direction", "target")
C_NODE, C_ARG, C_BIND = range(3)
# Columns of the per-node counters of an episode (float64[n_nodes, 3]).
CALLS, RUNS, SUCCESSES = range(3)
# Columns of a row of the machine's record (`run_ship`, `run_taxi`, `run_stepwise`): how
# the episode ended (the ship: passed the gate; the taxi: `taxi_rules`' outcome; a
# continuing ship's row: its gate passes), its primitive steps, its return, the
# taxi's illegal Pickups and Dropoffs (a continuing ship's row: its departures; else
# 0), then calls, runs and successes of each node.
ROW_END, ROW_STEPS, ROW_RETURN, ROW_ILLEGAL, ROW_COUNTERS = range(5)

# `rules`: the graph's user rules as one first-class function (`hierarchy.rules`).
# `calls`: the addresses of the functions the machine calls through `jit.call_at`
# (_FAR, in the order of CALL_STEP ...), set in each process (`Machine._link`).
# `world`: the taxi's world array (`taxi_rules.world_config`; empty in a ship machine).
Program = collections.namedtuple("Program", ("nodes", "params", "children", "rules", "calls",
                                             "world"))
CALL_STEP, CALL_CALL, CALL_DESCEND, CALL_OBSERVE, CALL_VIEW, CALL_GAUSSIAN = range(6)
# Each learner kind's parameters, one row per learner (slot). An actor-critic keeps its
# critic's trace in a GaussianBank row and its actor's weights in that row's values.
# An RLearning's gain [rho, greedy transitions] and its planning model (per entry the
# latest transition's next state, reward and duration; [transitions kept]) are rows of
# `gain` and `model_*` (`learners.average_reward`).
QBank = collections.namedtuple("QBank", ("q", "index", "value", "count", "gain", "model_next",
                                         "model_reward", "model_steps", "model_count"))
# The GibbsTables: a Trace's fields and the baseline's values per row, and each row's
# step size in this episode (alpha after its warm-up).
GibbsBank = collections.namedtuple("GibbsBank", ("theta", "zs", "y", "touched", "marked", "count",
                                                 "acc", "values", "alpha"))
# `widths`: the learned widths' traces, one row each (a Trace's fields), or None in a
# machine without any, whose code then does not hold the width's rule (`_width`).
GaussianBank = collections.namedtuple("GaussianBank", ("theta", "zs", "y", "touched", "marked",
                                                       "count", "acc", "values", "widths"))
# `dims`: the numbers each coder reads (a StateTiles reads the first dims of the state).
TileBank = collections.namedtuple("TileBank", ("low", "width", "n_tiles", "wrap", "offsets",
                                               "n_tilings", "dims"))
# The epsilon schedule (`learners.schedules`): its arrays and its settings, [threshold,
# every, divisor] of a held one, [start, end, episodes] of a linear one, after its kind.
Schedule = collections.namedtuple("Schedule", ("epsilon", "outcomes", "counts", "settings"))
HELD, LINEAR = 0, 1
SCHEDULE_KIND, LINEAR_START, LINEAR_END, LINEAR_EPISODES, PER_DECISION = 3, 4, 5, 6, 7
# The call stack and the episode: per depth d the node, its choice, its argument, its
# steps, the steps of its current child's run, its state (a table's) and the next;
# the reward of the current child's run, the action value chosen, (an actor-critic's
# m and u, below), the sign an AimTiles view puts on the drawn action, whether an
# RLearning's choice was greedy (1.0); the call's origin;
# its tiles (current, next; an actor-critic's critic tiles: current, next), score and
# a learned width's score; an actor-critic's mean m and draw u; the episode's [depth,
# steps, the root's argument, the root's event when it ended, the learning episodes
# before it], [return], per-node
# counters; scratch of the local frame and of (state, action); the positions sampled
# in the fused ship loop's step; the taxi's fused loop's state and episode
# (`taxi_rules`' int64[5], the state the taxi blocks read, and [3]); a GibbsTable's
# mask of available children and scratch (probabilities, score indices, scores); the
# run's flags (RUN_LEARN ...); the state a continuing ship restarts from after a
# departure (E_RESTART: pending); what the machine observes (`obs`: the fused ship's
# state, the taxi's state as float64 numbers, or the step-by-step path's observation,
# which `Machine._observation` writes) and the generator's state while a compiled
# entry point runs (`rng`, copied from the caller's and back). The machine's
# functions read these two from the stack rather than take them as arguments: each
# array passed was seven numbers pushed at every call, a sixth of a taxi step.
(S_NODE, S_CHOICE, S_ARG, S_STEPS, S_CHILD_STEPS, S_STATE, S_NEXT_STATE) = range(7)
F_REWARD, F_ACTION, F_MEAN, F_U, F_SIDE, F_GREEDY = range(6)
Stack = collections.namedtuple("Stack", ("ints", "floats", "origin", "tiles", "psi",
                                         "psi_width", "episode", "total", "counters", "local",
                                         "local_samples", "sa", "samples", "taxi", "mask",
                                         "probs", "index", "scores", "flags", "restart", "obs",
                                         "rng"))
E_DEPTH, E_STEPS, E_ROOT_ARG, E_EVENT, E_LEARNED, E_RESTART = range(6)
# The run's flags (the stack's `flags`): whether it learns, whether it samples its
# policies (else greedy); set by the Python side before each compiled call.
RUN_LEARN, RUN_SAMPLE = range(2)
# `extras`: None in a machine whose graph has none of the blocks in _EXTRA_KINDS (an
# ActorCritic, a user rule, the route's and the patrol's blocks), else 1. numba prunes
# a branch on `x is None` of an argument before typing it, so such a machine (the
# hybrid's, flat PGRL's, the taxi's, most users') compiles without their code: the
# route's and the patrol's blocks alone took a quarter of the hybrid's first compile.
# `world`: 1 in a machine with taxi blocks, whose world array (`taxi_rules.world_config`)
# is the program's `world`, else None (the same pruning: a ship graph holds no taxi
# code). Passed as the array, it was seven more numbers at every call of a taxi step.
_EXTRA_KINDS = ((LEARNER, (ACTOR_CRITIC, TILED_Q, AVERAGE_REWARD)),
                (VIEW, (VIEW_RULE, VIEW_AIM_TILES, VIEW_PATROL_CELL)),
                (END, (END_RULE, END_TARGET, END_CLOCK)), (INTERNAL, (G_RULE,)),
                (OFFER, (OFFER_NEAR_GATE,)))
Banks = collections.namedtuple("Banks", ("program", "q", "gibbs", "gaussian", "tiling",
                                         "schedule", "stack", "extras", "world"))


# ---- the compiled machine -------------------------------------------------------
# Its functions that are compiled on their own go without the C-callable wrapper numba
# adds to every function for a first-class function's use (no_cfunc_wrapper): nothing
# takes them so, and over nine banks each wrapper was ~18,000 characters of IR.

@numba.njit(cache=True, inline="always")
def _trace(g, slot):
  """The Eq. 3 trace of Gaussian learner `slot` (views of its bank's rows)."""
  return el.Trace(g.theta[slot], g.zs[slot], g.y[slot], g.touched[slot], g.marked[slot],
                  g.count[slot], g.acc[slot])


def _width(G, row):
  """The learned width's trace (`eligibility.Trace`) of the GaussianCMAC node `row`,
  or None when the machine has no learned width: numba then compiles the Eq. 3 rule
  without the width (`policies.gaussian_choose` prunes it), which keeps a third of
  the first compile off the graphs that do not use it."""


@overload(_width, inline="always")
def _width_typed(G, row):
  if isinstance(banks_mod.field_type(G, "widths"), types.NoneType):
    return lambda G, row: None

  def width(G, row):
    return _trace(G.widths, max(row[WIDTH_SLOT], 0))     # the widths hold a Trace's fields
  return width


def _reset_width(G, row):
  """z <- 0 on the node's learned width, if it has one."""


@overload(_reset_width, inline="always")
def _reset_width_typed(G, row):
  if isinstance(banks_mod.field_type(G, "widths"), types.NoneType):
    return lambda G, row: None

  def reset(G, row):
    if row[WIDTH_SLOT] >= 0:
      el.reset(_width(G, row))
  return reset


@numba.njit(cache=True, inline="always")
def _tiling(t, slot):
  k = t.n_tilings[slot]
  return tiles_mod.Tiling(t.low[slot], t.width[slot], t.n_tiles[slot], t.wrap[slot],
                          t.offsets[slot, :k])


@numba.njit(cache=True, inline="always")
def _gibbs_trace(B, slot):
  """The Eq. 3 trace of GibbsTable `slot` (views of its bank's rows)."""
  return el.Trace(B.theta[slot], B.zs[slot], B.y[slot], B.touched[slot], B.marked[slot],
                  B.count[slot], B.acc[slot])


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _taxi_seen(P, K, obs):
  """The state the taxi blocks read (`taxi_rules`' int64[5], K.taxi[0:5]) from `obs`,
  on the step-by-step path; the fused loop steps that state itself."""
  s = K.taxi[0:5]
  for i in range(4):
    s[i] = np.int64(obs[i])
  s[4] = np.int64(obs[4]) if P.world[taxi_rules.W_FUEL_ENABLED] != 0 else taxi_core.CLASSIC_FUEL


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _taxi_abstract(P, K, row, d):
  """The abstract state that the node at depth d (`row`) sees of the taxi
  (a TaxiAbstraction view)."""
  return taxi_subtasks.abstract_state(row[VIEW_SLOT], K.ints[d, S_ARG], K.taxi[0:5], P.world)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _step_sizes(P, B, K):
  """Each GibbsTable's step size in this episode: alpha times its warm-up at the
  learning episodes so far."""
  e = K.episode[E_LEARNED]
  for node in range(P.nodes.shape[0]):
    row = P.nodes[node]
    if row[LEARNER] == GIBBS_TABLE:
      p = P.params[node]
      fraction = p[START_FRACTION]
      if e >= p[DELAY]:
        rise = min(1.0, (e - p[DELAY] + 1.0) / p[RAMP])
        fraction += (1.0 - fraction) * rise
      B.alpha[row[SLOT]] = p[ALPHA] * fraction


@numba.njit(cache=True, inline="always")
def grid_cell(x, y, cell_m, grid):
  """The cell i * grid + j of (x, y) on a grid of `cell_m` cells, clamped to it."""
  i = min(max(int(x // cell_m), 0), grid - 1)
  j = min(max(int(y // cell_m), 0), grid - 1)
  return i * grid + j


# The ship's local blocks (LocalTiles, LocalGoal), chosen by type: none in a taxi
# machine (W, its world, not None), whose graph cannot hold them (Machine._ship_only).
# numba prunes a branch on `W is None` only where W is None, so a guard in the code
# left their rules (1.5 s of a taxi's first compile) in every taxi machine. Called,
# not inlined: numba compiles an overload's code on its own even where it inlines
# it, and these two were then compiled twice in every ship machine.

def _local_tiles(T, K, W, row, d, obs, which):
  """A LocalTiles view: the local frame of the call's origin and direction, tiled."""


@overload(_local_tiles)
def _local_tiles_typed(T, K, W, row, d, obs, which):
  if not isinstance(W, types.NoneType):
    return lambda T, K, W, row, d, obs, which: None

  def view(T, K, W, row, d, obs, which):
    tiling = _tiling(T, row[VIEW_SLOT])
    core.global_to_local(obs, K.origin[d], K.ints[d, S_ARG], K.local)
    tiles_mod.active_tiles(K.local, tiling, K.tiles[d, which, :tiling.offsets.shape[0]])
  return view


def _local_goal(K, W, row, d, obs, samples):
  """A LocalGoal end: (event, G) of the step's samples (`ship_core.low_level_outcome`)."""


@overload(_local_goal)
def _local_goal_typed(K, W, row, d, obs, samples):
  if not isinstance(W, types.NoneType):
    return lambda K, W, row, d, obs, samples: (core.NO_EVENT, 0.0)

  def end(K, W, row, d, obs, samples):
    return core.low_level_outcome(samples, obs, K.origin[d], K.ints[d, S_ARG], K.ints[d, S_STEPS],
                                  K.local_samples, K.local, row[MAX_STEPS])
  return end


def _taxi_done(P, K, W, row, d):
  """A TaxiDone end (`taxi_subtasks.done_of`); never in a ship machine (W None). By
  type too: `_end_of` is inlined, and numba inlined the taxi's rules into it before
  pruning them."""


@overload(_taxi_done, inline="always")
def _taxi_done_typed(P, K, W, row, d):
  if isinstance(W, types.NoneType):
    return lambda P, K, W, row, d: False
  return lambda P, K, W, row, d: taxi_subtasks.done_of(row[END_AT], K.ints[d, S_ARG], K.taxi[0:5],
                                                       P.world)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _in_world(W, function, address, args):
  """function(*args) as the world suits: in a ship machine (W None) through its address
  (`jit.call_at`), so that its code is compiled once rather than again inside each
  caller; in a taxi machine by numba's linked call, which LLVM may inline (the taxi's
  primitive steps are short: with every call through an address it trained ~20%
  slower)."""
  if W is None:
    return jit.call_at(function, address, args)
  return function(*args)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def _view(P, Q, B, G, T, S, K, X, W, d, which):
  """The node at depth d views the observation (K.obs): a table's state into S_STATE (which = 0) or
  S_NEXT_STATE (1); tiles into its tiles[d, which]. `_view` and `_observe` are
  compiled once and called, not inlined (numba copied an inlined body into each
  caller, at a high price in compile time; with the banks passed as pointers a call
  costs little)."""
  obs = K.obs
  node = K.ints[d, S_NODE]
  row = P.nodes[node]
  kind = row[VIEW]
  if kind == VIEW_GRID_CELL:
    p = P.params[node]
    K.ints[d, S_STATE + which] = grid_cell(obs[0], obs[1], p[CELL_M], np.int64(p[GRID]))
  elif kind == VIEW_PATROL_CELL:
    if X is not None:
      p = P.params[node]
      K.ints[d, S_STATE + which] = ship_rules.root_state(obs, np.int64(p[SECTORS]),
                                                         p[NEAR_GATE_M], p[NEAR_GATE_CELL_M])
  elif kind == VIEW_RULE:
    if X is not None:
      state = np.int64(P.rules(row[VIEW_SLOT], obs, K.origin[d], K.ints[d, S_ARG],
                               K.ints[d, S_STEPS], np.int64(0)))
      if state < 0 or state >= row[N_STATES]:
        raise IndexError("a CellRule's rule gave a state outside its QTable's states")
      K.ints[d, S_STATE + which] = state
  elif kind == VIEW_LOCAL_TILES:
    _local_tiles(T, K, W, row, d, obs, which)
  elif kind == VIEW_STATE_TILES:
    _state_tiles(T, K, row, d, which)
  elif kind == VIEW_AIM_TILES:
    if X is not None:
      p = P.params[node]
      tiling = _tiling(T, row[VIEW_SLOT])
      tx, ty = _target(P, K, d, obs)
      view = K.local[:3]
      K.floats[d, F_SIDE] = ship_rules.aim_view(obs, tx, ty, view, p[SQRT_ERROR] != 0.0,
                                                p[REFLECT_AT])
      tiles_mod.active_tiles(view, tiling, K.tiles[d, which, :tiling.offsets.shape[0]])
  elif kind == VIEW_TAXI_STATE:
    if W is not None:
      K.ints[d, S_STATE + which] = taxi_rules.encoded(obs, P.world)
  elif kind == VIEW_TAXI_ABSTRACT:
    if W is not None:
      K.ints[d, S_STATE + which] = _taxi_abstract(P, K, row, d)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _state_tiles(T, K, row, d, which):
  """A StateTiles view: the observation (K.obs) tiled into tiles[d, which]."""
  tiling = _tiling(T, row[VIEW_SLOT])
  tiles_mod.active_tiles(K.obs[:T.dims[row[VIEW_SLOT]]], tiling,
                         K.tiles[d, which, :tiling.offsets.shape[0]])


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _target(P, K, d, obs):
  """The point an AimTiles node at depth d steers to now (`ship_rules.target_of`)."""
  p = P.params[K.ints[d, S_NODE]]
  return ship_rules.target_of(K.ints[d, S_ARG], obs, ship_rules.side_of(K.origin[d, 1]),
                              p[INSET_M], p[APPROACH_M])


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _offered(P, node, obs):
  """How many of its first children `node` offers in `obs` (its `available`)."""
  row = P.nodes[node]
  if row[OFFER] == OFFER_NEAR_GATE and abs(obs[1] - ship_rules.GATE_Y) > P.params[node, WITHIN_M]:
    return np.int64(1)
  return row[N_CHILDREN]


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _critic_tiles(P, T, K, d, obs, r, which):
  """An actor-critic's critic tiles of (obs, r) into tiles[d, 2 + which]."""
  tiling = _tiling(T, P.nodes[K.ints[d, S_NODE], CRITIC_SLOT])
  sa = K.sa
  n = sa.shape[0] - 1
  for i in range(n):
    sa[i] = obs[i]
  sa[n] = r
  tiles_mod.active_tiles(sa, tiling, K.tiles[d, 2 + which, :tiling.offsets.shape[0]])


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def _gaussian_choose(P, G, T, K, d):
  """A GaussianCMAC node's choice (`policies.gaussian_choose`) into the stack. Called,
  not inlined: `_call` and `_observe` share one compiled copy of the inlined Eq. 3
  rule (four pointers and two numbers a call; compiled without reference counting)."""
  learn, sample = K.flags[RUN_LEARN], K.flags[RUN_SAMPLE]
  node = K.ints[d, S_NODE]
  row = P.nodes[node]
  p = P.params[node]
  slot = row[SLOT]
  k = T.n_tilings[row[VIEW_SLOT]]
  K.floats[d, F_ACTION] = policies.gaussian_choose(
      _trace(G, slot), G.values[slot], K.tiles[d, 0, :k], K.psi[d, :k], p[ALPHA], p[BETA],
      p[R_MAX], learn, sample, K.rng, _width(G, row), K.psi_width[d, :k],
      p[WIDTH_ALPHA], p[LOG_SIGMA_LOW], p[LOG_SIGMA_HIGH]) * K.floats[d, F_SIDE]


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def _gibbs_choose(P, B, K, W, d):
  """A GibbsTable node's choice among its available children into the stack. Called,
  not inlined: inlined into `_choose`, beside the other learners' inlined code, numba
  compiled the baseline's theta <- theta - alpha b(s) psi to a store that never reached
  the bank (numba 0.68; a stand-alone call of the same code wrote it)."""
  learn, sample = K.flags[RUN_LEARN], K.flags[RUN_SAMPLE]
  row = P.nodes[K.ints[d, S_NODE]]
  slot = row[SLOT]
  n_children = row[N_CHILDREN]
  mask = K.mask[:n_children]
  if row[AVAILABLE_AT] >= 0:
    if W is not None:
      taxi_subtasks.children_of(row[AVAILABLE_AT], K.taxi[0:5], P.world, mask)
  else:
    for i in range(n_children):
      mask[i] = True
  K.ints[d, S_CHOICE] = policies.softmax_choose(
      _gibbs_trace(B, slot), B.values[slot], K.ints[d, S_STATE], n_children, mask, B.alpha[slot],
      learn, sample, K.rng, K.probs[:n_children], K.index[:n_children],
      K.scores[:n_children])


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _epsilon(S, row, p, sample):
  """A Q learner's epsilon: the schedule's or its own; 0 when not sampling."""
  if not sample:
    return 0.0
  return S.epsilon[0] if row[EPS_SCHEDULE] else p[EPSILON]


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _table_choose(Q, S, K, X, row, p, d, sample, rng_state):
  """A QTable's or RLearning's epsilon-greedy choice in its state S_STATE (an
  RLearning also notes whether the choice was greedy, for its gain)."""
  q = Q.q[row[SLOT]]
  K.ints[d, S_CHOICE] = qlambda.epsilon_greedy(q, K.ints[d, S_STATE], row[N_CHILDREN],
                                               _epsilon(S, row, p, sample), rng_state)
  if row[LEARNER] == AVERAGE_REWARD and X is not None:
    K.floats[d, F_GREEDY] = average_reward.is_greedy(q, K.ints[d, S_STATE], K.ints[d, S_CHOICE],
                                                     row[N_CHILDREN])


def _actor_critic_choose(P, G, T, K, X, row, p, d, obs, sample, rng_state):
  """An ActorCritic node's draw (m, u, r) and its critic's tiles into the stack; by
  type, as `_taxi_done`: nothing where X is None (a machine without one)."""


@overload(_actor_critic_choose, inline="always")
def _actor_critic_choose_typed(P, G, T, K, X, row, p, d, obs, sample, rng_state):
  if isinstance(X, types.NoneType) or isinstance(G, types.NoneType):
    return lambda P, G, T, K, X, row, p, d, obs, sample, rng_state: None

  def choose(P, G, T, K, X, row, p, d, obs, sample, rng_state):
    k = T.n_tilings[row[VIEW_SLOT]]
    m, u, r = actor_critic.choose(G.values[row[SLOT]], K.tiles[d, 0, :k], p[R_MAX], sample,
                                  rng_state)
    K.floats[d, F_MEAN] = m
    K.floats[d, F_U] = u
    K.floats[d, F_ACTION] = r
    _critic_tiles(P, T, K, d, obs, r, np.int64(0))
    K.ints[d, S_CHOICE] = 0
  return choose


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _choose(P, Q, B, G, T, S, K, X, W, d):
  """Algorithm 1: choose a with mu^i(s, theta^i); sets the stack's choice and action."""
  obs, rng_state = K.obs, K.rng
  sample = K.flags[RUN_SAMPLE]
  node = K.ints[d, S_NODE]
  row = P.nodes[node]
  p = P.params[node]
  slot = row[SLOT]
  if row[LEARNER] == Q_TABLE or row[LEARNER] == AVERAGE_REWARD:
    if Q is not None:
      _table_choose(Q, S, K, X, row, p, d, sample, rng_state)
  elif row[LEARNER] == TILED_Q:
    if Q is not None and X is not None:
      K.ints[d, S_CHOICE] = qlambda.tiled_epsilon_greedy(
          Q.q[slot], K.tiles[d, 0, :T.n_tilings[row[VIEW_SLOT]]], row[N_CHILDREN],
          _offered(P, node, obs), _epsilon(S, row, p, sample), rng_state)
  elif row[LEARNER] == GAUSSIAN_CMAC:
    if G is not None:
      _in_world(W, _gaussian_choose, P.calls[CALL_GAUSSIAN], (P, G, T, K, d))
  elif row[LEARNER] == GIBBS_TABLE:
    if B is not None:
      _gibbs_choose(P, B, K, W, d)
  elif row[LEARNER] == ACTOR_CRITIC:
    _actor_critic_choose(P, G, T, K, X, row, p, d, obs, sample, rng_state)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def _call(P, Q, B, G, T, S, K, X, W, d, node, arg):
  """Task `node` is called at depth d with `arg` from the observation (K.obs): z <- 0,
  its view, its first choice."""
  obs = K.obs
  ints = K.ints
  ints[d, S_NODE] = node
  ints[d, S_ARG] = arg
  ints[d, S_STEPS] = 0
  ints[d, S_CHILD_STEPS] = 0
  K.floats[d, F_REWARD] = 0.0
  K.floats[d, F_SIDE] = 1.0
  K.origin[d, 0] = obs[0]
  K.origin[d, 1] = obs[1]
  row = P.nodes[node]
  if row[LEARNER] == Q_TABLE or row[LEARNER] == TILED_Q:
    if Q is not None:
      qlambda.clear(Q.count[row[SLOT]])
  elif row[LEARNER] == GAUSSIAN_CMAC:
    if G is not None:
      el.reset(_trace(G, row[SLOT]))                # Eq. 3: z <- 0
      _reset_width(G, row)
  elif row[LEARNER] == GIBBS_TABLE:
    if B is not None:
      el.reset(_gibbs_trace(B, row[SLOT]))          # Eq. 3: z <- 0
  elif row[LEARNER] == ACTOR_CRITIC:
    if X is not None and G is not None:
      el.reset(_trace(G, row[SLOT]))                # the critic's e <- 0
      for i in range(K.psi.shape[1]):
        K.psi[d, i] = 1.0                           # phi(s, a) of the critic's tiles
  _in_world(W, _view, P.calls[CALL_VIEW], (P, Q, B, G, T, S, K, X, W, d, np.int64(0)))
  _choose(P, Q, B, G, T, S, K, X, W, d)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _primitive_action(P, K, d):
  """The action of the child chosen at depth d if it is a primitive (a continuous
  one: the value its parent drew), else NaN."""
  child = P.children[P.nodes[K.ints[d, S_NODE], FIRST_CHILD] + K.ints[d, S_CHOICE], C_NODE]
  if P.nodes[child, KIND] != PRIMITIVE:
    return np.nan
  K.episode[E_DEPTH] = d
  action = P.params[child, ACTION]
  return K.floats[d, F_ACTION] if action != action else action       # NaN: continuous


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def _descend(P, Q, B, G, T, S, K, X, W, d):
  """From depth d, calls the chosen children down to a primitive; returns the
  primitive's action."""
  while True:
    action = _primitive_action(P, K, d)
    if action == action:
      return action
    child = P.children[P.nodes[K.ints[d, S_NODE], FIRST_CHILD] + K.ints[d, S_CHOICE]]
    arg = child[C_ARG]
    if child[C_BIND] >= 0:
      if W is not None:
        arg = taxi_subtasks.carry_target(child[C_BIND], K.taxi[0:5])
    d += 1
    jit.call_at(_call, P.calls[CALL_CALL], (P, Q, B, G, T, S, K, X, W, d, child[C_NODE], arg))


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _begin(P, Q, B, G, T, S, K, X, W):
  """An episode starts at the observation (K.obs): the root is called; returns the
  first action."""
  c = K.counters
  for i in range(c.shape[0]):
    for j in range(c.shape[1]):
      c[i, j] = 0.0
  K.episode[E_STEPS] = 0
  K.episode[E_EVENT] = core.NO_EVENT
  K.total[0] = 0.0
  if B is not None:
    _step_sizes(P, B, K)
  jit.call_at(_call, P.calls[CALL_CALL], (P, Q, B, G, T, S, K, X, W, np.int64(0),
                                          P.nodes.shape[0] - 1, K.episode[E_ROOT_ARG]))
  return jit.call_at(_descend, P.calls[CALL_DESCEND], (P, Q, B, G, T, S, K, X, W, np.int64(0)))


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cfunc_wrapper=True)
def begin(P, Q, B, G, T, S, K, X, W, rng_state):
  """`_begin` for the step-by-step path, from the observation the Python side wrote
  into K.obs. The fused loops inline `_begin` (numba copies its small body), so that
  a first train does not compile it as a function of its own; `_call` and
  `_descend`, which `step` needs too, are called through their addresses (`_FAR`),
  each compiled once."""
  arrays.copy_into(K.rng, rng_state)
  if W is not None:
    _taxi_seen(P, K, K.obs)
  action = _begin(P, Q, B, G, T, S, K, X, W)
  arrays.copy_into(rng_state, K.rng)
  return action


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cfunc_wrapper=True)
def advance(P, Q, B, G, T, S, K, X, W, samples, reward, terminated, truncated, rng_state):
  """`step` for the step-by-step path, on the observation the Python side wrote into
  K.obs: the taxi's blocks read it as taxi_rules' state (the fused loop steps that
  state itself)."""
  arrays.copy_into(K.rng, rng_state)
  if W is not None:
    _taxi_seen(P, K, K.obs)
  out = jit.call_at(step, P.calls[CALL_STEP], (P, Q, B, G, T, S, K, X, W, samples, reward,
                                               terminated, truncated))
  arrays.copy_into(rng_state, K.rng)
  return out


# The machine's nine arguments as the fields of one struct (`banks.as_structs` of a
# Refs): the step-by-step path's entry points take it, and unbox one struct a call
# where they unboxed seven (~0.8 us of a ~20 us control step through the MuJoCo ship).
Refs = collections.namedtuple("Refs", ("P", "Q", "B", "G", "T", "S", "K", "X", "W"))


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cfunc_wrapper=True)
def _begin_with(R, rng_state):
  """`begin` on the structs of `R` (a Refs struct)."""
  return begin(R.P, R.Q, R.B, R.G, R.T, R.S, R.K, R.X, R.W, rng_state)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cfunc_wrapper=True)
def _advance_with(R, obs, samples, reward, terminated, truncated, rng_state):
  """`advance` on the structs of `R` (a Refs struct), `obs` first copied into the
  stack's (`Machine.advance`)."""
  into = R.K.obs
  if obs.shape[0] != into.shape[0]:
    raise ValueError("Machine.advance: obs is not of the length of the episode's first")
  for i in range(obs.shape[0]):
    into[i] = obs[i]
  return advance(R.P, R.Q, R.B, R.G, R.T, R.S, R.K, R.X, R.W, samples, reward, terminated,
                 truncated, rng_state)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _end_of(P, K, X, W, d, samples):
  """After a child of the node at depth d returned: (its own event, G)."""
  obs = K.obs
  node = K.ints[d, S_NODE]
  row = P.nodes[node]
  event, internal = core.NO_EVENT, 0.0
  if row[END] == END_LOCAL_GOAL:
    event, internal = _local_goal(K, W, row, d, obs, samples)
    if row[INTERNAL] != G_SHAPING:
      internal = 0.0
  elif row[END] == END_TARGET:
    if X is not None:
      p = P.params[node]
      tx, ty = _target(P, K, d, obs)
      event, internal = ship_rules.aim_outcome(samples, obs, K.ints[d, S_ARG], tx, ty,
                                               K.ints[d, S_STEPS], row[MAX_STEPS], p[RADIUS_M],
                                               p[SHAPING_WEIGHT])
      if row[INTERNAL] != G_SHAPING:
        internal = 0.0
  elif row[END] == END_CLOCK:
    if X is not None and K.ints[d, S_STEPS] >= row[MAX_STEPS]:
      event = core.SUCCESS
  elif row[END] == END_TAXI:
    if _taxi_done(P, K, W, row, d):
      event = core.SUCCESS
  elif row[END] == END_RULE:
    if X is not None:
      said = P.rules(row[END_AT], obs, K.origin[d], K.ints[d, S_ARG], K.ints[d, S_STEPS],
                     np.int64(0))
      if said != 0.0 and said != 1.0 and said != -1.0:
        raise ValueError("an EndRule's rule gave an event other than 0, 1 or -1")
      event = np.int64(said)
  if row[INTERNAL] == G_RULE:
    if X is not None:
      internal = P.rules(row[G_AT], obs, K.origin[d], K.ints[d, S_ARG], K.ints[d, S_STEPS],
                         np.int64(event))
  return event, internal


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _end_schedule(S):
  """The held epsilon schedule's step (`schedules.end_episode`): at an episode's end, or
  after each of the root's decisions (`HeldEpsilon.per_decision`)."""
  schedules.end_episode(S.epsilon, S.outcomes, S.counts, S.settings[0], np.int64(S.settings[1]),
                        S.settings[2])


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def _observe(P, Q, B, G, T, S, K, X, W, d, signal, done, terminal):
  """Algorithm 1: the learner of the node at depth d takes R + G of its child's run;
  unless done, it makes its next choice."""
  obs, rng_state = K.obs, K.rng
  learn, sample = K.flags[RUN_LEARN], K.flags[RUN_SAMPLE]
  node = K.ints[d, S_NODE]
  row = P.nodes[node]
  p = P.params[node]
  slot = row[SLOT]
  ints = K.ints
  kind = row[LEARNER]
  # The view of s': a table's state always, a policy's tiles unless the call is over,
  # an actor-critic's unless s' is terminal.
  if kind == GIBBS_TABLE and row[VIEW] == VIEW_TAXI_ABSTRACT:
    if W is not None:              # without the call to `_view`: the taxi's every step
      ints[d, S_NEXT_STATE] = _taxi_abstract(P, K, row, d)
  elif row[VIEW] == VIEW_STATE_TILES and ((kind == GAUSSIAN_CMAC and not done) or (
      kind == ACTOR_CRITIC and not terminal)):
    _state_tiles(T, K, row, d, np.int64(1))    # nor here: flat PGRL's, the actor-critic's
  elif kind == Q_TABLE or kind == TILED_Q or kind == GIBBS_TABLE or kind == AVERAGE_REWARD or (
      kind == GAUSSIAN_CMAC and not done) or (kind == ACTOR_CRITIC and not terminal):
    _in_world(W, _view, P.calls[CALL_VIEW], (P, Q, B, G, T, S, K, X, W, d, np.int64(1)))
  if d == 0 and learn and S.settings[PER_DECISION] != 0.0:
    _end_schedule(S)                    # a held schedule counted in the root's decisions
  if kind == Q_TABLE:
    if Q is not None:
      ints[d, S_CHOICE] = qlambda.smdp_step(
          (Q.q[slot], Q.index[slot], Q.value[slot], Q.count[slot]), row[N_CHILDREN],
          ints[d, S_STATE], ints[d, S_CHOICE], signal, ints[d, S_NEXT_STATE], row[N_CHILDREN],
          done, terminal, _epsilon(S, row, p, sample), p[ALPHA], p[GAMMA], p[DECAY], learn,
          rng_state)
      ints[d, S_STATE] = ints[d, S_NEXT_STATE]
  elif kind == AVERAGE_REWARD:
    if Q is not None and X is not None:
      n = row[N_CHILDREN]
      s, a, s_next = ints[d, S_STATE], ints[d, S_CHOICE], ints[d, S_NEXT_STATE]
      if learn:                 # (s, a, r, tau, s'), tau the child's run's steps
        q, gain = Q.q[slot], Q.gain[slot]
        tau = float(ints[d, S_CHILD_STEPS])
        average_reward.update(q, n, gain, s, a, signal, tau, s_next, p[ALPHA], p[GAIN_STEP],
                              K.floats[d, F_GREEDY] != 0.0)
        average_reward.remember_and_plan(
            q, n, gain, (Q.model_next[slot], Q.model_reward[slot], Q.model_steps[slot],
                         Q.model_count[slot]), s, a, signal, tau, s_next, p[ALPHA],
            np.int64(p[PLANNING_EVERY]))
      ints[d, S_STATE] = s_next
      if not done:
        _table_choose(Q, S, K, X, row, p, d, sample, rng_state)
  elif kind == TILED_Q:
    if Q is not None and X is not None:
      k = T.n_tilings[row[VIEW_SLOT]]
      ints[d, S_CHOICE] = qlambda.smdp_step(
          (Q.q[slot], Q.index[slot], Q.value[slot], Q.count[slot]), row[N_CHILDREN],
          K.tiles[d, 0, :k], ints[d, S_CHOICE], signal, K.tiles[d, 1, :k],
          _offered(P, node, obs), done, terminal, _epsilon(S, row, p, sample), p[ALPHA],
          p[GAMMA], p[DECAY], learn, rng_state)
      arrays.copy_into(K.tiles[d, 0, :k], K.tiles[d, 1, :k])
  elif kind == GIBBS_TABLE:
    if B is not None:
      if learn:                                        # Eq. 3 with R + G, and b(s)
        policies.softmax_learn(_gibbs_trace(B, slot), B.values[slot], ints[d, S_STATE],
                               ints[d, S_NEXT_STATE], B.alpha[slot], p[DECAY], p[BETA], signal,
                               done)
      ints[d, S_STATE] = ints[d, S_NEXT_STATE]
      if not done:
        _gibbs_choose(P, B, K, W, d)
  elif kind == GAUSSIAN_CMAC:
    if G is not None:
      k = T.n_tilings[row[VIEW_SLOT]]
      if learn:                                        # Eq. 3 with R + G
        policies.gaussian_learn(_trace(G, slot), G.values[slot], K.tiles[d, 0, :k],
                                K.tiles[d, 1, :k], p[ALPHA], p[DECAY], p[BETA], signal, done,
                                _width(G, row), p[WIDTH_ALPHA])
      if not done:
        arrays.copy_into(K.tiles[d, 0, :k], K.tiles[d, 1, :k])
        _in_world(W, _gaussian_choose, P.calls[CALL_GAUSSIAN], (P, G, T, K, d))
  elif kind == ACTOR_CRITIC:
    # delta = R + Q(s', a') - Q(s, a), with a' drawn in s' unless s' is terminal (also
    # when the call is cut, to bootstrap from it); the next step's a is that a'.
    if X is not None and G is not None:
      k = T.n_tilings[row[VIEW_SLOT]]
      kc = T.n_tilings[row[CRITIC_SLOT]]
      critic = _trace(G, slot)
      q = actor_critic.critic_value(critic, K.tiles[d, 2, :kc])
      target = signal
      m, u, r = 0.0, 0.0, 0.0
      if not terminal:
        m, u, r = actor_critic.choose(G.values[slot], K.tiles[d, 1, :k], p[R_MAX], sample,
                                      rng_state)
        _critic_tiles(P, T, K, d, obs, r, np.int64(1))
        target += actor_critic.critic_value(critic, K.tiles[d, 3, :kc])
      if learn:
        actor_critic.learn(critic, K.tiles[d, 2, :kc], K.psi[d, :kc], p[ALPHA], target - q,
                           p[DECAY], G.values[slot], K.tiles[d, 0, :k], p[ALPHA_ACTOR], q,
                           K.floats[d, F_U], K.floats[d, F_MEAN])
      if not done:
        arrays.copy_into(K.tiles[d, 0, :k], K.tiles[d, 1, :k])
        arrays.copy_into(K.tiles[d, 2, :kc], K.tiles[d, 3, :kc])
        K.floats[d, F_MEAN] = m
        K.floats[d, F_U] = u
        K.floats[d, F_ACTION] = r


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def step(P, Q, B, G, T, S, K, X, W, samples, reward, terminated, truncated):
  """A primitive step ended in the observation K.obs with `reward` (`samples`: the positions
  sampled inside it, for the ship's local ends). Returns (episode over, the next
  action). One compiled function for both paths: the fused loops call it rather
  than inline it, which numba did by copying its whole body, the largest part of a
  fused loop's first compile; the ship's loop and `advance` call it through its
  address (`_FAR`), so that its code is not compiled again inside theirs."""
  learn = K.flags[RUN_LEARN]
  ints = K.ints
  floats = K.floats
  depth = K.episode[E_DEPTH]
  for level in range(depth + 1):
    floats[level, F_REWARD] += reward
    ints[level, S_STEPS] += 1
    ints[level, S_CHILD_STEPS] += 1
  K.episode[E_STEPS] += 1
  K.total[0] += reward
  over = terminated or truncated
  d = depth
  while True:
    node = ints[d, S_NODE]
    row = P.nodes[node]
    event, internal = _end_of(P, K, X, W, d, samples)
    done = event != core.NO_EVENT or over
    terminal = terminated or event != core.NO_EVENT
    if row[END] == END_CLOCK and X is not None:   # a continuing root: the world's events end its children only
      done = event != core.NO_EVENT
      terminal = False
      if K.episode[E_RESTART] != 0:             # after a departure, it sees the restart
        K.episode[E_RESTART] = 0
        for i in range(K.restart.shape[0]):
          K.obs[i] = K.restart[i]
    if row[SEEN] == SEEN_STEP:
      seen = core.STEP_REWARD * ints[d, S_CHILD_STEPS]
    else:
      seen = floats[d, F_REWARD]
    floats[d, F_REWARD] = 0.0
    _in_world(W, _observe, P.calls[CALL_OBSERVE],
              (P, Q, B, G, T, S, K, X, W, d, seen + internal, done, terminal))
    ints[d, S_CHILD_STEPS] = 0                  # (an RLearning's tau, read by _observe)
    if not done:
      action = _primitive_action(P, K, d)        # the common case: no call to make
      if action != action:
        action = jit.call_at(_descend, P.calls[CALL_DESCEND],
                             (P, Q, B, G, T, S, K, X, W, d))
      return False, action
    # The call returns (Algorithm 1: return to the parent).
    c = K.counters[node]
    if d == 0:
      K.episode[E_EVENT] = event
      if learn:
        K.episode[E_LEARNED] += 1
        sch = S
        if sch.settings[SCHEDULE_KIND] == LINEAR:
          sch.epsilon[0] = schedules.linear(K.episode[E_LEARNED], sch.settings[LINEAR_START],
                                            sch.settings[LINEAR_END], sch.settings[LINEAR_EPISODES])
        elif sch.settings[PER_DECISION] == 0.0:
          _end_schedule(sch)
      return True, 0.0
    c[CALLS] += 1
    if not over:
      success = event == core.SUCCESS
      c[RUNS] += 1
      c[SUCCESSES] += success
      if learn and row[WATCH] >= 0:
        schedules.record_run(S.outcomes, S.counts, row[WATCH], success)
    d -= 1


# ---- fused with the analytic ship --------------------------------------------------

@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cfunc_wrapper=True)
def run_ship(P, Q, B, G, T, S, K, X, W, n_episodes, rng_state, world, record,
             fixed_start):
  """`n_episodes` episodes on Equation 1, of the full ship task (SPEC section 2):
  `world` = [gate reward, out-of-bounds reward, max steps, 0], or of the root alone
  as a stand-alone subtask (`world[3]` = 1, SPEC section 8): each episode a call at
  the local start of the root's argument (`sample_local_start`), -1 a step, ended by
  the root's own termination; or `n_episodes` record rows of the continuing task
  (`world[3]` = 2, SPEC section 8; a root with a Clock): the ship sails on from
  `fixed_start` (the process's state, written back), each gate pass pays and it sails
  on, each departure pays and it restarts at a start drawn from `rng_state`. Record
  row (ROW_END ...): passed (the gate, or the root's success; a continuing row: its
  gate passes), steps, return, 0 (a continuing row: its departures), then calls,
  runs, successes of each node; the ship's state (what the machine observes) and
  the positions sampled in a step are the stack's `obs` and `samples`, and the
  generator's state is copied into the stack's `rng` for the loop and back after
  it (the machine's functions then take none of them as arguments: passed, each
  array was seven numbers pushed at every call). Compiled without
  reference counting, as everything it inlines: the machine reads its banks through
  views, and counting references to them cost 70% of its time."""
  max_steps = np.int64(world[2])
  alone = world[3] == 1.0
  continuing = world[3] == 2.0
  state, samples, rng = K.obs, K.samples, K.rng
  arrays.copy_into(rng, rng_state)
  event = core.NO_EVENT
  reward = core.STEP_REWARD
  if continuing:
    arrays.copy_into(state, fixed_start)
  for episode in range(n_episodes):
    passes, departures = 0.0, 0.0
    if continuing:
      pass                                    # the process sails on
    elif fixed_start.shape[0] == 4:
      arrays.copy_into(state, fixed_start)
    elif alone:
      ship_rules.sample_local_start(rng, K.episode[E_ROOT_ARG], state)
    else:
      ship_rules.sample_start(rng, state)
    action = _begin(P, Q, B, G, T, S, K, X, W)
    while True:
      core.euler_control(state, action, samples)
      terminated, truncated = False, False
      if not alone:
        event, reward = core.global_outcome(samples, world[0], world[1])
        terminated = event != core.NO_EVENT
        if not continuing:
          truncated = (not terminated) and K.episode[E_STEPS] + 1 >= max_steps
        elif event == core.SUCCESS:
          passes += 1.0
        elif event == core.FAILURE:           # SPEC section 8: a fresh start, sail on
          departures += 1.0
          ship_rules.sample_start(rng, K.restart)
          K.episode[E_RESTART] = 1
      over, action = jit.call_at(step, P.calls[CALL_STEP],
                                 (P, Q, B, G, T, S, K, X, W, samples, reward, terminated,
                                  truncated))
      if over:
        break
    if continuing:
      _write_row(K, record[episode], passes, departures)
      continue
    if alone:
      event = K.episode[E_EVENT]
    _write_row(K, record[episode], 1.0 if event == core.SUCCESS else 0.0, 0.0)
  if continuing:
    arrays.copy_into(fixed_start, state)
  arrays.copy_into(rng_state, rng)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _write_row(K, row, end, illegal):
  """The record row of the episode just ended (ROW_END ... ROW_COUNTERS)."""
  row[ROW_END] = end
  row[ROW_STEPS] = K.episode[E_STEPS]
  row[ROW_RETURN] = K.total[0]
  row[ROW_ILLEGAL] = illegal
  for i in range(K.counters.shape[0]):
    for j in range(3):
      row[ROW_COUNTERS + 3 * i + j] = K.counters[i, j]


# ---- fused with the taxi ------------------------------------------------------------

@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cfunc_wrapper=True)
def run_taxi(P, Q, B, G, T, S, K, X, W, n_episodes, rng_state, record, starts):
  """`n_episodes` episodes of the taxi task `W` (`taxi_rules.world_config`; SPEC
  section 5), each from a start drawn from `rng_state` (`taxi_subtasks.sample_start`)
  or, with starts int64[k, 5] (k > 0), from starts[e % k]. The machine sees the
  state as float64 numbers; the world steps it as taxi_rules' int64 state. Record
  rows as `run_ship`'s, with the episode's outcome (`taxi_rules`: DELIVERED,
  OUT_OF_FUEL, TRUNCATED) and its illegal Pickups and Dropoffs. The generator's
  state is the stack's `rng` in the loop, as in `run_ship`."""
  state = K.taxi[0:5]                # the state the taxi blocks read
  episode = K.taxi[5:8]
  obs, rng = K.obs, K.rng
  arrays.copy_into(rng, rng_state)
  for e in range(n_episodes):
    if starts.shape[0] > 0:
      for i in range(5):
        state[i] = starts[e % starts.shape[0], i]
    else:
      taxi_subtasks.sample_start(rng, P.world, state)
    for i in range(3):
      episode[i] = 0
    for i in range(5):
      obs[i] = state[i]
    action = _begin(P, Q, B, G, T, S, K, X, W)
    while True:
      reward = taxi_rules.primitive_step(state, episode, np.int64(action), P.world)
      for i in range(5):
        obs[i] = state[i]
      outcome = episode[taxi_rules.E_OUTCOME]
      truncated = outcome == taxi_rules.TRUNCATED
      terminated = outcome != taxi_rules.RUNNING and not truncated
      over, action = step(P, Q, B, G, T, S, K, X, W, K.samples, reward, terminated, truncated)
      if over:
        break
    _write_row(K, record[e], episode[taxi_rules.E_OUTCOME], episode[taxi_rules.E_ILLEGAL])
  arrays.copy_into(rng_state, rng)


# The functions called through their addresses (`jit.call_at`), each compiled once
# rather than again inside each caller: a subtask's call and descent (rare beside
# the steps), and a control step from the ship's loop and the step-by-step path; in a
# ship machine also `_observe`, `_view` and the Gaussian choice (`_in_world`). Not the
# taxi's `step` from its loop, nor its `_observe`, `_view` and choices: with every
# call through an address, taxi HPG trained ~20% slower (a primitive step of the
# taxi is short, and numba's linked calls let LLVM inline them).
_FAR = (step, _call, _descend, _observe, _view, _gaussian_choose)


# ---- building the arrays from a graph of blocks ---------------------------------------

def _trace_size(learner):
  """The weights of a GaussianBank row's trace: the policy's, or the critic's."""
  return (learner.critic_coder.size if isinstance(learner, blocks.ActorCritic) else
          learner.coder.size)


def _values_size(learner):
  """The row's values: the baseline b over the tiles, or the actor's weights."""
  return (learner.actor_coder.size if isinstance(learner, blocks.ActorCritic) else
          learner.coder.size)


def _trace_rows(sizes):
  """A Trace's fields (`eligibility.Trace`) stacked, one row per size."""
  rows = max(len(sizes), 1)
  return (*(_stack_rows([np.zeros(n) for n in sizes], dt) for dt in
            (np.float64, np.float64, np.float64, np.int64, np.bool_)),
          np.zeros((rows, 1), dtype=np.int64), np.tile(np.array([0.0, 1.0]), (rows, 1)))


def _stack_rows(arrays_, dtype):
  """Rows of one length (zero-padded) from 1-D arrays; at least one row."""
  width = max([len(a) for a in arrays_] + [1])
  out = np.zeros((max(len(arrays_), 1), width), dtype=dtype)
  for i, a in enumerate(arrays_):
    out[i, :len(a)] = a
  return out


class Machine:
  """A task graph of blocks as arrays, and the compiled machine over them.

  `root_args` are the root call's arguments (as a `Child`'s: {"direction": d} runs
  a subtask on its own). `world`: the taxi's world array (`taxi_rules.world_config`)
  for a graph with taxi blocks (`blocks.TaxiState`), which `run_taxi` runs. `q_arrays`, `gaussian_arrays`, `width_trace` and
  `actor_critic_arrays` give a learner's arrays (views of the banks: writing into
  them restores a checkpoint). Nodes are numbered so that the root is last.
  """

  def __init__(self, graph, root_args=None, world=None):
    self.graph = graph
    self.world = None if world is None else np.array(world, dtype=np.int64)
    root_args = root_args or {}
    self.schedule_block = graph.schedule or blocks.HeldEpsilon()
    order = [n for n in graph.nodes if n != graph.root] + [graph.root]
    self.names = order
    index = {name: i for i, name in enumerate(order)}
    self.index_of = index
    self.argument_names = {}            # node -> the name of its argument (`ARGUMENTS`)
    nodes = np.zeros((len(order), N_INT), dtype=np.int64)
    params = np.zeros((len(order), N_FLOAT))
    params[:, ACTION] = np.nan
    children = []
    self.learners = {Q_TABLE: [], GAUSSIAN_CMAC: [], GIBBS_TABLE: []}
    self.codings = []
    self.rules = []                     # (node, kind, rule) of its CellRules, EndRules, RewardRules
    self._slot_of = {}
    watch = {name: i for i, name in enumerate(getattr(self.schedule_block, "watch", ()))}
    for name, node in graph.nodes.items():
      i = index[name]
      if isinstance(node, Primitive):
        nodes[i, KIND] = PRIMITIVE
        if node.action is not None:
          params[i, ACTION] = float(node.action)
        continue
      nodes[i, KIND] = SUBTASK
      refs = graph.children(name)
      nodes[i, FIRST_CHILD] = len(children)
      nodes[i, N_CHILDREN] = len(refs)
      for ref in refs:
        children.append((index[ref.node], self._argument(name, ref), self._binding(name, ref)))
      nodes[i, WATCH] = watch.get(name, -1)
      nodes[i, AVAILABLE_AT] = self._available(name, node, nodes[i], params[i])
      self._learner(name, node, nodes[i], params[i], refs)
      self._view(name, node, nodes[i], params[i])
      self._end(name, node, nodes[i], params[i])
    self.index = index
    q = self.learners[Q_TABLE]
    g = self.learners[GAUSSIAN_CMAC]
    widths = [b for b in g if getattr(b, "width_alpha", 0.0) != 0.0]
    self._width_slot_of = {id(b): i for i, b in enumerate(widths)}
    for i in range(len(order)):
      learner = getattr(graph.nodes[order[i]], "learner", None)
      nodes[i, WIDTH_SLOT] = self._width_slot_of.get(id(learner), -1)
    n_q = [self._q_size(b) for b in q]
    # None in a machine without a QTable, whose code then holds no Q-learning (as extras)
    planned = [n if getattr(b, "planning_every", 0) else 0 for b, n in zip(q, n_q)]
    qbank = QBank(_stack_rows([np.zeros(n) for n in n_q], np.float64),
                  _stack_rows([np.zeros(self._capacity(b)) for b in q], np.int64),
                  _stack_rows([np.zeros(self._capacity(b)) for b in q], np.float64),
                  np.zeros((max(len(q), 1), 1), dtype=np.int64),
                  np.zeros((max(len(q), 1), 2)),
                  _stack_rows([np.full(n, -1) for n in planned], np.int64),
                  _stack_rows([np.zeros(n) for n in planned], np.float64),
                  _stack_rows([np.zeros(n) for n in planned], np.float64),
                  np.zeros((max(len(q), 1), 1), dtype=np.int64)) if q else None
    # None in a machine without a Gaussian learner or actor-critic (the taxi's), whose
    # code then holds neither (the Q and Gibbs banks' pruning)
    gbank = GaussianBank(*_trace_rows([_trace_size(b) for b in g]),
                         _stack_rows([np.zeros(_values_size(b)) for b in g], np.float64),
                         el.Trace(*_trace_rows([b.coder.size for b in widths]))
                         if widths else None) if g else None
    self.tile_bank = self._tile_bank()
    k = int(self.tile_bank.n_tilings.max())
    depth = graph.depth()
    sb = self.schedule_block
    for name in getattr(sb, "watch", ()):
      if name not in index or isinstance(graph.nodes[name], Primitive):
        raise GraphError(f"the epsilon schedule watches {name!r}, which is not a subtask of "
                         f"the graph; subtasks: {sorted(n.name for n in graph.subtasks())}")
    if isinstance(sb, blocks.LinearEpsilon):
      eps, outcomes, counts = schedules.new_schedule(sb.start, 1, 1)
      settings = [0.0, 1.0, 1.0, LINEAR, sb.start, sb.end, sb.episodes, 0.0]
    else:
      eps, outcomes, counts = schedules.new_schedule(sb.epsilon, sb.window,
                                                     max(len(sb.watch), 1))
      settings = [sb.threshold, sb.every, sb.divisor, HELD, 0.0, 0.0, 0.0,
                  float(bool(sb.per_decision))]
    schedule = Schedule(eps, outcomes, counts, np.array(settings, dtype=np.float64))
    critics = [b.critic_coder for b in g if isinstance(b, blocks.ActorCritic)]
    n_max = max([int(nodes[i, N_CHILDREN]) for i in range(len(order))] + [1])
    stack = Stack(np.zeros((depth, 7), dtype=np.int64), np.zeros((depth, 6)),
                  np.zeros((depth, 2)), np.zeros((depth, 4, k), dtype=np.int64),
                  np.zeros((depth, k)), np.zeros((depth, k)),
                  np.array([0, 0, int(root_args.get("direction", -1)), 0, 0, 0], dtype=np.int64),
                  np.zeros(1),
                  np.zeros((len(order), 3)), np.zeros(4),
                  np.zeros((core.SAMPLES_PER_CONTROL + 1, 2)),
                  np.zeros(len(critics[0].low) if critics else 1),
                  np.zeros((core.SAMPLES_PER_CONTROL + 1, 2)), np.zeros(8, dtype=np.int64),
                  np.zeros(n_max, dtype=np.bool_), np.zeros(n_max),
                  np.zeros(n_max, dtype=np.int64), np.zeros(n_max), np.zeros(2, dtype=np.bool_),
                  np.zeros(4), np.zeros(4 if self.world is None else 5),
                  np.zeros(4, dtype=np.uint64))
    if len({len(c.low) for c in critics}) > 1:
      raise GraphError("the graph's actor-critics' critics code (state, action) of "
                       f"different sizes: {sorted({len(c.low) for c in critics})}")
    program = Program(nodes, params, np.array(children, dtype=np.int64).reshape(-1, 3),
                      rules_mod.compile_rules(self.rules), np.zeros(len(_FAR), dtype=np.int64),
                      np.zeros(0, dtype=np.int64) if self.world is None else self.world)
    extras = any(np.isin(nodes[:, column], kinds).any() for column, kinds in _EXTRA_KINDS)
    self.banks = Banks(program, qbank, self._gibbs_bank(), gbank, self.tile_bank, schedule, stack,
                       1 if extras else None, None if self.world is None else 1)
    # What the compiled functions take: each bank as a struct of the same arrays,
    # passed by reference (`learners.banks`: numba copied the namedtuples' ~45
    # arrays at every call and inlined call, at a high price in compile time).
    self.refs = (*banks_mod.as_structs(*self.banks[:-2]), self.banks.extras, self.banks.world)
    self._entries = {}                  # (function, generator state's kind) -> entry point
    # The step-by-step path's sampled positions, copied into an array of the machine's
    # own (`_positions`), so that their kind never changes between calls.
    self._positions_in = np.zeros((0, 2))
    self._state_seen = self._state_kind = None
    self._flags_set = (None, None)      # (learn, sample) last written by `_flags`
    self._refs_struct = None            # `refs` as one struct, made at the first `begin`
    # (generator state, entry point) of the last `advance` through `_compiled`: the next
    # with the same state calls that entry point straight away.
    self._advancing = (None, None)

  # -- what each block puts in the node's row --

  def _slot(self, kind, learner):
    if id(learner) not in self._slot_of:
      self._slot_of[id(learner)] = len(self.learners[kind])
      self.learners[kind].append(learner)
    return self._slot_of[id(learner)]

  def _learner(self, name, node, row, p, refs):
    learner = node.learner
    self._n_actions = getattr(self, "_n_actions", {})
    if isinstance(learner, (blocks.QTable, blocks.TiledQTable)):
      tiled = isinstance(learner, blocks.TiledQTable)
      row[LEARNER] = TILED_Q if tiled else Q_TABLE
      row[SLOT] = self._slot(Q_TABLE, learner)          # both in the QBank
      self._same_children(name, learner, refs)
      p[ALPHA], p[DECAY], p[GAMMA], p[EPSILON] = (learner.alpha, learner.trace_decay,
                                                  learner.gamma, learner.epsilon)
      row[EPS_SCHEDULE] = int(bool(learner.epsilon_schedule))
      if tiled and (not isinstance(node.view, blocks.StateTiles)
                    or node.view.coder != learner.coder):
        raise GraphError(f"subtask {name!r}: a TiledQTable needs a StateTiles view over its "
                         "own coder")
      if not tiled:
        self._table(name, node, row, "a QTable", (blocks.GridCell, blocks.CellRule,
                                                  blocks.TaxiState))
    elif isinstance(learner, blocks.RLearning):
      row[LEARNER] = AVERAGE_REWARD
      row[SLOT] = self._slot(Q_TABLE, learner)          # in the QBank
      self._same_children(name, learner, refs)
      p[ALPHA], p[GAIN_STEP], p[EPSILON], p[PLANNING_EVERY] = (
          learner.alpha, learner.gain_step, learner.epsilon, learner.planning_every)
      row[EPS_SCHEDULE] = int(bool(learner.epsilon_schedule))
      self._table(name, node, row, "an RLearning", (blocks.GridCell, blocks.CellRule,
                                                    blocks.PatrolCell))
    elif isinstance(learner, blocks.GibbsTable):
      row[LEARNER] = GIBBS_TABLE
      row[SLOT] = self._slot(GIBBS_TABLE, learner)
      self._same_children(name, learner, refs)
      p[ALPHA], p[DECAY], p[BETA] = learner.alpha, learner.trace_gamma, learner.baseline
      p[START_FRACTION], p[DELAY], p[RAMP] = (learner.start_fraction, learner.delay,
                                              learner.ramp)
      self._table(name, node, row, "a GibbsTable", (blocks.GridCell, blocks.CellRule,
                                                    blocks.TaxiState, blocks.TaxiAbstraction))
    elif isinstance(learner, blocks.ActorCritic):
      row[LEARNER] = ACTOR_CRITIC
      row[SLOT] = self._slot(GAUSSIAN_CMAC, learner)
      p[ALPHA], p[DECAY], p[ALPHA_ACTOR], p[R_MAX] = (learner.alpha_critic, learner.trace_decay,
                                                      learner.alpha_actor, learner.r_max)
      self._one_continuous_child(name, "an ActorCritic", refs)
      if not isinstance(node.view, blocks.StateTiles) or node.view.coder != learner.actor_coder:
        raise GraphError(f"subtask {name!r}: an ActorCritic needs a StateTiles view over its "
                         "actor_coder")
      row[CRITIC_SLOT] = len(self.codings)
      self.codings.append(learner.critic_coder)
    elif isinstance(learner, blocks.GaussianCMAC):
      row[LEARNER] = GAUSSIAN_CMAC
      row[SLOT] = self._slot(GAUSSIAN_CMAC, learner)
      p[ALPHA], p[DECAY], p[BETA], p[R_MAX] = (learner.alpha, learner.trace_gamma,
                                               learner.baseline, learner.r_max)
      p[WIDTH_ALPHA], p[LOG_SIGMA_LOW], p[LOG_SIGMA_HIGH] = (
          learner.width_alpha, math.log(learner.sigma_low), math.log(learner.sigma_high))
      self._one_continuous_child(name, "a GaussianCMAC", refs)
      if not isinstance(node.view, (blocks.LocalTiles, blocks.StateTiles, blocks.AimTiles)) \
          or node.view.coder != learner.coder:
        raise GraphError(f"subtask {name!r}: a GaussianCMAC needs a LocalTiles, StateTiles or "
                         "AimTiles view over its own coder")
    else:
      raise GraphError(f"subtask {name!r}: learner {learner!r} is not a machine learner; "
                       "allowed: QTable, TiledQTable, RLearning, GibbsTable, GaussianCMAC, "
                       "ActorCritic (hpg_mj.hierarchy.blocks)")

  @staticmethod
  def _table(name, node, row, kind, views):
    """A table learner's states (N_STATES), over a view of one of the kinds `views`."""
    row[N_STATES] = int(node.learner.n_states)
    if not isinstance(node.view, views):
      allowed = [v.__name__ for v in views]
      raise GraphError(f"subtask {name!r}: {kind} needs a {', '.join(allowed[:-1])} or "
                       f"{allowed[-1]} view, got {type(node.view).__name__}")

  def _q_size(self, learner):
    """A QBank row's weights: a table's states, or a TiledQTable's tiles, x its actions."""
    n = learner.coder.size if isinstance(learner, blocks.TiledQTable) else learner.n_states
    return n * self._n_actions[id(learner)]

  def _capacity(self, learner):
    """A Q learner's trace: its capacity (None: every weight once); RLearning has none."""
    return getattr(learner, "trace_capacity", 1) or self._q_size(learner)

  def _same_children(self, name, learner, refs):
    """A table's children: the same number at every node that shares it."""
    known = self._n_actions.setdefault(id(learner), len(refs))
    if known != len(refs):
      raise GraphError(f"subtask {name!r}: its {type(learner).__name__} is shared with a node of "
                       f"{known} children, it has {len(refs)}")

  def _taxi_id(self, name, block):
    if self.world is None:
      raise GraphError(f"subtask {name!r}: a {type(block).__name__} needs the machine's taxi "
                       "world (Machine(graph, world=taxi_rules.world_config(rules)))")
    return blocks.TAXI_SUBTASKS.index(block.subtask)

  def _available(self, name, node, row, p):
    """The node's AVAILABLE_AT: a TaxiChildren's subtask id, -1 without one (a
    NearGateLine sets its OFFER)."""
    available = node.available
    if available is None:
      return -1
    if isinstance(available, blocks.NearGateLine):
      if not isinstance(node.learner, blocks.TiledQTable):
        raise GraphError(f"subtask {name!r}: only a TiledQTable offers its children by "
                         f"NearGateLine; its learner is a {type(node.learner).__name__}")
      row[OFFER], p[WITHIN_M] = OFFER_NEAR_GATE, float(available.within_m)
      return -1
    if not isinstance(available, blocks.TaxiChildren):
      raise GraphError(f"subtask {name!r}: available {available!r} is not a machine block; "
                       "allowed: None, TaxiChildren, NearGateLine (hpg_mj.hierarchy.blocks)")
    if not isinstance(node.learner, blocks.GibbsTable):
      raise GraphError(f"subtask {name!r}: only a GibbsTable chooses among available children; "
                       f"its learner is a {type(node.learner).__name__}")
    return self._taxi_id(name, available)

  def _argument(self, name, ref):
    """A child's C_ARG: its `direction` or `target` argument (-1: none)."""
    unknown = sorted(set(ref.args) - set(ARGUMENTS))
    if unknown or len(ref.args) > 1:
      raise GraphError(f"subtask {name!r}: its child {ref.node!r} takes {sorted(ref.args)}; "
                       f"the machine passes one integer argument, one of {list(ARGUMENTS)}")
    for key, value in ref.args.items():
      self.argument_names[self.index_of[ref.node]] = key
      return int(value)
    return -1

  def _binding(self, name, ref):
    """A child's C_BIND: a TaxiTarget's subtask id, -1 without one."""
    if ref.bind is None:
      return -1
    if not isinstance(ref.bind, blocks.TaxiTarget):
      raise GraphError(f"subtask {name!r}: its child {ref.node!r} binds by {ref.bind!r}, not a "
                       "machine block; allowed: None, TaxiTarget (hpg_mj.hierarchy.blocks)")
    return self._taxi_id(name, ref.bind)

  def _one_continuous_child(self, name, kind, refs):
    if len(refs) != 1 or self.graph.nodes[refs[0].node].action is not None:
      raise GraphError(f"subtask {name!r}: {kind}'s one child is a continuous primitive "
                       "(Primitive(name) without an action)")

  def _view(self, name, node, row, p):
    view = node.view
    if isinstance(view, blocks.GridCell):
      row[VIEW] = VIEW_GRID_CELL
      p[CELL_M], p[GRID] = float(view.cell_m), float(view.grid)
      self._states(name, node, "GridCell", int(view.grid) ** 2)
    elif isinstance(view, blocks.PatrolCell):
      row[VIEW] = VIEW_PATROL_CELL
      p[SECTORS], p[NEAR_GATE_M], p[NEAR_GATE_CELL_M] = (view.heading_sectors, view.near_gate_m,
                                                         view.near_gate_cell_m)
      self._states(name, node, "PatrolCell", view.n_states())
    elif isinstance(view, blocks.CellRule):
      row[VIEW] = VIEW_RULE
      row[VIEW_SLOT] = self._rule(name, rules_mod.VIEW, view.rule)
    elif isinstance(view, (blocks.LocalTiles, blocks.StateTiles)):
      if isinstance(view, blocks.LocalTiles):
        self._ship_only(name, "LocalTiles")
      row[VIEW] = VIEW_LOCAL_TILES if isinstance(view, blocks.LocalTiles) else VIEW_STATE_TILES
      row[VIEW_SLOT] = len(self.codings)
      self.codings.append(view.coder)
    elif isinstance(view, blocks.AimTiles):
      row[VIEW] = VIEW_AIM_TILES
      row[VIEW_SLOT] = len(self.codings)
      self.codings.append(view.coder)
      t = view.targets
      p[INSET_M], p[APPROACH_M], p[RADIUS_M] = t.inset_m, t.approach_m, t.radius_m
      p[SQRT_ERROR] = float(view.error_scale == "sqrt")
      p[REFLECT_AT] = ship_rules.error_coordinate(view.reflect_deg, view.error_scale)
    elif isinstance(view, blocks.TaxiState):
      self._taxi_id(name, blocks.TaxiAbstraction("root"))      # needs the world
      row[VIEW] = VIEW_TAXI_STATE
      self._states(name, node, "TaxiState", taxi_core.num_states(
          bool(self.world[taxi_rules.W_FUEL_ENABLED]), int(self.world[taxi_rules.W_CAPACITY])))
    elif isinstance(view, blocks.TaxiAbstraction):
      row[VIEW] = VIEW_TAXI_ABSTRACT
      row[VIEW_SLOT] = self._taxi_id(name, view)
      self._states(name, node, "TaxiAbstraction", taxi_subtasks.n_abstract_states(
          bool(self.world[taxi_rules.W_FUEL_ENABLED]),
          int(self.world[taxi_rules.W_CAPACITY]))[row[VIEW_SLOT]])
    else:
      raise GraphError(f"subtask {name!r}: view {view!r} is not a machine view; allowed: "
                       "GridCell, PatrolCell, LocalTiles, StateTiles, AimTiles, CellRule, "
                       "TaxiState, TaxiAbstraction (hpg_mj.hierarchy.blocks)")

  def _states(self, name, node, view, n):
    """A table has as many states as its view (a grid, a taxi abstraction, ...)."""
    if node.learner.n_states != n:
      raise GraphError(f"subtask {name!r}: its {view} view has {n} states, its "
                       f"{type(node.learner).__name__} {node.learner.n_states}")

  def _rule(self, name, kind, rule):
    """The rule's number among the graph's rules."""
    self.rules.append((name, kind, rule))
    return len(self.rules) - 1

  def _ship_only(self, name, block):
    """A block of the ship's local frame is refused in a machine with a taxi world,
    whose code does not hold it (`W is None` prunes it there)."""
    if self.world is not None:
      raise GraphError(f"subtask {name!r}: {block} is a block of the ship's local frame; a "
                       "machine with a taxi world (Machine(graph, world=...)) cannot run it")

  def _end(self, name, node, row, p):
    end, internal = node.termination, node.internal_reward
    if isinstance(end, blocks.Never):
      row[END] = END_NEVER
    elif isinstance(end, blocks.LocalGoal):
      self._ship_only(name, "LocalGoal")
      row[END] = END_LOCAL_GOAL
      row[MAX_STEPS] = int(end.max_steps)
    elif isinstance(end, blocks.Clock):
      if name != self.graph.root:
        raise GraphError(f"subtask {name!r}: a Clock ends only the root (a continuing task's "
                         f"record row); the root is {self.graph.root!r}")
      row[END] = END_CLOCK
      row[MAX_STEPS] = int(end.steps)
    elif isinstance(end, blocks.TargetReached):
      if row[VIEW] != VIEW_AIM_TILES:
        raise GraphError(f"subtask {name!r}: a TargetReached ends a node with an AimTiles "
                         f"view (its targets); its view is a {type(node.view).__name__}")
      row[END] = END_TARGET
      row[MAX_STEPS] = int(end.max_steps)
    elif isinstance(end, blocks.EndRule):
      row[END] = END_RULE
      row[END_AT] = self._rule(name, rules_mod.END, end.rule)
    elif isinstance(end, blocks.TaxiEnd):
      row[END] = END_TAXI
      row[END_AT] = self._taxi_id(name, end)
    else:
      raise GraphError(f"subtask {name!r}: termination {end!r} is not a machine "
                       "termination; allowed: Never, Clock, LocalGoal, TargetReached, EndRule, "
                       "TaxiEnd (hpg_mj.hierarchy.blocks)")
    if internal is None:
      row[INTERNAL] = G_NONE
    elif isinstance(internal, blocks.Shaping) and (
        row[END] == END_TARGET or (row[END] == END_LOCAL_GOAL and internal.weight == 1.0)):
      row[INTERNAL] = G_SHAPING
      p[SHAPING_WEIGHT] = float(internal.weight)
    elif isinstance(internal, blocks.RewardRule):
      row[INTERNAL] = G_RULE
      row[G_AT] = self._rule(name, rules_mod.REWARD, internal.rule)
    else:
      raise GraphError(f"subtask {name!r}: internal reward {internal!r} is not allowed; "
                       "allowed: None, RewardRule, Shaping() with a LocalGoal termination, "
                       "Shaping(weight) with a TargetReached")
    seen = node.reward if node.reward is not None else blocks.SUMMED
    if seen not in (blocks.SUMMED, blocks.STEP):
      raise GraphError(f"subtask {name!r}: reward {seen!r} is not allowed; allowed: "
                       f"{blocks.SUMMED!r}, {blocks.STEP!r}")
    row[SEEN] = SEEN_STEP if seen == blocks.STEP else SEEN_SUMMED

  def _tile_bank(self):
    coders = self.codings or [tiles_mod.TileCoder((0.0,), (1.0,), (1,), (False,), 1)]
    made = [c.arrays() for c in coders]
    dims = max(len(c.low) for c in coders)
    k = max(c.n_tilings for c in coders)
    low = np.zeros((len(made), dims))
    width = np.ones((len(made), dims))
    n_tiles = np.ones((len(made), dims), dtype=np.int64)
    wrap = np.zeros((len(made), dims), dtype=np.bool_)
    offsets = np.zeros((len(made), k, dims))
    for i, t in enumerate(made):
      n = len(t.low)
      low[i, :n], width[i, :n], n_tiles[i, :n], wrap[i, :n] = t.low, t.width, t.n_tiles, t.wrap
      offsets[i, :t.offsets.shape[0], :n] = t.offsets
    return TileBank(low, width, n_tiles, wrap, offsets,
                    np.array([c.n_tilings for c in coders], dtype=np.int64),
                    np.array([len(c.low) for c in coders], dtype=np.int64))

  def _gibbs_bank(self):
    """The GibbsTables' bank, or None in a machine without one (whose code then holds
    no Gibbs policy: the Q bank's pruning)."""
    tables = self.learners[GIBBS_TABLE]
    if not tables:
      return None
    return GibbsBank(*_trace_rows([b.n_states * self._n_actions[id(b)] for b in tables]),
                     _stack_rows([np.zeros(b.n_states) for b in tables], np.float64),
                     np.zeros(len(tables)))

  # -- the learners' arrays, by name --

  def gibbs_arrays(self, learner):
    """The Eq. 3 trace (`eligibility.Trace`) and baseline values of a GibbsTable."""
    slot = self._slot_of[id(learner)]
    return (self._bank_trace(slot, learner.n_states * self._n_actions[id(learner)],
                             self.banks.gibbs), self.banks.gibbs.values[slot, :learner.n_states])

  def q_arrays(self, learner):
    """(q, trace index, trace value, trace count) of a QTable or TiledQTable (views of
    the bank)."""
    slot = self._slot_of[id(learner)]
    n = self._q_size(learner)
    b = self.banks.q
    return b.q[slot, :n], b.index[slot], b.value[slot], b.count[slot]

  def r_learning_arrays(self, learner):
    """(q, gain [rho, greedy transitions], the planning model (next, reward, steps,
    [count])) of an RLearning (views of the bank)."""
    slot = self._slot_of[id(learner)]
    n = self._q_size(learner)
    b = self.banks.q
    m = n if learner.planning_every else 0
    return (b.q[slot, :n], b.gain[slot], (b.model_next[slot, :m], b.model_reward[slot, :m],
                                          b.model_steps[slot, :m], b.model_count[slot]))

  def gaussian_arrays(self, learner):
    """The Eq. 3 trace (`eligibility.Trace`) and baseline values of a GaussianCMAC."""
    slot = self._slot_of[id(learner)]
    return self._bank_trace(slot, learner.coder.size), \
        self.banks.gaussian.values[slot, :learner.coder.size]

  def actor_critic_arrays(self, learner):
    """(the actor's weights, the critic's trace `eligibility.Trace`) of an ActorCritic."""
    slot = self._slot_of[id(learner)]
    return (self.banks.gaussian.values[slot, :learner.actor_coder.size],
            self._bank_trace(slot, learner.critic_coder.size))

  def width_trace(self, learner):
    """The trace (`eligibility.Trace`) of a GaussianCMAC's learned width, or None."""
    slot = self._width_slot_of.get(id(learner))
    return None if slot is None else self._bank_trace(slot, learner.coder.size,
                                                      self.banks.gaussian.widths)

  def _bank_trace(self, slot, n, bank=None):
    """The Eq. 3 trace of row `slot` of the GaussianBank (or of `bank`, its widths)
    over its first n weights (views)."""
    b = self.banks.gaussian if bank is None else bank
    return el.Trace(b.theta[slot, :n], b.zs[slot, :n], b.y[slot, :n], b.touched[slot, :n],
                    b.marked[slot, :n], b.count[slot], b.acc[slot])

  @property
  def epsilon_schedule(self):
    s = self.banks.schedule
    return s.epsilon, s.outcomes, s.counts

  # -- running it --

  def _bottom_up(self):
    """The machine's functions, callees first, with arguments of the types its
    callers pass (`_link`: each then compiles near the top of the Python stack, as
    `learners.jit.compile_first` has them). One list for every graph: their types do
    not depend on it."""
    b = self.refs
    d = np.int64(0)
    gibbs = [] if b[2] is None else [(_gibbs_choose, (b[0], b[2], b[6], b[8], d))]
    gaussian = [] if b[3] is None else [(_gaussian_choose, (b[0], b[3], b[4], b[6], d))]
    return [*gibbs, *gaussian, (_view, (*b, d, d)), (_call, (*b, d, d, d)), (_descend, (*b, d)),
            (_observe, (*b, d, 0.0, False, False)), (step, (*b, _NO_SAMPLES, 0.0, False, False))]

  def _link(self):
    """Compiles (or loads) the machine's functions from the bottom up, as
    `learners.jit.compile_first` does, and sets the addresses of those called
    through them (`_FAR`) in this machine's program: once per machine, before its
    first compiled call (a function the graph does not need, such as the Gaussian
    choice of a machine without one, keeps address 0)."""
    calls = self.banks.program.calls
    if calls[CALL_STEP]:
      return
    for function, example in self._bottom_up():
      address = jit.address_of(function, example)
      if function in _FAR:
        calls[_FAR.index(function)] = address

  def _flags(self, learn, sample):
    """The run's flags (RUN_LEARN, RUN_SAMPLE) for the compiled calls that follow,
    written when they change (the machine's code only reads them)."""
    if learn is self._flags_set[0] and sample is self._flags_set[1]:
      return
    flags = self.banks.stack.flags
    flags[RUN_LEARN] = bool(learn)
    flags[RUN_SAMPLE] = bool(sample)
    self._flags_set = (learn, sample)

  def run(self, episodes, learn, sample, rng_state, world, start=None):
    """Episodes fused with the analytic ship; `world` as `run_ship`'s (its last
    entry may be left out: the full task); rows as `run_ship` writes them."""
    self._link()
    rows = self._rows(episodes)
    fixed = np.empty(0) if start is None else np.asarray(start, dtype=np.float64)
    world = np.concatenate([np.asarray(world, dtype=np.float64), np.zeros(4)])[:4]
    self._observation_size(4)
    self._flags(learn, sample)
    run_ship(*self.refs, int(episodes), rng_state, world, rows, fixed)
    return rows

  def run_continuing(self, rows, learn, sample, rng_state, world, ship):
    """`rows` record rows of the continuing ship task (`run_ship`'s world[3] = 2) from
    `ship`, the process's state (float64[4], sailed on in place); `world` = (gate
    reward, out-of-bounds reward)."""
    self._link()
    out = self._rows(rows)
    world = np.array([world[0], world[1], 0.0, 2.0], dtype=np.float64)
    self._observation_size(4)
    self._flags(learn, sample)
    run_ship(*self.refs, int(rows), rng_state, world, out, ship)
    return out

  def run_taxi(self, episodes, learn, sample, rng_state, starts=None):
    """Episodes fused with the taxi of the machine's `world`, from `starts` (rows of
    taxi_rules' state, used in turn; None: drawn); rows as `run_taxi` writes them."""
    if self.world is None:
      raise GraphError("run_taxi: this machine was built without a taxi world "
                       "(Machine(graph, world=taxi_rules.world_config(...)))")
    rows = self._rows(episodes)
    self._observation_size(5)
    starts = np.zeros((0, 5), dtype=np.int64) if starts is None else \
        np.ascontiguousarray(starts, dtype=np.int64).reshape(-1, 5)
    args = (*self.refs, int(episodes), rng_state, rows, starts)
    self._link_taxi_loop(args)
    self._flags(learn, sample)
    run_taxi(*args)
    return rows

  def _link_taxi_loop(self, args):
    """`_link` for the taxi's fused loop, called with `args`. The loop calls only
    `_call` and `_descend` through their addresses and links the rest of the machine
    into its own code: when its code for these types and theirs are in this process or
    numba's cache, only they are loaded (the other four, loaded as functions of their
    own, took ~35 ms of a ~1.5 s taxi run's start); otherwise all is, from the bottom
    up, before the loop compiles (its unused calls through addresses are typed too)."""
    calls = self.banks.program.calls
    signature = tuple(numba.typeof(a) for a in args)
    if calls[CALL_CALL] and signature in run_taxi.overloads:
      return
    far = [(f, example) for f, example in self._bottom_up() if f in (_call, _descend)]
    if all(jit.load_cached(f, jit.canonical_signature(example)) for f, example in far) and \
        jit.load_cached(run_taxi, signature):
      for f, example in far:
        calls[_FAR.index(f)] = jit.address_of(f, example)
    else:
      self._link()

  def _rows(self, episodes):
    return np.zeros((int(episodes), ROW_COUNTERS + 3 * len(self.names)))

  def start_schedule(self, learned_episodes):
    """The schedules that follow the learning episodes (a linear epsilon, the
    GibbsTables' step sizes) at `learned_episodes`, the agent's count, which a run
    resumes from; a held epsilon keeps its own state."""
    self.banks.stack.episode[E_LEARNED] = int(learned_episodes)
    sb, s = self.schedule_block, self.banks.schedule
    if isinstance(sb, blocks.LinearEpsilon):
      s.epsilon[3] = float(learned_episodes)
      s.epsilon[0] = schedules.linear(float(learned_episodes), sb.start, sb.end, sb.episodes)

  def begin(self, obs, learn, sample, rng_state):
    """Resumable: an episode starts at `obs`; returns the first action."""
    self._observation(obs)
    self._flags(learn, sample)
    return self._compiled(_begin_with, rng_state)

  def advance(self, obs, reward, terminated, truncated, info, learn, sample, rng_state):
    """Resumable: the environment stepped; returns (episode over, next action).

    The observation and the sampled positions (`info["positions"]`) of an environment
    that gives them as float64 arrays in C order (the ship's, every step's new arrays)
    go to the compiled code as they are, which reads them within the call and keeps
    none; others are first copied into arrays of the machine's own (`_observation`,
    `_positions`), as every call through `_compiled` has them: an entry point checks
    only an array's item size, and copying both cost ~0.7 us of a ~10 us step through
    the MuJoCo ship."""
    samples = _NO_SAMPLES
    if info:
      positions = info.get("positions")
      if positions is not None:
        samples = positions
        if type(samples) is not np.ndarray or samples.dtype is not _F64 or \
            samples.strides != _ROWS_OF_XY:
          samples = self._positions(positions)
      before = info.get("state_before_restart")
      if before is not None:        # a continuing ship restarted: its root sees `obs`
        k = self.banks.stack
        k.restart[:] = obs
        k.episode[E_RESTART] = 1
        obs = before
    self._flags(learn, sample)
    state, entry = self._advancing
    if state is rng_state:          # `_compiled`'s entry point for this state, called as it would
      if type(obs) is not np.ndarray or obs.dtype is not _F64 or obs.strides != _VECTOR:
        obs = self._observation(obs, within_episode=True)
      return entry(self._refs_struct, obs, samples, float(reward), bool(terminated),
                   bool(truncated), rng_state)
    if samples is not _NO_SAMPLES:
      samples = self._positions(samples)
    out = self._compiled(_advance_with, self._observation(obs, within_episode=True), samples,
                         float(reward), bool(terminated), bool(truncated), rng_state)
    if rng_state is self._state_seen:   # not a strided state, which went in as a C copy
      self._advancing = (rng_state, self._entries[(_advance_with, self._state_kind)])
    return out

  def _observation(self, values, within_episode=False):
    """The step-by-step path's observation written into the stack's `obs`, which the
    machine's functions read, as float64 (the compiled entry points then see arrays of
    one kind on every call); returns that array. An episode's first sets its length."""
    if type(values) is not np.ndarray:
      values = np.asarray(values)
    obs = self.banks.stack.obs
    if values.shape != obs.shape:
      if values.ndim != 1:
        raise ValueError(f"Machine: obs must be a vector of numbers, got shape {values.shape}")
      if within_episode:
        raise ValueError("Machine.advance: obs is not of the length of the episode's first")
      self._observation_size(values.shape[0])
      obs = self.banks.stack.obs
    obs[...] = values
    return obs

  def _observation_size(self, n):
    """The stack's `obs` of n numbers: a new array where its length differs, and the
    stack's struct made again around it (a struct's arrays are fixed when it is made)."""
    stack = self.banks.stack
    if stack.obs.shape[0] == n:
      return
    self.banks = self.banks._replace(stack=stack._replace(obs=np.zeros(n)))
    (k,) = banks_mod.as_structs(self.banks.stack)
    self.refs = (*self.refs[:6], k, *self.refs[7:])
    self._refs_struct = None
    self._advancing = (None, None)

  def _positions(self, values):
    """The positions sampled in a step (info['positions'], rows of (x, y)) copied into
    the machine's own array as float64, as `_observation` does the observation. The
    compiled code reads them within the call and keeps none."""
    if type(values) is not np.ndarray:
      values = np.asarray(values)
    buffer = self._positions_in
    if values.shape != buffer.shape:
      if values.ndim != 2 or values.shape[1:] != buffer.shape[1:]:
        raise ValueError("Machine: info['positions'] must be rows of (x, y) of numbers, "
                         f"got shape {values.shape}")
      buffer = self._positions_in = np.empty(values.shape)
    buffer[...] = values
    return buffer

  def _compiled(self, fn, *args):
    """fn(refs, *args), `refs` the machine's structs as one (`Refs`), through the entry
    point numba compiled for these types. numba's dispatcher types every argument on each
    call, and typing the banks, when they were namedtuples of arrays, cost three quarters
    of a step-by-step step (the hybrid through the MuJoCo ship: 12,000 control steps a
    second, 41,000 this way). An entry point checks no types (a float32 array would be
    read as float64): the arrays passed are the machine's own (`_input`) and the scalars
    Python's float and bool, of one kind on every call, but for the generator state, the
    caller's (the last argument), whose kind (its dtype, dimensions and flags) is read
    again whenever another array is passed; another kind goes through the dispatcher
    first."""
    state = args[-1]
    if state is not self._state_seen:
      if not (state.flags.c_contiguous and state.flags.writeable):
        contiguous = np.array(state, order="C")    # the compiled code takes C arrays (jit.call_at)
        out = self._compiled(fn, *args[:-1], contiguous)
        state[...] = contiguous
        return out
      self._state_seen, self._state_kind = state, _kind(state)
    key = (fn, self._state_kind)
    entry = self._entries.get(key)
    if self._refs_struct is None:     # made at the first call, again after `_observation_size`
      self._link()
      (self._refs_struct,) = banks_mod.as_structs(Refs(*self.refs))
    if entry is None:
      out = fn(self._refs_struct, *args)
      found = fn.overloads.get(tuple(numba.typeof(a) for a in (self._refs_struct, *args)))
      self._entries[key] = fn if found is None else found.entry_point
      return out
    return entry(self._refs_struct, *args)

  def counters(self):
    """This episode's per-node counters (calls, runs, successes), flattened."""
    return self.banks.stack.counters.reshape(-1).copy()


_NO_SAMPLES = np.zeros((core.SAMPLES_PER_CONTROL + 1, 2))
# What `advance` passes as it is: float64 (the one native dtype object), in C order.
_F64 = np.dtype(np.float64)
_VECTOR, _ROWS_OF_XY = (8,), (16, 8)


def _kind(value):
  """What an entry point's signature fixes of an argument (`Machine._compiled`)."""
  if isinstance(value, np.ndarray):
    f = value.flags
    return value.dtype.str, value.ndim, f.c_contiguous, f.f_contiguous, f.writeable, f.aligned
  return type(value)


def _tell_calls(machine, on_call):
  """`on_call` of each call below the root that has just begun (no step taken in it)."""
  from hpg_mj.hierarchy.graph import Call
  k = machine.banks.stack
  for d in range(1, int(k.episode[E_DEPTH]) + 1):
    if k.ints[d, S_STEPS] == 0:
      arg = int(k.ints[d, S_ARG])
      node = int(k.ints[d, S_NODE])
      name = machine.argument_names.get(node)
      on_call(Call(machine.names[node], {name: arg} if name is not None else {},
                   k.origin[d].copy()))


def run_stepwise(machine, env, episodes, learn, sample, rng_state, start, ended,
                 on_call=None):
  """The step-by-step path: `episodes` episodes of `machine` through `env` (any
  Gymnasium or dm_control environment), each from `start()` (None: the
  environment's own). Without learning the policies are greedy unless `sample`.
  `ended(last)` gives the row's end (ROW_END) from the episode's last step (an
  `executor.Step`: the ship's gate passed, the taxi's outcome). `on_call(call)`, if given, is
  told of every subtask called below the root (a `graph.Call`: its node, its
  arguments, the state where it was called), as the executor tells it. Rows as
  `run_ship`'s (ROW_ILLEGAL stays 0)."""
  from hpg_mj.hierarchy import executor     # the environments' adapters
  adapter = executor.adapter_for(env)
  step, advance = executor.step_values(adapter), machine.advance
  sample = learn if sample is None else (sample or learn)
  rows = machine._rows(episodes)
  for i in range(int(episodes)):
    obs = adapter.reset(start())
    action = machine.begin(obs, learn, sample, rng_state)
    if on_call is not None:
      _tell_calls(machine, on_call)
    over = False
    while not over:
      obs, reward, terminated, truncated, info = step(action)
      over, action = advance(obs, reward, terminated, truncated, info, learn, sample, rng_state)
      if on_call is not None and not over:
        _tell_calls(machine, on_call)
    rows[i, ROW_END] = ended(executor.Step(obs, float(reward), bool(terminated),
                                           bool(truncated), info))
    rows[i, ROW_STEPS] = machine.banks.stack.episode[E_STEPS]
    rows[i, ROW_RETURN] = machine.banks.stack.total[0]
    rows[i, ROW_COUNTERS:] = machine.counters()
  return rows


__all__ = ["Machine", "Child", "Primitive", "Subtask", "begin", "step", "advance", "run_ship",
           "run_taxi", "run_stepwise"]
