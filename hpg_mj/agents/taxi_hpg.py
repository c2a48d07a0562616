"""Tabular HPG (Algorithm 1) on taxi-fuel (SPEC section 5, paper section 5.1): its
configuration, its step-by-step learners on the task graph of `hierarchy.taxi`
(`TaxiHierarchy`, over the fused loop's arrays) and its agent.

Every non-primitive subtask of the task graph (`taxi_rules`) holds one policy
parameter per (abstract state, child) and acts with a softmax (Gibbs) policy;
each learns by Eq. 3 on its own trace (`learners.eligibility`):

    on every call of subtask i:    z_i <- 0                            (Algorithm 1, lines 11-12)
    each choice a in state s:      z_i <- gamma_i z_i + psi_i(s, a)    (line 14; `softmax_act`)
    when the child a returns R:    theta_i <- theta_i + alpha_i R z_i  (line 16, read as Eq. 3)

R is the sum of the primitive rewards earned while the child ran (line 17); the
taxi has no internal reward G. The trace is reset when a subtask starts rather
than when it ends (line 12): the same thing, except that the final child's
reward - a delivery's +20 - is applied with the trace still holding the
choices that led to it, as Eq. 3 does (z is reset at s*, and R(s*, .) = 0).

Two deliberate departures from the paper, each an option of the task file
(tasks/taxi_fuel_hpg.toml) explained at `Config`: the step sizes warm up instead
of never increasing, and each subtask subtracts a learned baseline b_i(s) from
its reward-to-go (REINFORCE's baseline), which adds to the rule above

    each choice a in state s:      theta_i <- theta_i - alpha_i b_i(s) psi_i(s, a)
    when the child a returns R:    b_i(s) <- b_i(s) + beta_i (R + b_i(s') - b_i(s))

Its fused compiled loop and learners' arrays are `hpg_mj.hierarchy.taxi_hpg`.
"""
import dataclasses

import numpy as np

from hpg_mj.agents import _taxi
from hpg_mj import taskfile
from hpg_mj.taskfile import param
from hpg_mj.hierarchy import taxi as taxi_hierarchy
from hpg_mj.hierarchy import taxi_subtasks as rules
from hpg_mj.hierarchy.taxi_hpg import (N_RECORD, betas, choose, gammas, learn_baseline,
                                       new_traces, new_values, policy_table, run_carry,
                                       run_episode, run_navigate, schedule, step_sizes,
                                       subtract_baseline, train)
from hpg_mj.learners import stepwise as learners
from hpg_mj.learners import jit
from hpg_mj.learners import rng
from hpg_mj.worlds import taxi_core as core
from hpg_mj.worlds import taxi_rules as world_rules


