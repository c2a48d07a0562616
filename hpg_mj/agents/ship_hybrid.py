"""The hierarchical hybrid on ship steering (paper, Figure 3 and section 5.2;
SPEC sections 2-3): a Q(lambda) root over eight directions on a 20 x 20 grid of
50 m cells, and two shared low-level subtasks (diagonal, straight) that steer
with a Gaussian-with-sigmoid CMAC policy learned by Eq. 3.

Both paths work on the same arrays and call the same compiled rules: the fused
loop over the analytic ship (`train`, Algorithm 1 unrolled for Figure 3's graph) and the task graph
of Figure 3 run step by step through any ship environment (`graph`).
"""
import collections
import dataclasses

import numba
import numpy as np

from hpg_mj.agents import _ship
from hpg_mj.agents import taskfile
from hpg_mj.agents.taskfile import param
from hpg_mj.hierarchy import ship as ship_graph
from hpg_mj.hierarchy import ship_rules as rules
from hpg_mj.learners import agents as learners
from hpg_mj.learners import arrays
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import jit
from hpg_mj.learners import policies
from hpg_mj.learners import qlambda
from hpg_mj.learners import schedules
from hpg_mj.learners import tiles
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core as core


# Per-episode record columns (the order of `ShipHybrid.record_fields`).
# A subtask's runs count the calls that ended by its own success or failure; a call
# cut short by the end of the episode (gate, bounds, time limit) is no run.
PASSED, STEPS, CALLS, DIAG_RUNS, DIAG_SUCCESS, STRAIGHT_RUNS, STRAIGHT_SUCCESS, RETURN = range(8)
N_RECORD = 8

# The hyper-parameters the compiled loop takes, each named [section] key as in the
# task file (`settings` fills them from a Config).
Settings = collections.namedtuple("Settings", (
    "root_alpha", "root_trace_decay", "root_epsilon_threshold", "root_epsilon_every",
    "root_epsilon_divisor", "low_level_alpha", "low_level_trace_gamma", "low_level_baseline",
    "low_level_max_steps",
    "environment_max_steps", "environment_gate_reward", "environment_out_of_bounds_reward"))
# The root's Q(lambda) table and trace; the epsilon schedule's arrays.
RootTable = collections.namedtuple("RootTable", ("q", "index", "value", "count"))


def settings(config):
  root, low, env = config.root, config.low_level, config.environment
  return Settings(float(root.alpha), float(root.trace_decay), float(root.epsilon_threshold),
                  int(root.epsilon_every), float(root.epsilon_divisor), float(low.alpha),
                  float(low.trace_gamma), float(low.baseline), int(low.max_steps),
                  int(env.max_steps),
                  float(env.gate_reward), float(env.out_of_bounds_reward))


# error_model="numpy": no raising branch on division, less reference counting (learners.policies).
# Only compiled code calls it: no Python entry point to compile (a first compile 0.15 s shorter).
@numba.njit(cache=True, error_model="numpy", no_cpython_wrapper=True)
def run_low_level(state, direction, low, low_values, tiling, s, learn, sample, rng_state,
                  steps_before, scratch):
  """One call of a low-level subtask (trace `low`, baseline `low_values`) from
  `state` (modified in place). The baseline b (`policies.subtract_baseline`) is
  learned with step size s.low_level_baseline; 0 leaves it out (Eq. 3 exactly).

  Returns (global event, local event, reward to the root, control steps).
  """
  scratch_tiles, scratch_psi, scratch_next, samples, local_samples, local_state, origin = scratch
  beta = s.low_level_baseline
  origin[0] = state[0]
  origin[1] = state[1]
  el.reset(low)                                        # Eq. 3: z <- 0
  reward_root = 0.0
  k = 0
  global_event = core.NO_EVENT
  local_event = core.NO_EVENT
  core.global_to_local(state, origin, direction, local_state)
  tiles_mod.active_tiles(local_state, tiling, scratch_tiles)
  while True:
    if sample:
      r = policies.gaussian_act(low, scratch_tiles, core.MAX_TURN_RATE, rng_state, scratch_psi)
      if learn and beta != 0.0:
        policies.subtract_baseline(low.theta, low_values, scratch_tiles, s.low_level_alpha,
                                   scratch_psi)
    else:
      r = policies.gaussian_greedy(low, scratch_tiles, core.MAX_TURN_RATE)
    core.euler_control(state, r, samples)
    k += 1
    global_event, reward = core.global_outcome(samples, s.environment_gate_reward,
                                               s.environment_out_of_bounds_reward)
    reward_root += reward
    local_event, internal = core.low_level_outcome(samples, state, origin, direction, k,
                                                   local_samples, local_state,
                                                   s.low_level_max_steps)
    ended = (global_event != core.NO_EVENT or local_event != core.NO_EVENT
             or steps_before + k >= s.environment_max_steps)
    if not ended:       # the next state, already local (`low_level_outcome`), and its tiles
      tiles_mod.active_tiles(local_state, tiling, scratch_next)
    if learn:                                          # Eq. 3 with R + G
      el.learn(low, s.low_level_alpha, core.STEP_REWARD + internal, s.low_level_trace_gamma)
      if beta != 0.0:
        next_value = 0.0 if ended else policies.tile_mean(low_values, scratch_next)
        policies.learn_baseline(low_values, scratch_tiles, beta, core.STEP_REWARD + internal,
                                s.low_level_trace_gamma, next_value)
    if ended:
      return global_event, local_event, reward_root, k
    arrays.copy_into(scratch_tiles, scratch_next)


