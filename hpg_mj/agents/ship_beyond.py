"""A route past the paper's (SPEC section 8; issue 12, item 4): a root that sees
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
"""
import collections
import dataclasses
import math

import numba
import numpy as np

from hpg_mj.agents import _ship
from hpg_mj.agents.taskfile import param
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import Child, Primitive, Subtask, TaskGraph
from hpg_mj.learners import stepwise as learners
from hpg_mj.learners import arrays
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import qlambda
from hpg_mj.learners import rng
from hpg_mj.learners import schedules
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core as core

PASSED, STEPS, CALLS, AIM_RUNS, AIM_SUCCESS, RETURN = range(6)
N_RECORD = 6
GATE_X = 0.5 * (core.GATE[0, 0] + core.GATE[1, 0])
GATE_Y = core.GATE[0, 1]
GATE_WIDTH = core.GATE[1, 0] - core.GATE[0, 0]
APPROACH_DX = (-100.0, 0.0, 100.0)   # approach points: x of the gate's middle + these
DISTANCE_CLIP = 400.0                # the aim state's distance saturates here (m)

Settings = collections.namedtuple("Settings", (
    "root_alpha", "root_trace_decay", "root_epsilon_threshold", "root_epsilon_every",
    "root_epsilon_divisor", "root_inset_m", "root_approach_within_m",
    "root_approach_m",
    "alpha", "trace_gamma", "baseline", "max_steps", "width_alpha", "log_sigma_low",
    "log_sigma_high", "radius_m", "shaping",
    "sqrt_error", "reflect_at",
    "environment_max_steps", "environment_gate_reward", "environment_out_of_bounds_reward"))
RootTable = collections.namedtuple("RootTable", ("q", "index", "value", "count"))


def settings(config):
  root, low, env = config.root, config.low_level, config.environment
  return Settings(float(root.alpha), float(root.trace_decay), float(root.epsilon_threshold),
                  int(root.epsilon_every), float(root.epsilon_divisor), float(root.inset_m),
                  float(root.approach_within_m), float(root.approach_m),
                  float(low.alpha), float(low.trace_gamma), float(low.baseline),
                  int(low.max_steps), float(low.width_alpha), math.log(low.sigma_low),
                  math.log(low.sigma_high), float(low.radius_m), float(low.shaping),
                  low.error_scale == "sqrt", error_coordinate(low.reflect_deg, low.error_scale),
                  int(env.max_steps), float(env.gate_reward), float(env.out_of_bounds_reward))


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


# ---- the rules, one implementation for both paths ---------------------------------

@numba.njit(cache=True)
def root_tiles(state, tiling, view, out):
  """The root's state: the active tiles (one per tiling, into `out`) of the ship's
  position and heading (`view`: scratch for the three)."""
  view[0] = state[0]
  view[1] = state[1]
  view[2] = state[2]
  tiles_mod.active_tiles(view, tiling, out)


@numba.njit(cache=True)
def n_targets(s):
  return 1 + len(APPROACH_DX)


@numba.njit(cache=True)
def offered(state, s):
  """How many of the root's choices start here (their initiation sets, Sutton, Precup
  & Singh 1999): the gate everywhere, the approach points within
  `root_approach_within_m` of the gate line."""
  return n_targets(s) if abs(state[1] - GATE_Y) <= s.root_approach_within_m else 1


@numba.njit(cache=True)
def side_of(y):
  """Which side of the gate line a height lies on (the line itself counts as north)."""
  return 1.0 if y >= GATE_Y else -1.0


@numba.njit(cache=True)
def target_of(action, state, side, s):
  """The point the root's `action` steers to now. Action 0, *gate*: the point of
  the gate (its posts moved in by `root_inset_m`) nearest the ship, followed as
  the ship moves (a continuous target). Actions 1-3, *approach*: fixed points
  `root_approach_m` before the gate line on the side `side` of the call's start,
  at the gate's middle x + APPROACH_DX."""
  if action == 0:
    low = core.GATE[0, 0] + s.root_inset_m
    high = core.GATE[1, 0] - s.root_inset_m
    return min(max(state[0], low), high), GATE_Y
  return GATE_X + APPROACH_DX[action - 1], GATE_Y + side * s.root_approach_m


