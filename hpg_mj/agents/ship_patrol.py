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
With `planning_every` > 0 the root also plans (`average_reward.plan`):
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

Both paths are the open machine over the graph of blocks (`graph`; kinds
`hierarchy.kinds.patrol`), fused and step by step on either backend
(`_ship.ContinuingShipAgent`); for a fixed seed they give the same records and
arrays. Its state by node name (`root.q`, `root.gain`, `root.model_next`, ...,
`diagonal.theta`, ..., `schedule.state`).
"""
import dataclasses

import numpy as np

from hpg_mj.agents import _ship
from hpg_mj.agents import ship_hybrid as hybrid
from hpg_mj.taskfile import param
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy import ship_rules as rules
from hpg_mj.hierarchy.patrol import N_RECORD, scripted
from hpg_mj.learners import average_reward
from hpg_mj.learners import rng
from hpg_mj.worlds import ship_core as core

EVALUATION_SEED = 2 ** 20    # the generator of the greedy evaluations' starts


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
  """The task file's schema: its sections [environment], [root], [low_level] and [comparison]."""
  environment: _ship.ContinuingEnvironment = dataclasses.field(
      default_factory=_ship.ContinuingEnvironment)
  root: Root = dataclasses.field(default_factory=Root)
  low_level: hybrid.LowLevel = dataclasses.field(default_factory=hybrid.LowLevel)
  comparison: Comparison = dataclasses.field(default_factory=Comparison)


class ShipPatrol(_ship.ContinuingShipAgent):
  """The hybrid's hierarchy with an average-reward root, on the continuing task."""

  name = "ship_patrol"
  Config = Config
  record_fields = ("steps", "gates", "departures", "calls", "diagonal_runs",
                   "diagonal_successes", "straight_runs", "straight_successes", "return",
                   "gain")
  own_fields = ("gain",)               # `finish_row`'s
  figure = "gates_per_hour"
  metric_window = 125                  # online metrics: the last 125 hours (beyond's block)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    root, low = self.config.root, self.config.low_level
    side = 2.0 * root.near_gate_m / root.near_gate_cell_m
    if abs(side - round(side)) > 1e-9:
      raise ValueError(f"[root] near_gate_cell_m = {root.near_gate_cell_m} must divide twice "
                       f"near_gate_m = {root.near_gate_m} (2 * near_gate_m / near_gate_cell_m "
                       f"= {side}, not a whole number)")
    self.coder = hybrid.coder(low)
    self.view = blocks.PatrolCell(root.heading_sectors, root.near_gate_m, root.near_gate_cell_m)
    self.root = blocks.RLearning(self.view.n_states(), root.alpha, root.gain_step, root.epsilon,
                                 epsilon_schedule=True, planning_every=root.planning_every)
    self.low = [blocks.GaussianCMAC(self.coder, low.alpha, low.trace_gamma, low.baseline,
                                    core.MAX_TURN_RATE) for _ in (rules.DIAGONAL, rules.STRAIGHT)]

  def graph(self):
    """Figure 3's graph with the continuing root (SPEC section 8): R-learning over the
    patrol's cells; a low-level call also returns at a gate pass or a departure; the
    root's call, a record row, ends once it has `record_steps` control steps, between
    calls; the held epsilon counts the root's decisions (there are no episodes)."""
    return hybrid.figure3(self.root, self.view, blocks.Clock(self.record_steps), self.low,
                          self.coder, self.config.low_level.max_steps, self.config.root,
                          per_decision=True)

  @property
  def q(self):
    """The root's relative values Q (the live array)."""
    return self.machine.state()["root.q"]

  @property
  def gain(self):
    """The root's gain [rho, greedy transitions seen] (the live array)."""
    return self.machine.state()["root.gain"]

  @property
  def model(self):
    """The root's planning model (next, reward, steps, [count]; the live arrays)."""
    state = self.machine.state()
    return tuple(state[f"root.model_{k}"] for k in ("next", "reward", "steps", "count"))

  def finish_row(self, row):
    row[self.record_fields.index("gain")] = self.gain[average_reward.RHO]

  # ---- the greedy evaluations --------------------------------------------------------

  def evaluation(self, hours, kind="agent", other=None):
    """Gates per hour of `hours` greedy hours from the evaluation generator's start
    (the same for every policy): this agent's ("agent"), an episodic hybrid's
    (`other`, "episodic": its root's values and subtasks, run on this task) or the
    scripted helmsman's ("scripted")."""
    rng_state = rng.make_state(EVALUATION_SEED)
    ship = _ship.draw_start(rng_state)
    if kind == "scripted":
      rows = np.zeros((int(hours), N_RECORD))
      env = self.config.environment
      scripted(int(hours), self.record_steps, rng_state, ship, env.gate_reward,
               env.out_of_bounds_reward, rows)
      return self.as_record(rows)
    agent = self
    if kind == "episodic":
      cfg = self.config
      agent = ShipPatrol(dataclasses.replace(cfg, root=dataclasses.replace(
          cfg.root, heading_sectors=1, near_gate_m=0.0, planning_every=0)), seed=self.seed)
      mine, theirs = agent.machine.state(), other.machine.state()
      mine["root.q"][:] = theirs["root.q"]     # the hybrid's 50 m cells: the same table
      for key in mine:                         # its subtasks' arrays, by the same names
        if key.startswith(("diagonal.", "straight.")):
          mine[key][...] = theirs[key]
    return agent.as_record(agent.compiled(hours, False, False, ship, rng_state))

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