# error_model="numpy": no raising branch on division, less reference counting (learners.policies).
@numba.njit(cache=True, error_model="numpy")
def train(n_episodes, learn, sample, rng_state, root, schedule, diagonal, diagonal_values,
          straight, straight_values, tiling, s, record, fixed_start):
  """Trains for `n_episodes` episodes (Algorithm 1 over Figure 3's graph); with
  learn=False it only runs the policy, sampling it (sample=True) or greedily
  (sample=False: epsilon 0, u = m).

  `root` is the root's `RootTable`, `schedule` the epsilon schedule's arrays
  (`schedules.new_schedule`), `diagonal` and `straight` the subtasks' Eq. 3
  traces over `tiling` (and their baselines' values), `s` the `Settings`. `record` (n_episodes, N_RECORD)
  receives one row per episode. With `fixed_start` of length 4, every episode
  starts there instead of at random.
  """
  eps_state, outcomes, counts = schedule
  state = np.empty(4)
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  n_tilings = tiling.offsets.shape[0]
  scratch = (np.empty(n_tilings, dtype=np.int64), np.empty(n_tilings),
             np.empty(n_tilings, dtype=np.int64), samples, np.empty_like(samples), np.empty(4),
             np.empty(2))
  for episode in range(n_episodes):
    if fixed_start.shape[0] == 4:
      arrays.copy_into(state, fixed_start)
    else:
      _ship.sample_start(rng_state, state)
    qlambda.clear(root.count)
    steps = np.int64(0)                  # not the literal 0: run_low_level would compile twice
    total = 0.0
    cell = rules.root_cell(state[0], state[1])
    epsilon = eps_state[0] if sample else 0.0
    a = qlambda.epsilon_greedy(root.q, cell, rules.N_DIRECTIONS, epsilon, rng_state)
    row = record[episode]
    row[:] = 0.0
    while True:
      sub = rules.subtask_of(a)
      low, low_values = ((diagonal, diagonal_values) if sub == rules.DIAGONAL else
                         (straight, straight_values))
      g_event, l_event, reward, k = run_low_level(state, a, low, low_values, tiling, s, learn,
                                                  sample, rng_state, steps, scratch)
      if g_event == core.NO_EVENT and steps + k < s.environment_max_steps:
        success = l_event == core.SUCCESS
        if sub == rules.DIAGONAL:
          row[DIAG_RUNS] += 1
          row[DIAG_SUCCESS] += success
        else:
          row[STRAIGHT_RUNS] += 1
          row[STRAIGHT_SUCCESS] += success
        if learn:
          schedules.record_run(outcomes, counts, sub, success)
      steps += k
      total += reward
      row[CALLS] += 1
      terminal = g_event != core.NO_EVENT
      truncated = (not terminal) and steps >= s.environment_max_steps
      next_cell = rules.root_cell(state[0], state[1])
      over = terminal or truncated
      # One call site of `qlambda.update` for both cases (a literal 0 or False
      # argument would compile a second specialization); no draw when the episode is over.
      a_next = 0
      if not over:
        a_next = qlambda.epsilon_greedy(root.q, next_cell, rules.N_DIRECTIONS, epsilon, rng_state)
      if learn:
        qlambda.update(root.q, rules.N_DIRECTIONS, root.index, root.value, root.count, cell, a,
                       reward, next_cell, a_next, terminal, s.root_alpha, 1.0, s.root_trace_decay)
      if over:
        if learn:
          qlambda.clear(root.count)
        break
      cell = next_cell
      a = a_next
    row[PASSED] = g_event == core.SUCCESS
    row[STEPS] = steps
    row[RETURN] = total
    if learn:
      schedules.end_episode(eps_state, outcomes, counts, s.root_epsilon_threshold,
                            s.root_epsilon_every, s.root_epsilon_divisor)


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
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)
  root: Root = dataclasses.field(default_factory=Root)
  low_level: LowLevel = dataclasses.field(default_factory=LowLevel)


