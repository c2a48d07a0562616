"""The hierarchical hybrid on ship steering (paper, Figure 3 and section 5.2;
SPEC sections 2-3): a Q(lambda) root over eight directions on a 20 x 20 grid of
50 m cells, and two shared low-level subtasks (diagonal, straight) that steer
with a Gaussian-with-sigmoid CMAC policy learned by Eq. 3.

Both paths work on the same arrays and call the same compiled rules: the fused
loop over the analytic ship (`train`, Algorithm 1 unrolled for Figure 3's graph) and the task graph
of Figure 3 run step by step through any ship environment (`graph`).
"""
import dataclasses

import numba
import numpy as np

from hpg_mj.agents import _ship
from hpg_mj.agents.taskfile import param
from hpg_mj.hierarchy import ship as ship_graph
from hpg_mj.hierarchy import ship_rules as rules
from hpg_mj.learners import agents as learners
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import qlambda
from hpg_mj.learners import schedules
from hpg_mj.learners import tiles
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core as core


# Per-episode record columns.
# A subtask's runs count the calls that ended by its own success or failure; a call
# cut short by the end of the episode (gate, bounds, time limit) is no run.
PASSED, STEPS, CALLS, DIAG_RUNS, DIAG_SUCCESS, STRAIGHT_RUNS, STRAIGHT_SUCCESS, RETURN = range(8)
N_RECORD = 8


@numba.njit(cache=True)
def run_low_level(state, direction, low_w, low_zs, low_y, low_touched, low_marked, low_count,
                  low_acc, tile_low, tile_width, tile_n, tile_wrap, tile_offsets, alpha_low,
                  gamma_low, learn, sample, rng_state, steps_before, max_steps_episode,
                  max_steps_call, scratch_tiles, scratch_psi, samples, local_samples,
                  local_state, origin, task_rewards):
  """One call of a low-level subtask from `state` (modified in place).

  Returns (global event, local event, reward to the root, control steps).
  """
  origin[0] = state[0]
  origin[1] = state[1]
  el.reset(low_w, low_zs, low_y, low_touched, low_marked, low_count, low_acc)  # Eq. 3: z <- 0
  reward_root = 0.0
  k = 0
  global_event = core.NO_EVENT
  local_event = core.NO_EVENT
  while True:
    core.global_to_local(state, origin, direction, local_state)
    tiles_mod.active_tiles(local_state, tile_low, tile_width, tile_n, tile_wrap, tile_offsets,
                           scratch_tiles)
    if sample:
      r = policies.gaussian_act(low_w, low_zs, low_y, low_touched, low_marked, low_count,
                                low_acc, scratch_tiles, rules.R_MAX, rng_state, scratch_psi)
    else:
      r = policies.gaussian_greedy(low_w, low_zs, low_y, low_acc, scratch_tiles, rules.R_MAX)
    core.euler_control(state, r, samples)
    k += 1
    global_event, reward = core.global_outcome(samples, task_rewards[0], task_rewards[1])
    reward_root += reward
    local_event, internal = core.low_level_outcome(samples, state, origin, direction, k,
                                                    local_samples, local_state, max_steps_call)
    if learn:
      el.reward(low_w, low_zs, low_y, low_touched, low_marked, low_count, low_acc, alpha_low,
                core.STEP_REWARD + internal, gamma_low)
    if (global_event != core.NO_EVENT or local_event != core.NO_EVENT
        or steps_before + k >= max_steps_episode):
      return global_event, local_event, reward_root, k