class HPGEngine:
  """HPG on one taxi task: its learners (`traces`, and the baselines `values`),
  its generator, and a `run` for training and evaluation that wraps the
  compiled `train`."""

  def __init__(self, seed: int = 0, config=None, task: core.TaxiRules = None,
               initial: float = 0.0):
    """Args:
      seed: the integer seed of the `learners.rng` generator.
      config: the agent's `Config` (its [root], [carry], [navigate] sections).
      task: the taxi task (`taxi_core.TaxiRules`; SPEC taxi-fuel if None).
      initial: every parameter's start value (0: uniform policies).
    """
    config = Config() if config is None else config
    if not isinstance(config, Config):
      raise ValueError(f"HPGEngine: config must be a taxi_hpg.Config, got "
                       f"{type(config).__name__}")
    if not np.isfinite(initial):
      raise ValueError(f"HPGEngine: initial must be finite, got {initial!r}")
    self.task = task if task is not None else core.TaxiRules()
    self.world = world_rules.world_config(self.task)
    self.config = config
    self.rng_state = rng.make_state(seed)
    self.traces = new_traces(self.task.fuel_enabled, self.task.capacity, initial)
    self.values = new_values(self.task.fuel_enabled, self.task.capacity)   # the baselines
    self.episodes = 0          # learning episodes so far (they drive the step-size warm-up)
    self.primitive_steps = 0   # primitive steps of learning so far

  def run(self, n_episodes: int, learn: bool = True, greedy: bool = False, starts=None):
    """`n_episodes` episodes; returns the (n_episodes, N_RECORD) record.

    learn=True trains; learn=False evaluates the current policies, sampling
    from them or, with greedy=True, taking each subtask's most probable child.
    `starts`: None for random starts (SPEC section 5), or one state
    `[row, col, passenger, destination, fuel]` or a list of them, used in turn.
    """
    if not isinstance(n_episodes, (int, np.integer)) or n_episodes < 0:
      raise ValueError(f"HPGEngine.run: n_episodes must be an integer >= 0, got {n_episodes!r}")
    if learn and greedy:
      raise ValueError("HPGEngine.run: greedy=True evaluates without learning; pass learn=False")
    start = np.zeros((0, 5), dtype=np.int64)
    if starts is not None:
      rows = np.asarray(starts)
      rows = rows[None] if rows.ndim == 1 else rows
      start = np.array([self.task.check_state(row) for row in rows], dtype=np.int64)
      start = start.reshape(-1, 5)
    record = np.zeros((int(n_episodes), N_RECORD))
    scratch = self._train_scratch()
    jit.compile_first(train, lambda: self._rules_bottom_up(scratch))
    steps = train(int(n_episodes), bool(learn), bool(greedy), self.rng_state, self.world,
                  self.traces, self.values,
                  (schedule(self.config), gammas(self.config), betas(self.config)),
                  self.episodes, record, start, scratch)
    if learn:
      self.episodes += int(n_episodes)
      self.primitive_steps += int(steps)
    return record

  def _train_scratch(self):
    """`train`'s scratch arrays: (int64[12], float64[13], bool[MAX_CHILDREN])."""
    return (np.zeros(12, dtype=np.int64), np.zeros(13),
            np.zeros(rules.MAX_CHILDREN, dtype=np.bool_))

  def _rules_bottom_up(self, scratch):
    """The rules `train` calls, callees first, with arguments of the types it calls
    them with (`learners.jit.compile_first`; see `hierarchy.maxq.MAXQEngine`)."""
    scratch_int, scratch_float, mask = scratch
    state, episode, index = scratch_int[0:5], scratch_int[5:8], scratch_int[8:12]
    probs, psi, alphas = scratch_float[0:4], scratch_float[4:8], scratch_float[8:13]
    learning = (alphas, gammas(self.config), self.values, betas(self.config))
    small = (mask, probs, index, psi)
    i, f, b = np.int64(0), 0.0, False
    trace = self.traces[rules.NAVIGATE]
    return [
        (choose, (trace, i, i, mask, b, b, self.rng_state, probs, index, psi)),
        (subtract_baseline, (trace.theta, self.values[0], i, i, mask, b, f, index, psi)),
        (run_navigate, (i, trace, state, episode, self.world, learning, b, b, self.rng_state,
                        small)),
        (run_carry, (i, trace, trace, state, episode, self.world, learning, b, b,
                     self.rng_state, small)),
        (run_episode, (self.traces, state, episode, self.world, learning, b, b,
                       self.rng_state, small)),
    ]

  def policy_tables(self):
    """Each subtask's current parameters, an (abstract states, children) table."""
    return tuple(policy_table(t, rules.N_CHILDREN[i]) for i, t in enumerate(self.traces))


