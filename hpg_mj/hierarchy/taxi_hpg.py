"""Tabular HPG (Algorithm 1) on taxi-fuel as a compiled fused loop (`train`), over
the learners' arrays, and its engine (`HPGEngine`: the arrays, the generator, the
runs) with the step-by-step learners on the task graph over the same arrays
(`TaxiHierarchy`); the agent (`hpg_mj.agents.taxi_hpg`) holds its configuration and
its docstring the rule. This loop stays hand-written until taxi HPG runs on the
task-graph machine.

Algorithm 1 is recursive; numba is not good at recursion, and this graph has a
fixed depth, so each level is its own function and the call stack is the
native one: `run_episode` (Root) -> `run_carry` (Get, Put or Refuel) ->
`run_navigate` (Navigate(t)) -> `taxi_rules.primitive_step`. Each function is
the `while i has not terminated` loop of Algorithm 1 for its level.

Randomness: only `learners.rng` (xoshiro256** over a uint64[4] state), drawn
in this order: per episode the start (square 0..24, passenger station 0..3,
destination among the other three 0..2, then with fuel the start fuel), then
one uniform per choice of any subtask, forced choices included, in the order
the choices are made. Greedy runs draw only the starts.

A trace is an `eligibility.Trace`; `new_traces` makes one per subtask (a tuple
by subtask id). The baselines are a tuple of five
float64 tables over the subtasks' abstract states (`new_values`).

Speed: the three levels and `train` are compiled without numba's reference
counting (`_nrt=False`), which otherwise spends about half the time counting
references to the arrays handed down at every call (3.3 million primitive steps
per second with it, about 7 million without; `hpg-mj bench train`). That is safe
because nothing here allocates (numba refuses to compile an allocation without
NRT), and the shared `learners` and `taxi_rules` functions they use are inlined
(`inline="always"`), so no reference-count-free copy of them is cached for other
callers; the other callees are this module's `choose` and `subtract_baseline`,
compiled without reference counting too, and `taxi_core.taxi_step` and
`state_from_draws`, which return scalars. `choose` and `subtract_baseline` are
called, not inlined, because numba inlines by copying and re-typing a body at every
call site: inlined into the three levels they made the first compile take 11.6 s
rather than 7.0 (`scripts/compile_times.py`), for a loop 1.25 times faster (8.2
against 6.6 million primitive steps per second). The first `run` in a process
compiles them and the three levels one by one, leaves first, before `train`
(`learners.jit`).
"""
import numba
import numpy as np

from hpg_mj.hierarchy import taxi as taxi_hierarchy
from hpg_mj.hierarchy import taxi_subtasks as rules
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import jit
from hpg_mj.learners import policies
from hpg_mj.learners import rng
from hpg_mj.learners import stepwise
from hpg_mj.worlds import taxi_core as core
from hpg_mj.worlds import taxi_rules as world_rules


# Per-episode record columns: the return, the primitive steps, how the episode
# ended (taxi_rules.DELIVERED, OUT_OF_FUEL or TRUNCATED), illegal Pickups/Dropoffs.
RETURN, STEPS, OUTCOME, ILLEGAL = range(4)
N_RECORD = 4


# Rows of the step-size schedule array handed to the compiled loop (one column
# per subtask id, see `schedule`).
S_ALPHA, S_START_FRACTION, S_DELAY, S_RAMP = range(4)


LEVELS = ("root", "carry", "navigate")


def _by_subtask(config, key):
  """A per-level key of the task file ([root], [carry], [navigate]) as float64[5] by
  subtask id (ROOT, GET, PUT, REFUEL, NAVIGATE)."""
  root, carry, navigate = (float(getattr(getattr(config, level), key)) for level in LEVELS)
  return np.array([root, carry, carry, carry, navigate])


def schedule(config) -> np.ndarray:
  """float64[4, 5]: rows S_ALPHA, S_START_FRACTION, S_DELAY, S_RAMP by subtask id."""
  return np.stack([_by_subtask(config, "alpha"), _by_subtask(config, "start_fraction"),
                   _by_subtask(config, "delay"), _by_subtask(config, "ramp")])