@numba.njit(cache=True)
def train(n_episodes, learn, sample, rng_state, q, q_index, q_value, q_count, alpha_root, lam,
          schedule, outcomes, counts, eps_threshold, eps_every, eps_divisor,
          diag_w, diag_zs, diag_y, diag_touched, diag_marked, diag_count, diag_acc,
          str_w, str_zs, str_y, str_touched, str_marked, str_count, str_acc,
          tile_low, tile_width, tile_n, tile_wrap, tile_offsets, alpha_low, gamma_low,
          max_steps_episode, max_steps_call, record, fixed_start, task_rewards):
  """Trains for `n_episodes` episodes; with learn=False it only runs the policy,
  sampling it (sample=True) or greedily (sample=False: epsilon 0, u = m).

  `task_rewards` = [gate bonus, out-of-bounds penalty] (SPEC: +100, -100).
  `record` (n_episodes, N_RECORD) receives one row per episode. With
  `fixed_start` of length 4, every episode starts there instead of at random.
  """
  state = np.empty(4)
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  local_samples = np.empty_like(samples)
  local_state = np.empty(4)
  origin = np.empty(2)
  n_tilings = tile_offsets.shape[0]
  scratch_tiles = np.empty(n_tilings, dtype=np.int64)
  scratch_psi = np.empty(n_tilings)
  for episode in range(n_episodes):
    if fixed_start.shape[0] == 4:
      state[:] = fixed_start
    else:
      _ship.sample_start(rng_state, state)
    qlambda.clear(q_count)
    steps = 0
    total = 0.0
    cell = rules.root_cell(state[0], state[1])
    epsilon = schedule[0] if sample else 0.0
    a = qlambda.epsilon_greedy(q, cell, rules.N_DIRECTIONS, epsilon, rng_state)
    row = record[episode]
    row[:] = 0.0
    while True:
      sub = rules.subtask_of(a)
      if sub == rules.DIAGONAL:
        g_event, l_event, reward, k = run_low_level(
            state, a, diag_w, diag_zs, diag_y, diag_touched, diag_marked, diag_count, diag_acc,
            tile_low, tile_width, tile_n, tile_wrap, tile_offsets, alpha_low, gamma_low, learn,
            sample, rng_state, steps, max_steps_episode, max_steps_call, scratch_tiles, scratch_psi,
            samples, local_samples, local_state, origin, task_rewards)
      else:
        g_event, l_event, reward, k = run_low_level(
            state, a, str_w, str_zs, str_y, str_touched, str_marked, str_count, str_acc,
            tile_low, tile_width, tile_n, tile_wrap, tile_offsets, alpha_low, gamma_low, learn,
            sample, rng_state, steps, max_steps_episode, max_steps_call, scratch_tiles, scratch_psi,
            samples, local_samples, local_state, origin, task_rewards)
      if g_event == core.NO_EVENT and steps + k < max_steps_episode:
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
      truncated = (not terminal) and steps >= max_steps_episode
      next_cell = rules.root_cell(state[0], state[1])
      if terminal or truncated:
        if learn:
          qlambda.update(q, rules.N_DIRECTIONS, q_index, q_value, q_count, cell, a, reward,
                         next_cell, 0, terminal, alpha_root, 1.0, lam)
          qlambda.clear(q_count)
        break
      a_next = qlambda.epsilon_greedy(q, next_cell, rules.N_DIRECTIONS, epsilon, rng_state)
      if learn:
        qlambda.update(q, rules.N_DIRECTIONS, q_index, q_value, q_count, cell, a, reward,
                       next_cell, a_next, False, alpha_root, 1.0, lam)
      cell = next_cell
      a = a_next
    row[PASSED] = g_event == core.SUCCESS
    row[STEPS] = steps
    row[RETURN] = total
    if learn:
      schedules.end_episode(schedule, outcomes, counts, eps_threshold, eps_every, eps_divisor)


@dataclasses.dataclass(frozen=True)
class Root:
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
class LowLevel:
  """[low_level]: the shared diagonal and straight subtasks, learned by Eq. 3."""
  learner: str = param("policy_gradient", "Eq. 3", choices=("policy_gradient",))
  alpha: float = param(0.01, "Eq. 3 step size", low=0, low_open=True)
  trace_gamma: float = param(1.0, "discount on the Eq. 3 trace (1 = plain Eq. 3)", low=0,
                             high=1, low_open=True)
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
    self.low = [learners.GaussianPolicyGradient(self.coder.size, low.tilings, rules.R_MAX,
                                                low.alpha, low.trace_gamma)
                for _ in (rules.DIAGONAL, rules.STRAIGHT)]
    self._learn = True

  def state(self):
    out = {"rng_state": self.rng_state, "root_q": self.root.q,
           "root_trace_index": self.root.index, "root_trace_value": self.root.value,
           "root_trace_count": self.root.count, "epsilon_schedule": self.schedule,
           "subtask_outcomes": self.outcomes, "subtask_counts": self.counts}
    for name, learner in (("diagonal", self.low[0]), ("straight", self.low[1])):
      for key, value in learner.trace.items():
        out[f"{name}_{key}"] = value
    return out

  def parameters(self):
    """Root Q-values and both low-level weight vectors (pending updates applied)."""
    return {"root_q": self.root.parameters(),
            "diagonal_w": self.low[rules.DIAGONAL].parameters(),
            "straight_w": self.low[rules.STRAIGHT].parameters()}

  # ---- the compiled path ---------------------------------------------------------

  def compiled(self, episodes, learn, sample, start=None):
    root, low, env = self.config.root, self.config.low_level, self.config.environment
    rows = np.zeros((episodes, N_RECORD))
    d, s = self.low[rules.DIAGONAL].trace, self.low[rules.STRAIGHT].trace
    fixed = np.empty(0) if start is None else np.array(start, dtype=np.float64)
    train(
        episodes, learn, sample, self.rng_state, self.root.q, self.root.index, self.root.value,
        self.root.count, root.alpha, root.trace_decay, self.schedule, self.outcomes,
        self.counts, root.epsilon_threshold, root.epsilon_every, root.epsilon_divisor,
        d["w"], d["zs"], d["y"], d["touched"], d["marked"], d["count"], d["acc"],
        s["w"], s["zs"], s["y"], s["touched"], s["marked"], s["count"], s["acc"],
        *self.tile_arrays, low.alpha, low.trace_gamma, env.max_steps, low.max_steps, rows,
        fixed, self.task_rewards)
    return rows

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
    w = record[-_ship.METRIC_WINDOW:]
    diag_runs, str_runs = w["diagonal_runs"].sum(), w["straight_runs"].sum()
    out.update({
        "calls_per_episode": float(w["calls"].mean()) if len(w) else None,
        "diagonal_success_rate": float(w["diagonal_successes"].sum() / diag_runs)
                                 if diag_runs else None,
        "straight_success_rate": float(w["straight_successes"].sum() / str_runs)
                                 if str_runs else None,
    })
    return out