def error_coordinate(e_deg, error_scale):
  """A heading error's coordinate on the aim tiles."""
  return 180.0 * math.sqrt(e_deg / 180.0) if error_scale == "sqrt" else float(e_deg)


@numba.njit(cache=True)
def aim_view(state, tx, ty, out, sqrt_error=False, reflect_at=180.0):
  """The aim subtask's state: heading error e to the target (deg, wrapped; with
  `sqrt_error` as 180 sign(e) sqrt(|e| / 180), still in [-180, 180], so that the
  tiles are finer near e = 0, where the ship holds its course), turning rate,
  distance (clipped at DISTANCE_CLIP). Returns the side, 1 or -1: with the error's
  coordinate below -`reflect_at`, the state is reflected about the line to the
  target, (e, turning rate) -> (-e, -turning rate), and the side is -1. Equation 1
  is symmetric under the reflection with r -> -r, so the policy's r times the side
  steers both sides of a large error with one set of tiles, each learning from
  the starts of both (the ship must turn the short way round; near e = 0, where
  it holds its course, both sides keep their own tiles: no fold there)."""
  e = core.wrap_deg(state[2] - core.bearing_deg(state[0], state[1], tx, ty))
  q = math.copysign(180.0 * math.sqrt(abs(e) / 180.0), e) if sqrt_error else e
  side = -1.0 if q < -reflect_at else 1.0
  out[0] = side * q
  out[1] = side * state[3]
  out[2] = min(math.hypot(tx - state[0], ty - state[1]), DISTANCE_CLIP)
  return side


@numba.njit(cache=True)
def aim_outcome(samples, state, action, tx, ty, steps_in_call, global_event, s):
  """After one control step inside an aim call: (local event, G). SUCCESS through
  the gate, or (approach) within `radius_m` of the target; FAILURE off the field,
  after `max_steps`, or (gate) across the gate line beside the gate; G = the
  heading shaping towards the target (SPEC section 3's G, times `shaping`), +100 / -100."""
  event = core.NO_EVENT
  if global_event == core.SUCCESS:
    event = core.SUCCESS
  elif global_event == core.FAILURE:
    event = core.FAILURE
  else:
    for k in range(1, samples.shape[0]):
      if action == 0:
        if (samples[k - 1, 1] - GATE_Y) * (samples[k, 1] - GATE_Y) < 0.0:
          event = core.FAILURE                           # crossed the line, missed the gate
          break
      elif math.hypot(samples[k, 0] - tx, samples[k, 1] - ty) <= s.radius_m:
        event = core.SUCCESS
        break
    if event == core.NO_EVENT and steps_in_call >= s.max_steps:
      event = core.FAILURE
  internal = s.shaping * core.shaping_reward(state[0], state[1], state[2], tx, ty)
  if event == core.SUCCESS:
    internal += core.GATE_REWARD
  elif event == core.FAILURE:
    internal += core.OUT_OF_BOUNDS_REWARD
  return event, internal


