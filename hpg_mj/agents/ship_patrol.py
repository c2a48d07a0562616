"""The continuing ship task with an average-reward root (SPEC section 8; the
paper's section 6: "the hierarchy with a continuing root whose performance is
the average reward", whose results it did not include).

The hierarchy is the hybrid's (Figure 3, SPEC section 3): a root choosing one of
eight directions, and the shared diagonal and straight subtasks learned by Eq. 3,
from scratch in the same run. The root differs: the process never ends (each
gate pass +100 and the ship sails on; leaving the field pays the penalty and
restarts the ship at a uniform start), so the root learns relative values and
the gain rho, the reward per control step, by average-reward SMDP Q-learning
(`learners.average_reward`: R-learning after Schwartz 1993 in the SMDP form of
Ghavamzadeh & Mahadevan 2001, 2002); and its state is the 50 m cell and, with
`heading_sectors` > 1, the ship's heading (`root_state`): passing the gate again
is a U-turn that only pays from a cell when the ship points away from the gate.
With `planning_every` > 0 the root also plans (`average_reward.plan`, issue 24):
the cells the process meets only after a rare departure keep values learned
while the gain was low unless their latest calls are backed up again with
today's gain.
A low-level call returns to the root at its own success or failure, at a gate
pass, or when the ship leaves the field.

The agent is continuing: its record has one row per hour of sailing (6,000
control steps; `record_steps`), and its task file's protocol says how long to
train in `control_steps` or `hours`. After training, `final_metrics` measures
greedily, on the same hours from the same starts, this agent, the episodic
hybrid (tasks/ship_hybrid.toml's agent, trained on its own protocol with this
run's seed) and the scripted figure-eight helmsman (`ship_core.patrol_pilot_target`).

Both paths call the same compiled rules: the fused loop over the analytic ship
(`patrol`) and the task graph run step by step (`graph`, `run_stepwise`) through
the Gymnasium patrol on either backend, with the restarts drawn from the agent's
generator; for a fixed seed they give the same records and arrays.
"""
import dataclasses

import numpy as np

from hpg_mj.agents import _ship
from hpg_mj.agents import ship_hybrid as hybrid
from hpg_mj.taskfile import param
from hpg_mj.hierarchy import executor as executor_mod
from hpg_mj.hierarchy import ship_rules as rules
from hpg_mj.hierarchy.patrol import (CALLS, DEPARTURES, GAIN, GATES, N_RECORD, NEVER, RETURN, STEPS,
                                     AgentRestarts, Settings, count_run, n_root_cells, patrol,
                                     root_state, scripted)
from hpg_mj.hierarchy.graph import Child, Primitive, Subtask, TaskGraph
from hpg_mj.learners import average_reward
from hpg_mj.learners import rng
from hpg_mj.learners import schedules
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core as core

EVALUATION_SEED = 2 ** 20    # the generator of the greedy evaluations' starts
# The environment's events that end a low-level call (and what the row counts).
_GLOBAL_EVENTS = {"gate": core.SUCCESS, "out_of_bounds": core.FAILURE}


def settings(config):
  """`hierarchy.patrol.Settings` for `run_low_level`, with no episode clock."""
  root, low, env = config.root, config.low_level, config.environment
  return Settings(float(root.alpha), 0.0, float(root.epsilon_threshold),
                         int(root.epsilon_every), float(root.epsilon_divisor), float(low.alpha),
                         float(low.trace_gamma), float(low.baseline), int(low.max_steps),
                         NEVER, float(env.gate_reward), float(env.out_of_bounds_reward))


@dataclasses.dataclass(frozen=True)
class Environment:
  """[environment] of the continuing ship task (SPEC section 8)."""
  world: str = param("ship", "the world", choices=("ship",))
  backend: str = param("analytic", "train on Equation 1 (the compiled path)",
                       choices=("analytic",))
  gate_reward: float = param(core.GATE_REWARD, "reward for each pass of the gate")
  out_of_bounds_reward: float = param(core.OUT_OF_BOUNDS_REWARD,
                                      "reward for leaving the field (then a fresh start)")