class _BaselinedSoftmax(learners.SoftmaxPolicyGradient):
  """The Gibbs learner with the compiled loop's baseline b(s) (`train`):
  Eq. 3, plus theta <- theta - alpha b(s) psi(s, a) for each choice and a TD(0)
  step of b when the child returns, by the same compiled functions.

  theta <- theta - alpha b(s) psi(s, a) is applied when the child returns, not
  at the choice as in the compiled loop: the child never touches this
  subtask's parameters, so the numbers are the same, and only then does the
  executor say whether it is learning.
  """

  def __init__(self, n_states, n_actions, values, beta):
    super().__init__(n_states, n_actions, alpha=1.0)
    self.values = values      # the compiled loop's baseline table (shared)
    self.beta = float(beta)
    self._here = 0
    self._mask = self._all

  def act(self, features, mask, rng_state, sample):
    self._here = int(features)
    self._mask = self._all if mask is None else mask
    return super().act(features, mask, rng_state, sample)

  def observe(self, signal, next_features, done, terminal, learn):
    subtract_baseline(self.trace.theta, self.values, self._here, self.n_actions,
                                    self._mask, learn, self.alpha, self._index, self._psi)
    super().observe(signal, next_features, done, terminal, learn)
    learn_baseline(self.values, self._here, learn, self.beta, signal, done,
                                 0 if next_features is None else int(next_features))


class TaxiHierarchy:
  """The task graph over an `HPGEngine`'s learners (shared arrays)."""

  def __init__(self, hpg: HPGEngine):
    self.hpg = hpg
    self.world = hpg.world
    sizes = rules.n_abstract_states(hpg.task.fuel_enabled, hpg.task.capacity)
    self.learners = []
    beta, gamma = betas(hpg.config), gammas(hpg.config)
    for i, trace in enumerate(hpg.traces):
      learner = _BaselinedSoftmax(sizes[i], rules.N_CHILDREN[i], hpg.values[i], beta[i])
      learner.trace = trace                               # the compiled loop's arrays
      learner.gamma = float(gamma[i])
      self.learners.append(learner)
    self._alphas = np.zeros(rules.N_SUBTASKS)
    self._state = np.zeros(5, dtype=np.int64)

  def _s(self, obs):
    return taxi_hierarchy.rules_state(obs, self.hpg.task.fuel_enabled, self._state)

  def graph(self):
    w = self.world
    views = {
        rules.ROOT: lambda call, obs: int(rules.root_state(self._s(obs), w)),
        rules.NAVIGATE: lambda call, obs: int(rules.navigate_state(call.args["target"],
                                                                   self._s(obs))),
    }
    for i in (rules.GET, rules.PUT, rules.REFUEL):
      views[i] = lambda call, obs, i=i: int(rules.carry_state(i, self._s(obs)))
    return taxi_hierarchy.taxi_graph(w, self.learners, self._s, views.__getitem__)




def _level(alpha, start_fraction, delay, ramp, doc):
  cls = dataclasses.make_dataclass("Level", [
      ("learner", str, param("policy_gradient", "Eq. 3", choices=("policy_gradient",))),
      ("alpha", float, param(alpha, "Eq. 3 step size after the warm-up", low=0)),
      ("start_fraction", float, param(start_fraction, "the step size's fraction of alpha at "
                                      "first", low=0, high=1)),
      ("delay", int, param(delay, "learning episodes at start_fraction", low=0)),
      ("ramp", int, param(ramp, "episodes of the linear rise to alpha", low=1)),
      ("trace_gamma", float, param(1.0, "discount on the Eq. 3 trace (1 = plain Eq. 3)", low=0,
                                   high=1, low_open=True)),
      ("baseline", float, param(0.3, "TD(0) step size of the baseline b(s) (0: none, Eq. 3)",
                                low=0, high=1)),
  ], frozen=True, bases=(taskfile.Section,))
  cls.__doc__ = doc
  return cls


Root = _level(0.3, 0.0, 15_000, 20_000, "[root]: Root -> {Get, Put, Refuel}")
Carry = _level(0.1, 0.1, 0, 25_000, "[carry]: Get, Put and Refuel (each its own table)")
Navigate = _level(0.1, 0.1, 0, 25_000, "[navigate]: Navigate(t), one table over (t, row, col)")