def gammas(config) -> np.ndarray:
  """float64[5]: the trace discounts ([level] trace_gamma) by subtask id."""
  return _by_subtask(config, "trace_gamma")


def betas(config) -> np.ndarray:
  """float64[5]: the baselines' TD(0) step sizes ([level] baseline) by subtask id."""
  return _by_subtask(config, "baseline")


def new_trace(n_states: int, n_children: int, initial: float = 0.0):
  """One subtask's Eq. 3 learner over an (n_states x n_children) table."""
  return el.new_trace(n_states * n_children, initial)


def new_traces(fuel_enabled: bool = True, capacity: int = core.FUEL_CAPACITY,
               initial: float = 0.0):
  """The five learners, by subtask id: Root, Get, Put, Refuel, Navigate."""
  sizes = rules.n_abstract_states(fuel_enabled, capacity)
  return tuple(new_trace(sizes[i], rules.N_CHILDREN[i], initial)
               for i in range(rules.N_SUBTASKS))


def new_values(fuel_enabled: bool = True, capacity: int = core.FUEL_CAPACITY):
  """The five baselines b_i (zero), by subtask id: one value per abstract state."""
  return tuple(np.zeros(n) for n in rules.n_abstract_states(fuel_enabled, capacity))


def policy_table(trace, n_children: int) -> np.ndarray:
  """A copy of the trace's current parameters as an (n_states, n_children) table."""
  return el.parameters(trace).reshape(-1, n_children)


@numba.njit(cache=True, _nrt=False)
def choose(trace, abstract, n_children, mask, learn, greedy, rng_state, probs, index, psi):
  """Algorithm 1, line 8: a child from the subtask's softmax policy in its
  abstract state; when learning, also line 14: z <- z + psi (`softmax_act`)."""
  if greedy:
    return policies.softmax_greedy(trace, abstract, n_children, mask)
  if learn:
    return policies.softmax_act(trace, abstract, n_children, mask, rng_state, probs, index, psi)
  policies.softmax_probabilities(trace, abstract, n_children, mask, probs)
  return policies.sample_index(probs[:n_children], rng.uniform(rng_state))


@numba.njit(cache=True, inline="always")
def begin_call(trace, learn):
  """Eq. 3: z <- 0 when a subtask is called."""
  if learn:
    el.reset(trace)


@numba.njit(cache=True, inline="always")
def learn_from(trace, learn, alpha, reward, gamma):
  """Algorithm 1, line 16 read as Eq. 3: theta <- theta + alpha R z, then z <- gamma z."""
  if learn:
    el.learn(trace, alpha, reward, gamma)


@numba.njit(cache=True, _nrt=False)
def subtract_baseline(theta, values, abstract, n_children, mask, learn, alpha, index, psi):
  """Eq. 3 with a baseline (`Config`): theta <- theta - alpha b(s) psi(s, a) for
  the choice a just made in abstract state s, whose score `softmax_act` left in
  `index`, `psi` (one entry per child allowed by `mask`). Nothing when b(s) = 0."""
  if learn:
    amount = alpha * values[abstract]
    if amount != 0.0:
      n = 0
      for b in range(n_children):
        if mask[b]:
          theta[index[n]] -= amount * psi[n]
          n += 1


@numba.njit(cache=True, inline="always")
def learn_baseline(values, abstract, learn, beta, reward, done, next_abstract):
  """The baseline's TD(0) step on the subtask's own return, once the child
  that was chosen in s returned R: b(s) <- b(s) + beta (R + b(s') - b(s)), with
  b(s') = 0 when the call (or the episode) ended."""
  if learn and beta != 0.0:
    target = reward
    if not done:
      target += values[next_abstract]
    values[abstract] += beta * (target - values[abstract])


# The three levels of Algorithm 1's recursion. Each is the `while i has not
# terminated` loop (lines 7-19) of its subtask; a call returns the sum of the
# primitive rewards earned during it (R~, line 17). Nothing here allocates: the
# scratch arrays come from the caller (see the module docstring on _nrt=False).