@dataclasses.dataclass(frozen=True)
class Root:
  """[root]: average-reward SMDP Q-learning over the calls (SPEC section 8)."""
  learner: str = param("r_learning", "R-learning in SMDP form (learners.average_reward)",
                       choices=("r_learning",))
  heading_sectors: int = param(1, "the root's state: its 50 m cell and the heading in this "
                               "many sectors (1: the cell alone, as the hybrid's root)", low=1)
  near_gate_m: float = param(0.0, "half-width of the square about the gate's centre where the "
                             "root's cells are finer (0: the 50 m grid everywhere)", low=0,
                             high=400)
  near_gate_cell_m: float = param(25.0, "the root's cell inside that square; it must divide "
                                  "twice near_gate_m", low=1, high=50)
  alpha: float = param(0.1, "step size of the relative values Q", low=0, low_open=True)
  gain_step: float = param(0.0001, "step size of the gain rho (Schwartz's update)", low=0,
                           high=1, low_open=True)
  epsilon: float = param(0.3, "exploration, held until both subtasks pass epsilon_threshold",
                         low=0, high=1)
  epsilon_threshold: float = param(0.8, "success rate over epsilon_window runs that starts "
                                   "the decay", low=0, high=1)
  epsilon_window: int = param(1000, "runs per subtask the threshold looks at", low=1)
  epsilon_every: int = param(400, "root decisions between divisions of epsilon", low=1)
  epsilon_divisor: float = param(1.01, "epsilon is divided by this", low=1)
  planning_every: int = param(0, "root decisions between sweeps of planning over the latest "
                              "transition of each (state, direction) (0: no planning)", low=0)


@dataclasses.dataclass(frozen=True)
class Comparison:
  """[comparison]: what `final_metrics` measures beside the learned agent."""
  episodic_task: str = param("ship_hybrid", "the episodic agent's task file (run greedily "
                             "on this task); \"\" for none")
  episodic_episodes: int = param(0, "its training episodes (0: its file's protocol)", low=0)
  evaluation_hours: int = param(100, "hours of greedy sailing per measured policy", low=1)


@dataclasses.dataclass(frozen=True)
class Config:
  environment: Environment = dataclasses.field(default_factory=Environment)
  root: Root = dataclasses.field(default_factory=Root)
  low_level: hybrid.LowLevel = dataclasses.field(default_factory=hybrid.LowLevel)
  comparison: Comparison = dataclasses.field(default_factory=Comparison)