@dataclasses.dataclass(frozen=True)
class Config:
  """HPG's hyper-parameters for the taxi, by level: [root]; [carry] (Get, Put and
  Refuel); [navigate] (Navigate(t)); each with the keys alpha, start_fraction,
  delay, ramp, trace_gamma and baseline (alpha_i, start_i, ... below).

  Step sizes warm up: subtask i learns with alpha_i * f_i(e) in its e-th learning
  episode, f_i = start_i for the first delay_i episodes, then rising linearly to
  1 over ramp_i episodes. The paper's assumptions A4-A5 ask for non-increasing
  step sizes; a constant alpha large enough to learn in 100,000 episodes makes
  Eq. 3 (REINFORCE, no baseline) commit early to wrong children for good: the
  first calls are long random walks that mostly end with the tank dry, so every
  choice in them gets the same large negative reward-to-go, pure noise that
  drives the softmax to a corner, and a subtask whose calls from a state always
  run dry never again sees a reward that tells its children apart. Small steps
  while calls are long and doomed, full steps once they are short, avoid it.
  Root also waits (delay) with a uniform policy while its children learn, or it
  learns to avoid a child (Refuel, say) that is merely still bad.

  Each subtask may also subtract a baseline b_i(s) from its reward-to-go, a
  second declared departure (REINFORCE's baseline, Williams 1992; the paper's
  Eq. 3 has none): a choice a made in state s then moves theta_i along
  psi(s, a) times (the rewards of the rest of the call - b_i(s)) instead of the
  rewards alone. In Eq. 3's online form that is one extra step at the choice,
  theta_i <- theta_i - alpha_i b_i(s) psi(s, a) (`subtract_baseline`), next to the
  unchanged z and theta updates. b_i is a table over subtask i's abstract states,
  learned by TD(0) on the subtask's own rewards with step size baseline_i
  (`learn_baseline`; 0 keeps b_i = 0, Eq. 3 exactly). Any b(s) that does not
  depend on the choice made in s leaves the gradient estimate unbiased
  (E[psi(s, a)] = 0 under the policy); it only removes variance. Why it is
  needed: without it every call's reward-to-go is of one sign (Navigate's only
  ever negative, Root's mostly the +20 delivery), so each choice is pushed the
  same way whatever its worth, and only the small differences between those
  large pushes carry the gradient. Root, whose decisions (refuel now, later or
  never) differ by a few steps out of a return of about 6, learned them too
  slowly: about 93% of the optimal mean return after 100,000 episodes (online,
  last 1,000 episodes, seeds 0-4) with alpha 0.1 / 0.03 / 0.03 and no
  baseline, while the larger step sizes below run away without one (51%).
  With the baseline and them: 98.8% (97.2% over seeds 5-24). The baseline's
  step size is 1 at most: b(s) moves part of the way to its TD target. The
  baselines learn from the first episode, Root's too while Root waits.
  """
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)
  root: Root = dataclasses.field(default_factory=Root)
  carry: Carry = dataclasses.field(default_factory=Carry)
  navigate: Navigate = dataclasses.field(default_factory=Navigate)


class TaxiHPG(_taxi.TaxiAgent):
  """HPG's tables, baselines and generator, trained step by step or compiled."""

  name = "taxi_hpg"
  Config = Config
  record_fields = ("return", "steps", "outcome", "illegal")

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    self._adopt(HPGEngine(seed=seed, config=self.config, task=self.rules))
    self.hierarchy = TaxiHierarchy(self.engine)
    self._schedule = schedule(self.config)
    self._alphas = np.zeros(len(self.hierarchy.learners))

  def state(self):
    out = {"rng_state": self.rng_state}
    names = ("root", "get", "put", "refuel", "navigate")
    for name, trace, values in zip(names, self.engine.traces, self.engine.values):
      out.update({f"{name}_{k}": v for k, v in trace._asdict().items()})
      out[f"{name}_baseline"] = values
    return out

  def compiled(self, episodes, learn, sample):
    # (The engine counts its own episodes; the base class must not count them again.)
    before = self.engine.episodes
    rows = self.engine.run(episodes, learn=learn, greedy=not learn and not sample)
    self.engine.episodes = before
    return rows

  def graph(self):
    return self.hierarchy.graph()

  def begin_episode(self, learn):
    step_sizes(self._schedule, self.engine.episodes, self._alphas)
    for learner, alpha in zip(self.hierarchy.learners, self._alphas):
      learner.alpha = float(alpha)