@numba.njit(cache=True, _nrt=False)
def run_navigate(target, nav, state, episode, world, learning, learn, greedy, rng_state, scratch):
  """One call of Navigate(target). `learning` = (alphas, gammas, values, betas) by
  subtask id; `scratch` = (mask, probs, index, psi)."""
  alphas, gammas, values, betas = learning
  mask, probs, index, psi = scratch
  begin_call(nav, learn)
  n = rules.N_CHILDREN[rules.NAVIGATE]
  total = 0.0
  done = world_rules.episode_over(episode) or rules.navigate_done(target, state, world)
  here = rules.navigate_state(target, state)
  while not done:
    rules.navigate_children(mask)
    move = choose(nav, here, n, mask, learn, greedy, rng_state, probs, index, psi)
    subtract_baseline(nav.theta, values[rules.NAVIGATE], here, n, mask, learn,
                      alphas[rules.NAVIGATE], index, psi)
    reward = world_rules.primitive_step(state, episode, move, world)  # child index = action index
    learn_from(nav, learn, alphas[rules.NAVIGATE], reward, gammas[rules.NAVIGATE])
    done = world_rules.episode_over(episode) or rules.navigate_done(target, state, world)
    there = rules.navigate_state(target, state)
    learn_baseline(values[rules.NAVIGATE], here, learn, betas[rules.NAVIGATE], reward, done,
                   there)
    here = there
    total += reward
  return total


@numba.njit(cache=True, _nrt=False)
def run_carry(subtask, carry, nav, state, episode, world, learning, learn, greedy, rng_state,
              scratch):
  """One call of Get, Put or Refuel (`subtask`, with its trace `carry`)."""
  alphas, gammas, values, betas = learning
  mask, probs, index, psi = scratch
  begin_call(carry, learn)
  n = rules.N_CHILDREN[subtask]
  total = 0.0
  done = world_rules.episode_over(episode) or rules.carry_done(subtask, state, world)
  here = rules.carry_state(subtask, state)
  while not done:
    rules.carry_children(subtask, state, world, mask)
    child = choose(carry, here, n, mask, learn, greedy, rng_state, probs, index, psi)
    subtract_baseline(carry.theta, values[subtask], here, n, mask, learn, alphas[subtask], index, psi)
    if child == rules.CARRY_NAVIGATE:
      reward = run_navigate(rules.carry_target(subtask, state), nav, state, episode, world,
                            learning, learn, greedy, rng_state, scratch)
    else:
      reward = world_rules.primitive_step(state, episode, rules.carry_primitive(subtask), world)
    learn_from(carry, learn, alphas[subtask], reward, gammas[subtask])
    done = world_rules.episode_over(episode) or rules.carry_done(subtask, state, world)
    there = rules.carry_state(subtask, state)
    learn_baseline(values[subtask], here, learn, betas[subtask], reward, done, there)
    here = there
    total += reward
  return total


@numba.njit(cache=True, _nrt=False)
def run_episode(traces, state, episode, world, learning, learn, greedy, rng_state, scratch):
  """One call of Root: the whole episode from `state`. Returns its return."""
  root, get, put, refuel, nav = traces
  alphas, gammas, values, betas = learning
  mask, probs, index, psi = scratch
  begin_call(root, learn)
  n = rules.N_CHILDREN[rules.ROOT]
  total = 0.0
  here = rules.root_state(state, world)
  while not world_rules.episode_over(episode):
    rules.root_children(state, world, mask)
    child = choose(root, here, n, mask, learn, greedy, rng_state, probs, index, psi)
    subtract_baseline(root.theta, values[rules.ROOT], here, n, mask, learn, alphas[rules.ROOT], index,
                      psi)
    if child == rules.ROOT_GET:
      reward = run_carry(rules.GET, get, nav, state, episode, world, learning, learn, greedy,
                         rng_state, scratch)
    elif child == rules.ROOT_PUT:
      reward = run_carry(rules.PUT, put, nav, state, episode, world, learning, learn, greedy,
                         rng_state, scratch)
    else:
      reward = run_carry(rules.REFUEL, refuel, nav, state, episode, world, learning, learn,
                         greedy, rng_state, scratch)
    learn_from(root, learn, alphas[rules.ROOT], reward, gammas[rules.ROOT])
    there = rules.root_state(state, world)
    learn_baseline(values[rules.ROOT], here, learn, betas[rules.ROOT], reward,
                   world_rules.episode_over(episode), there)
    here = there
    total += reward
  return total