class ShipPatrol(_ship.ShipAgent):
  """The hybrid's hierarchy with an average-reward root, on the continuing task."""

  name = "ship_patrol"
  Config = Config
  record_fields = ("steps", "gates", "departures", "calls", "diagonal_runs",
                   "diagonal_successes", "straight_runs", "straight_successes", "return",
                   "gain")
  figure = "gates_per_hour"
  record_steps = core.HOUR_STEPS       # a continuing agent: one record row per hour
  metric_window = 125                  # online metrics: the last 125 hours (beyond's block)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    # The hybrid's tiles, subtasks and epsilon schedule; the root is replaced.
    self.tile_arrays, self.low, (self.schedule, self.outcomes, self.counts) = \
        hybrid.low_level_parts(hybrid.Config(low_level=self.config.low_level, root=hybrid.Root(
            epsilon=self.config.root.epsilon, epsilon_window=self.config.root.epsilon_window)))
    root = self.config.root
    side = 2.0 * root.near_gate_m / root.near_gate_cell_m
    if abs(side - round(side)) > 1e-9:
      raise ValueError(f"[root] near_gate_cell_m = {root.near_gate_cell_m} must divide twice "
                       f"near_gate_m = {root.near_gate_m} (2 * near_gate_m / near_gate_cell_m "
                       f"= {side}, not a whole number)")
    self.q = np.zeros(n_root_cells(root.near_gate_m, root.near_gate_cell_m) *
                      root.heading_sectors * rules.N_DIRECTIONS)
    self.gain = average_reward.new_gain()
    # The planning model (`average_reward.new_model`); its first array of length 0
    # when [root] planning_every is 0, so nothing is kept.
    self.model = average_reward.new_model(self.q.size if root.planning_every else 0)
    self.ship = np.zeros(4)
    self.started = np.zeros(1)         # 1 once the process has its first start
    self._sailing = None               # the state a step-by-step run sails on from
    self._learn = True
    self._row_steps = 0

  def state(self):
    out = {"rng_state": self.rng_state, "root_q": self.q, "root_gain": self.gain,
           **{f"root_model_{k}": v for k, v in zip(("next", "reward", "steps", "count"),
                                                    self.model)},
           "ship_state": self.ship, "ship_started": self.started,
           "epsilon_schedule": self.schedule, "subtask_outcomes": self.outcomes,
           "subtask_counts": self.counts}
    for name, learner in (("diagonal", self.low[0]), ("straight", self.low[1])):
      for key, value in learner.trace._asdict().items():
        out[f"{name}_{key}"] = value
      out[f"{name}_baseline"] = learner.values
    return out

  def make_env(self, api="gymnasium", backend="analytic", **kwargs):
    env = self.config.environment
    settings_ = {"gate_reward": env.gate_reward, "out_of_bounds_reward": env.out_of_bounds_reward}
    if api == "gymnasium":
      import gymnasium

      import hpg_mj  # noqa: F401  (registers the ids)
      return gymnasium.make("hpg_mj/ShipPatrol-v0", backend=backend, **settings_, **kwargs)
    if api == "dm_control":
      from hpg_mj import suite
      return suite.load("ship", "patrol", {"random": 0, **kwargs})
    raise ValueError(f"unknown environment api {api!r}; allowed: ['gymnasium', 'dm_control']")

  # ---- the step-by-step path ----------------------------------------------------

  def stepwise_env(self, backend):
    """The Gymnasium patrol on `backend`, without its one-hour truncation: the
    agent's rows are its own hours, ended between calls as the compiled loop's."""
    return self.make_env("gymnasium", backend=backend, max_steps=NEVER)

  def run_stepwise(self, env, episodes, learn=True, sample=None, start=None, on_call=None):
    """`episodes` rows (hours) of the patrol task graph (`graph`) through `env`, a
    Gymnasium patrol without truncation (`stepwise_env`). As the compiled path:
    learning continues the agent's own process (from `start`, if given, instead);
    without learning the rows sail on from a fresh start drawn from the agent's
    generator; after leaving the field the ship restarts at a start drawn from
    the agent's generator too (the environment's own draw is replaced)."""
    adapter = AgentRestarts(executor_mod.adapter_for(env), self.rng_state)
    if learn:
      if start is not None:
        self.ship[:] = start
        self.started[0] = 1.0
      elif not self.started[0]:
        _ship.sample_start(self.rng_state, self.ship)
        self.started[0] = 1.0
      self._sailing = self.ship
    else:
      self._sailing = np.array(start, dtype=np.float64) if start is not None else np.empty(4)
      if start is None:
        _ship.sample_start(self.rng_state, self._sailing)
    try:
      return super().run_stepwise(adapter, episodes, learn=learn, sample=sample,
                                  on_call=on_call)
    finally:
      self._sailing = None

  def start_state(self):
    """Inside `run_stepwise`: where the process is (each row starts where the last
    ended); outside it, a fresh start from the agent's generator."""
    if self._sailing is None:
      return super().start_state()
    return self._sailing.copy()

  def begin_episode(self, learn):
    self._learn = learn
    self._row_steps = 0

  def end_episode(self, row, total, steps, last, learn):
    row[STEPS] = steps
    row[RETURN] = total
    row[GAIN] = self.gain[average_reward.RHO]
    self._sailing[:] = last.obs          # the next row sails on from here

  def graph(self):
    """Figure 3's graph with the continuing root (SPEC section 8): the root's
    R-learning over `root_state`; a low-level call also returns at a gate pass
    or a departure; the root returns (a record row ends) once the row has
    `record_steps` control steps, between calls."""
    cfg = self.config
    n_tilings = self.tile_arrays.offsets.shape[0]
    scratch_tiles = np.empty(n_tilings, dtype=np.int64)
    local = np.empty(4)
    local_samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
    max_steps = int(cfg.low_level.max_steps)
    sectors = cfg.root.heading_sectors
    near_m, near_cell_m = float(cfg.root.near_gate_m), float(cfg.root.near_gate_cell_m)
    root_learner = average_reward.RLearning(self.q, self.gain, rules.N_DIRECTIONS,
                                            cfg.root.alpha, cfg.root.gain_step,
                                            lambda: self.schedule[0], self.model,
                                            cfg.root.planning_every)

    def low_view(call, obs):
      origin = call.memo.setdefault("origin", np.array(call.origin[:2], dtype=np.float64))
      core.global_to_local(obs, origin, call.args["direction"], local)
      tiles_mod.active_tiles(local, self.tile_arrays, scratch_tiles)
      return scratch_tiles

    def low_internal_reward(call, step):
      # G on the state the step ended in, before any restart (as run_low_level).
      end = step.info.get("state_before_restart", step.obs)
      event, internal = core.low_level_outcome(
          step.info["positions"], end, call.memo["origin"], call.args["direction"],
          call.steps, local_samples, local, max_steps)
      call.memo["event"] = event
      call.memo["global"] = step.info.get("event")
      return internal

    def low_termination(call, step):
      return call.memo["event"] != core.NO_EVENT or call.memo["global"] in _GLOBAL_EVENTS

    def low_exit(call, step, episode_over):
      row = self.row
      row[CALLS] += 1
      g_event = _GLOBAL_EVENTS.get(call.memo["global"], core.NO_EVENT)
      sub = rules.subtask_of(call.args["direction"])
      if count_run(row, sub, call.memo["event"], g_event) and self._learn:
        schedules.record_run(self.outcomes, self.counts, sub, call.memo["event"] == core.SUCCESS)
      row[GATES] += g_event == core.SUCCESS
      row[DEPARTURES] += g_event == core.FAILURE

    def low_level(name, learner):
      return Subtask(name, children=["turn"], learner=learner, view=low_view,
                     internal_reward=low_internal_reward,
                     reward=lambda call, step, child_reward: core.STEP_REWARD,  # SPEC 3
                     termination=low_termination, on_exit=low_exit)

    def root_reward(call, step, child_reward):
      root_learner.duration = call.steps - self._row_steps     # the child's tau
      self._row_steps = call.steps
      return child_reward

    def root_termination(call, step):
      if self._learn:       # the held schedule, counted in root decisions (no episodes)
        s = settings(cfg)
        schedules.end_episode(self.schedule, self.outcomes, self.counts,
                              s.root_epsilon_threshold, s.root_epsilon_every,
                              s.root_epsilon_divisor)
      return call.steps >= self.record_steps

    root = Subtask(
        "root", learner=root_learner,
        children=[Child("diagonal" if d % 2 else "straight", direction=d)
                  for d in range(rules.N_DIRECTIONS)],
        view=lambda call, obs: root_state(obs, sectors, near_m, near_cell_m),
        reward=root_reward, termination=root_termination)
    return TaskGraph("root", [
        root,
        low_level("diagonal", self.low[rules.DIAGONAL]),
        low_level("straight", self.low[rules.STRAIGHT]),
        Primitive("turn"),
    ])

  # ---- the compiled path ---------------------------------------------------------

  def _tables(self, low):
    return (self.low[rules.DIAGONAL].trace, self.low[rules.DIAGONAL].values,
            self.low[rules.STRAIGHT].trace, self.low[rules.STRAIGHT].values) if low is None \
        else low

  def sail(self, hours, learn, sample, ship, rng_state, q=None, low=None, heading_sectors=None):
    """`hours` rows of the continuing task from `ship` (in place); `q` (another
    root's table over `heading_sectors` and the 50 m grid, the episodic
    hybrid's: 1) and `low` replace this agent's."""
    rows = np.zeros((int(hours), N_RECORD))
    cfg = self.config
    sectors = cfg.root.heading_sectors if heading_sectors is None else heading_sectors
    view = ((int(sectors), float(cfg.root.near_gate_m), float(cfg.root.near_gate_cell_m))
            if q is None else (int(sectors), 0.0, 25.0))
    patrol(int(hours), self.record_steps, learn, sample, rng_state, ship,
           self.q if q is None else q, self.gain, (self.schedule, self.outcomes, self.counts),
           self._tables(low), self.tile_arrays, settings(cfg),
           (float(cfg.root.gain_step), self.model, int(cfg.root.planning_every)), view, rows)
    return rows

  def compiled(self, episodes, learn, sample):
    """Learning continues the agent's own process; without learning, `episodes`
    hours are sailed from a fresh start drawn from the agent's generator."""
    if learn:
      if not self.started[0]:
        _ship.sample_start(self.rng_state, self.ship)
        self.started[0] = 1.0
      return self.sail(episodes, True, sample, self.ship, self.rng_state)
    ship = np.empty(4)
    _ship.sample_start(self.rng_state, ship)
    return self.sail(episodes, False, sample, ship, self.rng_state)

  # ---- metrics -------------------------------------------------------------------

  def metrics(self, record):
    """The online rates over the record's last `metric_window` hours (the block of
    `hpg-mj reproduce beyond`, whose report reads them so); control_steps counts
    the whole record."""
    return dict(self.rates(record[-self.metric_window:]),
                control_steps=int(record["steps"].sum()))

  def rates(self, record):
    """Gates, departures, reward and calls per hour (or step) over all of `record`."""
    steps = float(record["steps"].sum())
    hours = steps / core.HOUR_STEPS
    runs = {k: record[f"{k}_runs"].sum() for k in ("diagonal", "straight")}
    return {
        "episodes_measured": int(len(record)),     # record rows: hours of sailing
        "hours": hours,
        "control_steps": int(steps),
        "gates_per_hour": float(record["gates"].sum() / hours) if steps else None,
        "departures_per_hour": float(record["departures"].sum() / hours) if steps else None,
        "reward_per_step": float(record["return"].sum() / steps) if steps else None,
        "gain": float(record["gain"][-1]) if len(record) else None,
        "calls_per_hour": float(record["calls"].sum() / hours) if steps else None,
        **{f"{k}_success_rate": float(record[f"{k}_successes"].sum() / runs[k]) if runs[k]
           else None for k in runs},
    }

  def evaluation(self, hours, kind="agent", other=None):
    """Gates per hour of `hours` greedy hours from the evaluation generator's start
    (the same for every policy): this agent's ("agent"), an episodic hybrid's
    (`other`, "episodic") or the scripted helmsman's ("scripted")."""
    rng_state = rng.make_state(EVALUATION_SEED)
    ship = np.empty(4)
    _ship.sample_start(rng_state, ship)
    if kind == "scripted":
      rows = np.zeros((int(hours), N_RECORD))
      env = self.config.environment
      scripted(int(hours), self.record_steps, rng_state, ship, env.gate_reward,
               env.out_of_bounds_reward, rows)
    elif kind == "episodic":
      rows = self.sail(hours, False, False, ship, rng_state, q=other.parameters()["root_q"],
                       low=other.low_arrays(), heading_sectors=1)
    else:
      rows = self.sail(hours, False, False, ship, rng_state)
    return self.as_record(rows)

  def final_metrics(self, record):
    """Greedy gates per hour of this agent, the episodic hybrid and the scripted
    helmsman, over the same `evaluation_hours` from the same start (SPEC section 8)."""
    from hpg_mj import agents
    comparison = self.config.comparison
    hours = comparison.evaluation_hours
    out = {"greedy_gates_per_hour": self.rates(self.evaluation(hours))["gates_per_hour"],
           "scripted_gates_per_hour": self.rates(self.evaluation(hours, "scripted"))[
               "gates_per_hour"],
           "evaluation_hours": hours}
    if comparison.episodic_task:
      task = agents.load_task(comparison.episodic_task)
      episodes = comparison.episodic_episodes or task.protocol.episodes
      episodic, episodic_record, _ = agents.train(task, episodes=episodes, seed=self.seed)
      out["episodic_gates_per_hour"] = self.rates(self.evaluation(hours, "episodic",
                                                                  episodic))["gates_per_hour"]
      out["episodic_task"] = str(task.path.name)
      out["episodic_episodes"] = int(episodes)
      out["episodic_control_steps"] = int(episodic_record["steps"].sum())
      out["episodic_gate_pass_rate"] = episodic.metrics(episodic_record)["gate_pass_rate"]
    return out
