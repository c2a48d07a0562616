"""The ship steering hierarchy (paper, Figure 3 and section 5.2; SPEC section 3).

Root: Q(lambda) over the 20 x 20 grid of 50 m cells, choosing one of eight
directions. Each direction calls one of two shared low-level subtasks
(diagonal for NE, SE, SW, NW; straight for N, E, S, W) in its local 150 m frame,
which steers the ship with a Gaussian-with-sigmoid CMAC policy learned by Eq. 3.

`ShipHybrid` holds the learners. It trains either step by step through any
ship environment (`train_stepwise`, via `graph()` and the executor) or in the
fused compiled loop over the analytic ship (`train_compiled`); both paths work
on the same arrays and call the same rule functions.
"""
import dataclasses

import numpy as np

from hpg_mj.hierarchy import executor as executor_mod
from hpg_mj.hierarchy import ship_compiled
from hpg_mj.hierarchy import ship_rules as rules
from hpg_mj.hierarchy.graph import Child, Primitive, Subtask, TaskGraph
from hpg_mj.learners import agents
from hpg_mj.learners import rng
from hpg_mj.learners import tiles
from hpg_mj.worlds import ship_core as core


@dataclasses.dataclass
class ShipHybridConfig:
  """Hyper-parameters of the hierarchical hybrid (defaults: SPEC section 3)."""
  root_alpha: float = 0.1           # Q(lambda) step size
  root_lambda: float = 0.9          # Q(lambda) trace decay
  epsilon: float = 0.1              # held until both subtasks succeed in 80% of 1,000 runs
  epsilon_threshold: float = 0.8
  epsilon_window: int = 1000
  epsilon_every: int = 50           # then divided by epsilon_divisor every 50 episodes
  epsilon_divisor: float = 1.01
  low_alpha: float = 0.01           # Eq. 3 step size of the low-level subtasks
  low_gamma: float = 0.99           # discount on the Eq. 3 trace (1.0 = none)
  tilings: int = 9
  tiles: tuple = (5, 5, 36, 5)      # over local (x, y, theta, theta_dot)
  subtask_max_steps: int = core.SUBTASK_MAX_STEPS
  episode_max_steps: int = core.STEER_MAX_STEPS
  gate_reward: float = core.GATE_REWARD
  out_of_bounds_reward: float = core.OUT_OF_BOUNDS_REWARD


RECORD_COLUMNS = ("passed", "steps", "calls", "diagonal_runs", "diagonal_successes",
                  "straight_runs", "straight_successes", "return")