@numba.njit(cache=True, inline="always")
def step_sizes(schedule, episode_index, alphas):
  """Writes alpha_i * f_i(e) for learning episode e (see `Config`) into `alphas`."""
  for i in range(alphas.shape[0]):
    fraction = schedule[S_START_FRACTION, i]
    delay = schedule[S_DELAY, i]
    if episode_index >= delay:
      rise = min(1.0, (episode_index - delay + 1.0) / schedule[S_RAMP, i])
      fraction += (1.0 - fraction) * rise
    alphas[i] = schedule[S_ALPHA, i] * fraction


@numba.njit(cache=True, _nrt=False)
def train(n_episodes, learn, greedy, rng_state, world, traces, values, settings, first_episode,
          record, starts, scratch):
  """Runs `n_episodes` episodes of HPG: learning (`learn`), or evaluating the
  current policies by sampling (`learn=False`) or greedily (`greedy`, which
  needs `learn=False`).

  `traces`: the five `eligibility.Trace`s by subtask id (`new_traces`); `values`
  the baselines (`new_values`); `settings` = (schedule, gammas, betas):
  `schedule(config)`, which gives the step sizes of learning episode
  `first_episode + e`, the trace discounts and the baselines' step sizes, float64[5]
  each by subtask id. `record` (n_episodes, N_RECORD) receives one row per
  episode. `starts` int64[k, 5]: with k = 0 every episode starts at random (SPEC
  section 5), otherwise episode e starts at starts[e % k]. `scratch` (nothing here
  allocates, see above) = (int64[12], float64[13], bool[MAX_CHILDREN]).
  Returns the primitive steps run.
  """
  if learn and greedy:
    raise ValueError("taxi_hpg.train: greedy runs do not learn; pass learn=False")
  schedule, gammas, betas = settings
  scratch_int, scratch_float, mask = scratch
  state = scratch_int[0:5]
  episode = scratch_int[5:8]
  index = scratch_int[8:12]
  probs = scratch_float[0:4]
  psi = scratch_float[4:8]
  alphas = scratch_float[8:13]
  total_steps = 0
  for e in range(n_episodes):
    if starts.shape[0] > 0:
      for i in range(5):
        state[i] = starts[e % starts.shape[0], i]
    else:
      rules.sample_start(rng_state, world, state)
    for i in range(3):
      episode[i] = 0
    step_sizes(schedule, first_episode + e, alphas)
    ret = run_episode(traces, state, episode, world, (alphas, gammas, values, betas), learn,
                      greedy, rng_state, (mask, probs, index, psi))
    record[e, RETURN] = ret
    record[e, STEPS] = episode[world_rules.E_STEPS]
    record[e, OUTCOME] = episode[world_rules.E_OUTCOME]
    record[e, ILLEGAL] = episode[world_rules.E_ILLEGAL]
    total_steps += episode[world_rules.E_STEPS]
  return total_steps


# ---- the engine: the learners' arrays, the fused loop's runs, the step-by-step graph ----

class HPGEngine:
  """HPG on one taxi task: its learners (`traces`, and the baselines `values`),
  its generator, and a `run` for training and evaluation that wraps the
  compiled `train`."""

  def __init__(self, config, seed: int = 0, task: core.TaxiRules = None,
               initial: float = 0.0):
    """Args:
      config: the agent's Config (`hpg_mj.agents.taxi_hpg.Config`: its [root],
        [carry], [navigate] sections).
      seed: the integer seed of the `learners.rng` generator.
      task: the taxi task (`taxi_core.TaxiRules`; SPEC taxi-fuel if None).
      initial: every parameter's start value (0: uniform policies).
    """
    if not all(hasattr(config, level) for level in LEVELS):
      raise ValueError(f"HPGEngine: config must have the sections {list(LEVELS)} "
                       f"(hpg_mj.agents.taxi_hpg.Config), got {type(config).__name__}")
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


class _BaselinedSoftmax(stepwise.SoftmaxPolicyGradient):
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