class ShipHybrid(_ship.ShipAgent):
  """The learners of the ship hierarchy and both ways of training them."""

  name = "ship_hybrid"
  Config = Config
  record_fields = ("passed", "steps", "calls", "diagonal_runs", "diagonal_successes",
                   "straight_runs", "straight_successes", "return")

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    root, low = self.config.root, self.config.low_level
    self.coder = tiles.TileCoder((0.0, 0.0, -180.0, -core.MAX_TURN_RATE),
                                 (core.LOCAL_SIZE, core.LOCAL_SIZE, 180.0, core.MAX_TURN_RATE),
                                 tuple(low.tiles), (False, False, True, False), low.tilings)
    self.tile_arrays = self.coder.arrays()
    self.schedule, self.outcomes, self.counts = schedules.new_schedule(root.epsilon,
                                                                   root.epsilon_window)
    self.root = learners.QLambda(rules.ROOT_GRID ** 2, rules.N_DIRECTIONS, root.alpha,
                                 root.trace_decay, epsilon_source=lambda: self.schedule[0])
    self.low = [learners.GaussianPolicyGradient(self.coder.size, low.tilings, core.MAX_TURN_RATE,
                                                low.alpha, low.trace_gamma,
                                                baseline=low.baseline)
                for _ in (rules.DIAGONAL, rules.STRAIGHT)]
    self._learn = True

  def state(self):
    out = {"rng_state": self.rng_state, "root_q": self.root.q,
           "root_trace_index": self.root.index, "root_trace_value": self.root.value,
           "root_trace_count": self.root.count, "epsilon_schedule": self.schedule,
           "subtask_outcomes": self.outcomes, "subtask_counts": self.counts}
    for name, learner in (("diagonal", self.low[0]), ("straight", self.low[1])):
      for key, value in learner.trace._asdict().items():
        out[f"{name}_{key}"] = value
      out[f"{name}_baseline"] = learner.values
    return out

  def parameters(self):
    """Root Q-values and both low-level weight vectors (pending updates applied)."""
    return {"root_q": self.root.parameters(),
            "diagonal_w": self.low[rules.DIAGONAL].parameters(),
            "straight_w": self.low[rules.STRAIGHT].parameters()}

  # ---- the compiled path ---------------------------------------------------------

  def compiled(self, episodes, learn, sample, start=None):
    rows = np.zeros((episodes, N_RECORD))
    fixed = np.empty(0) if start is None else np.array(start, dtype=np.float64)
    jit.compile_first(train, self._rules_bottom_up)
    train(episodes, learn, sample, self.rng_state,
          RootTable(self.root.q, self.root.index, self.root.value, self.root.count),
          (self.schedule, self.outcomes, self.counts),
          self.low[rules.DIAGONAL].trace, self.low[rules.DIAGONAL].values,
          self.low[rules.STRAIGHT].trace, self.low[rules.STRAIGHT].values, self.tile_arrays,
          settings(self.config), rows, fixed)
    return rows

  def _rules_bottom_up(self):
    """`run_low_level`, which `train` calls, with arguments of the types it calls it
    with (`learners.jit.compile_first`; see `taxi_maxq.MAXQTables`)."""
    n_tilings = self.tile_arrays.offsets.shape[0]
    samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
    scratch = (np.empty(n_tilings, dtype=np.int64), np.empty(n_tilings),
               np.empty(n_tilings, dtype=np.int64), samples, np.empty_like(samples),
               np.empty(4), np.empty(2))
    low = self.low[rules.DIAGONAL]
    return [(run_low_level, (np.empty(4), np.int64(0), low.trace, low.values,
                             self.tile_arrays, settings(self.config), False, False,
                             self.rng_state, np.int64(0), scratch))]

  # ---- the step-by-step path -----------------------------------------------------

  def graph(self):
    return ship_graph.ship_graph(self.root, self.low, self.tile_arrays,
                                 self.config.low_level.max_steps, on_run=self._on_run,
                                 on_episode_end=self._on_episode_end)

  def _on_run(self, subtask, success, episode_over):
    """A low-level call returned: count it in the record (and, learning, in the
    schedule's window); a call cut by the end of the episode is no run."""
    self.row[self.record_fields.index("calls")] += 1
    if episode_over:
      return
    name = "diagonal" if subtask == rules.DIAGONAL else "straight"
    self.row[self.record_fields.index(f"{name}_runs")] += 1
    self.row[self.record_fields.index(f"{name}_successes")] += success
    if self._learn:
      schedules.record_run(self.outcomes, self.counts, subtask, success)

  def _on_episode_end(self, last_step, learn):
    if learn:
      root = self.config.root
      schedules.end_episode(self.schedule, self.outcomes, self.counts, root.epsilon_threshold,
                        root.epsilon_every, root.epsilon_divisor)

  def begin_episode(self, learn):
    self._learn = learn

  # ---- metrics ------------------------------------------------------------------

  def metrics(self, record):
    out = super().metrics(record)
    w = record[-self.metric_window:]
    diag_runs, str_runs = w["diagonal_runs"].sum(), w["straight_runs"].sum()
    out.update({
        "calls_per_episode": float(w["calls"].mean()) if len(w) else None,
        "diagonal_success_rate": float(w["diagonal_successes"].sum() / diag_runs)
                                 if diag_runs else None,
        "straight_success_rate": float(w["straight_successes"].sum() / str_runs)
                                 if str_runs else None,
    })
    return out