class ShipHybrid:
  """The learners of the ship hierarchy and both ways of training them."""

  def __init__(self, config=None, seed=0):
    self.config = config or ShipHybridConfig()
    c = self.config
    self.coder = tiles.TileCoder((0.0, 0.0, -180.0, -core.MAX_TURN_RATE),
                                 (core.LOCAL_SIZE, core.LOCAL_SIZE, 180.0, core.MAX_TURN_RATE),
                                 tuple(c.tiles), (False, False, True, False), c.tilings)
    self.tile_arrays = self.coder.arrays()
    self.schedule, self.outcomes, self.counts = rules.new_schedule(c.epsilon, c.epsilon_window)
    self.root = agents.QLambda(rules.ROOT_GRID ** 2, rules.N_DIRECTIONS, c.root_alpha,
                               c.root_lambda, epsilon_source=lambda: self.schedule[0])
    self.low = [agents.GaussianPolicyGradient(self.coder.size, c.tilings, rules.R_MAX,
                                              c.low_alpha, c.low_gamma)
                for _ in (rules.DIAGONAL, rules.STRAIGHT)]
    self.rng_state = rng.make_state(seed)
    self.episodes = 0
    self._row = np.zeros(ship_compiled.N_RECORD)
    # When a list, every low-level call appends (x, y, direction) where it began
    # (Figure 12 marks the root's decisions).
    self.call_log = None
    self._scratch_tiles = np.empty(c.tilings, dtype=np.int64)
    self._local = np.empty(4)
    self._local_samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))

  # ---- the task graph (paper, Figure 3) ------------------------------------

  def graph(self):
    c = self.config

    def low_view(call, obs):
      origin = call.memo.setdefault("origin", np.array(call.origin[:2], dtype=np.float64))
      core.global_to_local(obs, origin, call.args["direction"], self._local)
      tiles.active_tiles(self._local, *self.tile_arrays, self._scratch_tiles)
      return self._scratch_tiles

    def low_internal_reward(call, step):
      event, internal = rules.low_level_outcome(
          step.info["positions"], step.obs, call.memo["origin"], call.args["direction"],
          call.steps, self._local_samples, self._local, c.subtask_max_steps)
      call.memo["event"] = event
      return internal

    def low_exit(call, step, episode_over):
      self._row[ship_compiled.CALLS] += 1
      if self.call_log is not None:
        self.call_log.append((float(call.origin[0]), float(call.origin[1]),
                              int(call.args["direction"])))
      if not episode_over:
        sub = rules.subtask_of(call.args["direction"])
        success = call.memo["event"] == core.SUCCESS
        runs, wins = ((ship_compiled.DIAG_RUNS, ship_compiled.DIAG_SUCCESS)
                      if sub == rules.DIAGONAL else
                      (ship_compiled.STRAIGHT_RUNS, ship_compiled.STRAIGHT_SUCCESS))
        self._row[runs] += 1
        self._row[wins] += success
        if self._learn:
          rules.record_run(self.outcomes, self.counts, sub, success)

    def low_level(name, learner):
      return Subtask(
          name, children=["turn"], learner=learner, view=low_view,
          internal_reward=low_internal_reward,
          reward=lambda call, step, child_reward: core.STEP_REWARD,   # only the -1 (SPEC 3)
          termination=lambda call, step: call.memo["event"] != core.NO_EVENT,
          on_exit=low_exit)

    root = Subtask(
        "root", learner=self.root,
        children=[Child("diagonal" if d % 2 else "straight", direction=d)
                  for d in range(rules.N_DIRECTIONS)],
        view=lambda call, obs: rules.root_cell(obs[0], obs[1]),
        termination=lambda call, step: False)   # the root ends with the episode
    return TaskGraph("root", [
        root,
        low_level("diagonal", self.low[rules.DIAGONAL]),
        low_level("straight", self.low[rules.STRAIGHT]),
        Primitive("turn"),                     # the turning rate r, chosen by the low level
    ], on_episode_end=self._episode_end)

  def _episode_end(self, last_step, learn):
    if learn:
      rules.end_episode(self.schedule, self.outcomes, self.counts,
                        self.config.epsilon_threshold, self.config.epsilon_every,
                        self.config.epsilon_divisor)

  # ---- training -------------------------------------------------------------

  def sample_start(self):
    start = np.empty(4)
    ship_compiled.sample_start(self.rng_state, start)
    return start

  def train_stepwise(self, adapter, episodes, learn=True, start=None, sample=None):
    """Episodes through an environment adapter (Gymnasium or dm_control ship).

    Starts are drawn from this agent's generator (as the compiled loop does),
    or fixed by `start`. Returns the per-episode record (episodes, N_RECORD).
    """
    graph = self.graph()
    run = executor_mod.Executor(graph, adapter, self.rng_state)
    record = np.zeros((episodes, ship_compiled.N_RECORD))
    self._learn = learn
    for i in range(episodes):
      self._row = record[i]
      begin = np.array(start, dtype=np.float64) if start is not None else self.sample_start()
      total, steps, last = run.run_episode(begin, learn=learn, sample=sample)
      self._row[ship_compiled.PASSED] = last.info.get("event") == "gate"
      self._row[ship_compiled.STEPS] = steps
      self._row[ship_compiled.RETURN] = total
      if learn:
        self.episodes += 1
    return record

  def train_compiled(self, episodes, learn=True, start=None, sample=None):
    """Episodes in the fused compiled loop over the analytic ship."""
    sample = learn if sample is None else (sample or learn)
    c = self.config
    record = np.zeros((episodes, ship_compiled.N_RECORD))
    d, s = self.low[rules.DIAGONAL].trace, self.low[rules.STRAIGHT].trace
    fixed = np.empty(0) if start is None else np.array(start, dtype=np.float64)
    ship_compiled.train(
        episodes, learn, sample, self.rng_state, self.root.q, self.root.index, self.root.value,
        self.root.count, c.root_alpha, c.root_lambda, self.schedule, self.outcomes,
        self.counts, c.epsilon_threshold, c.epsilon_every, c.epsilon_divisor,
        d["w"], d["zs"], d["y"], d["touched"], d["marked"], d["count"], d["acc"],
        s["w"], s["zs"], s["y"], s["touched"], s["marked"], s["count"], s["acc"],
        *self.tile_arrays, c.low_alpha, c.low_gamma, c.episode_max_steps,
        c.subtask_max_steps, record, fixed,
        np.array([c.gate_reward, c.out_of_bounds_reward]))
    if learn:
      self.episodes += episodes
    return record

  def parameters(self):
    """Root Q-values and both low-level weight vectors (pending updates applied)."""
    return {"root_q": self.root.parameters(),
            "diagonal_w": self.low[rules.DIAGONAL].parameters(),
            "straight_w": self.low[rules.STRAIGHT].parameters()}