@numba.njit(cache=True)
def run_aim(state, action, trace, width, values, tiling, s, learn, sample, rng_state,
            steps_before, scratch):
  """One call of the aim subtask for the root's `action` from `state` (in place).
  Returns (global event, local event, reward to the root, control steps)."""
  tiles, next_tiles, psi, psi_width, samples, view = scratch
  el.reset(trace)                                       # Eq. 3: z <- 0
  el.reset(width)
  reward_root = 0.0
  k = 0
  side = side_of(state[1])
  tx, ty = target_of(action, state, side, s)
  while True:
    reflected = aim_view(state, tx, ty, view, s.sqrt_error, s.reflect_at)
    tiles_mod.active_tiles(view, tiling, tiles)
    r = policies.gaussian_choose(trace, values, tiles, psi, s.alpha, s.baseline,
                                 core.MAX_TURN_RATE, learn, sample, rng_state, width, psi_width,
                                 s.width_alpha, s.log_sigma_low, s.log_sigma_high)
    r *= reflected                                       # the reflection's r -> -r
    core.euler_control(state, r, samples)
    k += 1
    global_event, reward = core.global_outcome(samples, s.environment_gate_reward,
                                               s.environment_out_of_bounds_reward)
    reward_root += reward
    tx, ty = target_of(action, state, side, s)           # the target after the step
    local_event, internal = aim_outcome(samples, state, action, tx, ty, k, global_event, s)
    ended = (global_event != core.NO_EVENT or local_event != core.NO_EVENT
             or steps_before + k >= s.environment_max_steps)
    if learn:
      if not ended:
        aim_view(state, tx, ty, view, s.sqrt_error, s.reflect_at)
        tiles_mod.active_tiles(view, tiling, next_tiles)
      policies.gaussian_learn(trace, values, tiles, next_tiles, s.alpha, s.trace_gamma,
                              s.baseline, core.STEP_REWARD + internal, ended, width,
                              s.width_alpha)
    if ended:
      return global_event, local_event, reward_root, k


