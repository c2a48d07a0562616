"""Tabular HPG (Algorithm 1) on taxi-fuel as a compiled fused loop (`train`), over
the learners' arrays; the agent (`hpg_mj.agents.taxi_hpg`) holds its configuration,
its step-by-step learners and its metrics, and its docstring the rule. This loop
stays hand-written until taxi HPG runs on the task-graph machine.

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

from hpg_mj.hierarchy import taxi_subtasks as rules
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import rng
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