@numba.njit(cache=True)
def train(n_episodes, learn, sample, rng_state, root, root_tiling, schedule, trace, width,
          values, tiling, s, record, fixed_start):
  """`n_episodes` episodes of the full task (Algorithm 1 over this graph); with
  learn=False only the policy runs, sampled or greedy (epsilon 0, u = m)."""
  eps_state, outcomes, counts = schedule
  state = np.empty(4)
  n = tiling.offsets.shape[0]
  scratch = (np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64), np.empty(n),
             np.empty(n), np.empty((core.SAMPLES_PER_CONTROL + 1, 2)), np.empty(3))
  n_actions = n_targets(s)
  n_root = root_tiling.offsets.shape[0]
  here = np.empty(n_root, dtype=np.int64)              # the root's tiles now
  there = np.empty(n_root, dtype=np.int64)             # and after the call
  root_view = np.empty(3)
  for episode in range(n_episodes):
    if fixed_start.shape[0] == 4:
      arrays.copy_into(state, fixed_start)
    else:
      _ship.sample_start(rng_state, state)
    qlambda.clear(root.count)
    steps = 0
    total = 0.0
    root_tiles(state, root_tiling, root_view, here)
    epsilon = eps_state[0] if sample else 0.0
    a = qlambda.tiled_epsilon_greedy(root.q, here, n_actions, offered(state, s), epsilon,
                                     rng_state)
    row = record[episode]
    row[:] = 0.0
    while True:
      g_event, l_event, reward, k = run_aim(state, a, trace, width, values, tiling, s,
                                            learn, sample, rng_state, steps, scratch)
      if steps + k < s.environment_max_steps and (g_event == core.NO_EVENT
                                                   or g_event == core.SUCCESS):
        success = l_event == core.SUCCESS
        row[AIM_RUNS] += 1
        row[AIM_SUCCESS] += success
        if learn:
          schedules.record_run(outcomes, counts, 0, success)
          schedules.record_run(outcomes, counts, 1, success)
      steps += k
      total += reward
      row[CALLS] += 1
      terminal = g_event != core.NO_EVENT
      truncated = (not terminal) and steps >= s.environment_max_steps
      root_tiles(state, root_tiling, root_view, there)
      n_there = offered(state, s)
      if terminal or truncated:
        if learn:
          qlambda.tiled_update(root.q, n_actions, root.index, root.value, root.count, here, a,
                               reward, there, n_there, 0, terminal, s.root_alpha, 1.0,
                               s.root_trace_decay)
          qlambda.clear(root.count)
        break
      a_next = qlambda.tiled_epsilon_greedy(root.q, there, n_actions, n_there, epsilon,
                                            rng_state)
      if learn:
        qlambda.tiled_update(root.q, n_actions, root.index, root.value, root.count, here, a,
                             reward, there, n_there, a_next, False, s.root_alpha, 1.0,
                             s.root_trace_decay)
      arrays.copy_into(here, there)
      a = a_next
    row[PASSED] = g_event == core.SUCCESS
    row[STEPS] = steps
    row[RETURN] = total
    if learn:
      schedules.end_episode(eps_state, outcomes, counts, s.root_epsilon_threshold,
                            s.root_epsilon_every, s.root_epsilon_divisor)


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
  inset_m: float = param(2.0, "the gate action aims at the gate with its posts moved in "
                         "by this (m)", low=0, high=49)
  approach_m: float = param(80.0, "how far before the gate line the approach points lie (m)",
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
  radius_m: float = param(15.0, "within this distance of its target a call has succeeded",
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
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)
  root: Root = dataclasses.field(default_factory=Root)
  low_level: LowLevel = dataclasses.field(default_factory=LowLevel)


def aim_coder(low):
  reflected = low.reflect_deg < 180.0
  low_error = -error_coordinate(low.reflect_deg, low.error_scale)
  return tiles_mod.TileCoder((low_error, -core.MAX_TURN_RATE, 0.0),
                             (180.0, core.MAX_TURN_RATE, DISTANCE_CLIP), tuple(low.tiles),
                             (not reflected, False, False), low.tilings)


class _Reflected:
  """The aim learner on the step-by-step path: its turning rate times the side of
  the last view (`aim_view`'s reflection)."""

  def __init__(self, learner):
    self.learner = learner
    self.side = 1.0

  def act(self, features, mask, rng_state, sample):
    return self.side * self.learner.act(features, mask, rng_state, sample)

  def __getattr__(self, name):
    return getattr(self.learner, name)


class ShipBeyond(_ship.ShipAgent):
  """A root over (cell, heading) that picks points; an aim subtask that steers there."""

  name = "ship_beyond"
  Config = Config
  record_fields = ("passed", "steps", "calls", "aim_runs", "aim_successes", "return")

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    root, low = self.config.root, self.config.low_level
    blocks.check_width(low.width_alpha, low.sigma_low, low.sigma_high, "[low_level]")
    self.s = settings(self.config)
    self.coder = aim_coder(low)
    self.tile_arrays = self.coder.arrays()
    self.schedule, self.outcomes, self.counts = schedules.new_schedule(root.epsilon,
                                                                   root.epsilon_window)
    self.root_coder = root_coder(root)
    self.root_tiling = self.root_coder.arrays()
    self.root = learners.TiledQLambda(self.root_coder.size, root.tilings, n_targets(self.s),
                                      root.alpha, root.trace_decay,
                                      epsilon_source=lambda: self.schedule[0])
    self.low = learners.GaussianPolicyGradient(self.coder.size, low.tilings, core.MAX_TURN_RATE,
                                               low.alpha, low.trace_gamma, baseline=low.baseline)
    self.width = el.new_trace(self.coder.size)
    self._learn = True

  def state(self):
    out = {"rng_state": self.rng_state, "root_q": self.root.q,
           "root_trace_index": self.root.index, "root_trace_value": self.root.value,
           "root_trace_count": self.root.count, "epsilon_schedule": self.schedule,
           "subtask_outcomes": self.outcomes, "subtask_counts": self.counts,
           "aim_baseline": self.low.values}
    for key, value in self.low.trace._asdict().items():
      out[f"aim_{key}"] = value
    for key, value in self.width._asdict().items():
      out[f"aim_width_{key}"] = value
    return out

  def parameters(self):
    return {"root_q": self.root.parameters(), "aim_w": self.low.parameters(),
            "aim_log_sigma": el.parameters(self.width)}

  def compiled(self, episodes, learn, sample, start=None):
    rows = np.zeros((episodes, N_RECORD))
    fixed = np.empty(0) if start is None else np.array(start, dtype=np.float64)
    train(episodes, learn, sample, self.rng_state,
          RootTable(self.root.q, self.root.index, self.root.value, self.root.count),
          self.root_tiling, (self.schedule, self.outcomes, self.counts), self.low.trace, self.width,
          self.low.values, self.tile_arrays, self.s, rows, fixed)
    return rows

  # ---- the step-by-step path -----------------------------------------------------

  def graph(self):
    if self.s.width_alpha != 0.0:
      raise ValueError("ship_beyond: [low_level] width_alpha > 0 runs on the compiled path "
                       "only (backend 'analytic'); the step-by-step path (MuJoCo) has the "
                       "paper's sigma = 1 learner. Evaluate greedily there (u = m).")
    s = self.s
    n = self.tile_arrays.offsets.shape[0]
    scratch_tiles = np.empty(n, dtype=np.int64)
    view = np.empty(3)

    def target(call, obs):
      side = call.memo.setdefault("side", side_of(float(call.origin[1])))
      return target_of(call.args["action"], np.asarray(obs, dtype=np.float64), side, s)

    aim_learner = _Reflected(self.low)

    def low_view(call, obs):
      tx, ty = target(call, obs)
      # The executor views the state it acts in last before acting (and the next
      # state after), so the side set here is the one act() applies.
      aim_learner.side = aim_view(np.asarray(obs, dtype=np.float64), tx, ty, view,
                                  s.sqrt_error, s.reflect_at)
      tiles_mod.active_tiles(view, self.tile_arrays, scratch_tiles)
      return scratch_tiles

    def internal_reward(call, step):
      tx, ty = target(call, step.obs)
      info = step.info
      g_event = {"gate": core.SUCCESS, "out_of_bounds": core.FAILURE}.get(info.get("event"),
                                                                          core.NO_EVENT)
      event, internal = aim_outcome(info["positions"], np.asarray(step.obs, dtype=np.float64),
                                    call.args["action"], tx, ty, call.steps, g_event, s)
      call.memo["event"] = event
      call.memo["global"] = g_event
      return internal

    def on_exit(call, step, episode_over):
      self.row[CALLS] += 1
      if episode_over and call.memo.get("global") != core.SUCCESS:
        return
      if step.truncated:
        return
      success = call.memo["event"] == core.SUCCESS
      self.row[AIM_RUNS] += 1
      self.row[AIM_SUCCESS] += success
      if self._learn:
        schedules.record_run(self.outcomes, self.counts, 0, success)
        schedules.record_run(self.outcomes, self.counts, 1, success)

    def on_episode_end(last_step, learn):
      if learn:
        root = self.config.root
        schedules.end_episode(self.schedule, self.outcomes, self.counts, root.epsilon_threshold,
                              root.epsilon_every, root.epsilon_divisor)

    aim = Subtask("aim", children=["turn"], learner=aim_learner, view=low_view,
                  internal_reward=internal_reward,
                  reward=lambda call, step, child_reward: core.STEP_REWARD,
                  termination=lambda call, step: call.memo["event"] != core.NO_EVENT,
                  on_exit=on_exit)
    root_scratch = (np.empty(3), np.empty(self.root_tiling.offsets.shape[0], dtype=np.int64))

    def root_view(call, obs):
      obs = np.asarray(obs, dtype=np.float64)
      root_tiles(obs, self.root_tiling, *root_scratch)
      return root_scratch[1], offered(obs, s)

    root = Subtask("root", learner=self.root,
                   children=[Child("aim", action=a) for a in range(n_targets(s))],
                   view=root_view,
                   termination=lambda call, step: False)
    return TaskGraph("root", [root, aim, Primitive("turn")], on_episode_end=on_episode_end)

  def begin_episode(self, learn):
    self._learn = learn

  def metrics(self, record):
    out = super().metrics(record)
    w = record[-self.metric_window:]
    runs = w["aim_runs"].sum()
    out.update({
        "calls_per_episode": float(w["calls"].mean()) if len(w) else None,
        "aim_success_rate": float(w["aim_successes"].sum() / runs) if runs else None,
    })
    return out
