"""HPG (Algorithm 1) on taxi-fuel in one compiled loop (SPEC section 5, paper section 5.1).

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

A trace is the tuple `(w, zs, y, touched, marked, count, acc)` of `eligibility`'s
arrays; `new_traces` makes one per subtask.
"""
import dataclasses

import numba
import numpy as np

from hpg_mj.hierarchy import taxi_rules as rules
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import rng
from hpg_mj.worlds import taxi_core as core

# Per-episode record columns: the return, the primitive steps, how the episode
# ended (taxi_rules.DELIVERED, OUT_OF_FUEL or TRUNCATED), illegal Pickups/Dropoffs.
RETURN, STEPS, OUTCOME, ILLEGAL = range(4)
N_RECORD = 4


@dataclasses.dataclass(frozen=True)
class HPGConfig:
  """HPG's hyper-parameters for the taxi (tuned to reach 95% of the optimal mean
  return within 100,000 episodes; see tests/hierarchy/test_taxi_hpg.py)."""
  alpha_root: float = 0.05       # Eq. 3 step size of Root
  alpha_carry: float = 0.05      # of Get, Put and Refuel
  alpha_navigate: float = 0.05   # of Navigate(t) (one table for the five targets)
  gamma_root: float = 1.0        # trace discount of Root (1: Eq. 3 exactly)
  gamma_carry: float = 1.0       # of Get, Put and Refuel
  gamma_navigate: float = 1.0    # of Navigate(t)
  initial: float = 0.0           # every policy parameter's start value (0: uniform policies)

  def alphas(self) -> np.ndarray:
    """Step sizes by subtask id (taxi_rules.ROOT .. NAVIGATE)."""
    return np.array([self.alpha_root, self.alpha_carry, self.alpha_carry, self.alpha_carry,
                     self.alpha_navigate])

  def gammas(self) -> np.ndarray:
    return np.array([self.gamma_root, self.gamma_carry, self.gamma_carry, self.gamma_carry,
                     self.gamma_navigate])

  def __post_init__(self):
    for name in ("alpha_root", "alpha_carry", "alpha_navigate"):
      value = getattr(self, name)
      if not (np.isfinite(value) and value >= 0.0):
        raise ValueError(f"HPGConfig: {name} must be a finite number >= 0, got {value!r}")
    for name in ("gamma_root", "gamma_carry", "gamma_navigate"):
      value = getattr(self, name)
      if not 0.0 < value <= 1.0:
        raise ValueError(f"HPGConfig: {name} must be in (0, 1], got {value!r}")
    if not np.isfinite(self.initial):
      raise ValueError(f"HPGConfig: initial must be finite, got {self.initial!r}")


def new_trace(n_states: int, n_children: int, initial: float = 0.0):
  """One subtask's Eq. 3 learner over an (n_states x n_children) table, as a tuple."""
  t = el.new_trace(n_states * n_children, initial)
  return (t["w"], t["zs"], t["y"], t["touched"], t["marked"], t["count"], t["acc"])


def new_traces(fuel_enabled: bool = True, capacity: int = core.FUEL_CAPACITY,
               initial: float = 0.0):
  """The five learners, by subtask id: Root, Get, Put, Refuel, Navigate."""
  sizes = rules.n_abstract_states(fuel_enabled, capacity)
  return tuple(new_trace(sizes[i], rules.N_CHILDREN[i], initial)
               for i in range(rules.N_SUBTASKS))


def policy_table(trace, n_children: int) -> np.ndarray:
  """A copy of the trace's current parameters as an (n_states, n_children) table."""
  w, zs, y, _, _, _, acc = trace
  return (w + zs * acc[0] - y).reshape(-1, n_children)


@numba.njit(cache=True)
def sample_start(rng_state, world, state):
  """A start state (SPEC section 5), drawn in the order square, passenger
  station, destination among the other three, fuel (fuel task only)."""
  square = rng.randint(rng_state, rules.N_SQUARES)
  station = rng.randint(rng_state, rules.N_STATIONS)
  other = rng.randint(rng_state, rules.N_STATIONS - 1)
  fuel = core.CLASSIC_FUEL
  if world[rules.W_FUEL_ENABLED] != 0:
    fuel = world[rules.W_START_FUEL_MIN] + rng.randint(
        rng_state, world[rules.W_START_FUEL_MAX] - world[rules.W_START_FUEL_MIN] + 1)
  row, col, passenger, destination, fuel = core.state_from_draws(square, station, other, fuel)
  state[rules.ROW] = row
  state[rules.COL] = col
  state[rules.PASSENGER] = passenger
  state[rules.DESTINATION] = destination
  state[rules.FUEL] = fuel


@numba.njit(cache=True)
def choose(trace, abstract, n_children, mask, learn, greedy, rng_state, probs, index, psi):
  """Algorithm 1, line 8 (and line 14 when learning: z <- z + psi)."""
  w, zs, y, touched, marked, count, acc = trace
  if greedy:
    return policies.softmax_greedy(w, zs, y, acc, abstract, n_children, mask)
  if learn:
    return policies.softmax_act(w, zs, y, touched, marked, count, acc, abstract, n_children,
                                mask, rng_state, probs, index, psi)
  policies.softmax_probabilities(w, zs, y, acc, abstract, n_children, mask, probs)
  return policies.sample_index(probs[:n_children], rng.uniform(rng_state))


@numba.njit(cache=True)
def start_call(trace, learn):
  """Eq. 3: z <- 0 when a subtask is called."""
  if learn:
    w, zs, y, touched, marked, count, acc = trace
    el.reset(w, zs, y, touched, marked, count, acc)


@numba.njit(cache=True)
def learn_from(trace, learn, alpha, reward, gamma):
  """Algorithm 1, line 16 as Eq. 3: theta <- theta + alpha R z (then z <- gamma z)."""
  if learn:
    w, zs, y, touched, marked, count, acc = trace
    el.reward(w, zs, y, touched, marked, count, acc, alpha, reward, gamma)


@numba.njit(cache=True)
def run_navigate(target, state, episode, world, nav, alphas, gammas, learn, greedy, rng_state,
                 mask, probs, index, psi):
  """One call of Navigate(target); returns the reward it earned."""
  start_call(nav, learn)
  n = rules.N_CHILDREN[rules.NAVIGATE]
  total = 0.0
  while not rules.episode_over(episode) and not rules.navigate_done(target, state, world):
    rules.navigate_children(mask)
    move = choose(nav, rules.navigate_state(target, state), n, mask, learn, greedy, rng_state,
                  probs, index, psi)
    reward = rules.primitive_step(state, episode, move, world)  # child index = action index
    learn_from(nav, learn, alphas[rules.NAVIGATE], reward, gammas[rules.NAVIGATE])
    total += reward
  return total


@numba.njit(cache=True)
def run_carry(subtask, carry, nav, state, episode, world, alphas, gammas, learn, greedy,
              rng_state, mask, probs, index, psi):
  """One call of Get, Put or Refuel (`carry` is its trace); returns its reward."""
  start_call(carry, learn)
  n = rules.N_CHILDREN[subtask]
  total = 0.0
  while not rules.episode_over(episode) and not rules.carry_done(subtask, state, world):
    rules.carry_children(subtask, state, world, mask)
    child = choose(carry, rules.carry_state(subtask, state), n, mask, learn, greedy, rng_state,
                   probs, index, psi)
    target = rules.carry_child_target(subtask, child)
    if target >= 0:
      reward = run_navigate(target, state, episode, world, nav, alphas, gammas, learn, greedy,
                            rng_state, mask, probs, index, psi)
    else:
      reward = rules.primitive_step(state, episode, rules.carry_primitive(subtask), world)
    learn_from(carry, learn, alphas[subtask], reward, gammas[subtask])
    total += reward
  return total


@numba.njit(cache=True)
def run_episode(root, get, put, refuel, nav, state, episode, world, alphas, gammas, learn,
                greedy, rng_state, mask, probs, index, psi):
  """One call of Root from `state`: the whole episode. Returns its return."""
  start_call(root, learn)
  n = rules.N_CHILDREN[rules.ROOT]
  total = 0.0
  while not rules.episode_over(episode):
    rules.root_children(state, world, mask)
    child = choose(root, rules.root_state(state, world), n, mask, learn, greedy, rng_state,
                   probs, index, psi)
    if child == rules.ROOT_GET:
      reward = run_carry(rules.GET, get, nav, state, episode, world, alphas, gammas, learn,
                         greedy, rng_state, mask, probs, index, psi)
    elif child == rules.ROOT_PUT:
      reward = run_carry(rules.PUT, put, nav, state, episode, world, alphas, gammas, learn,
                         greedy, rng_state, mask, probs, index, psi)
    else:
      reward = run_carry(rules.REFUEL, refuel, nav, state, episode, world, alphas, gammas,
                         learn, greedy, rng_state, mask, probs, index, psi)
    learn_from(root, learn, alphas[rules.ROOT], reward, gammas[rules.ROOT])
    total += reward
  return total


@numba.njit(cache=True)
def train(n_episodes, learn, greedy, rng_state, world, root, get, put, refuel, nav, alphas,
          gammas, record, fixed_start):
  """Runs `n_episodes` episodes of HPG: learning (`learn`), or evaluating the
  current policies by sampling (`learn=False`) or greedily (`greedy`, which
  needs `learn=False`).

  `alphas`, `gammas`: float64[5] by subtask id. `record` (n_episodes, N_RECORD)
  receives one row per episode. With `fixed_start` of length 5 every episode
  starts there instead of at a random start. Returns the primitive steps run.
  """
  if learn and greedy:
    raise ValueError("taxi_compiled.train: greedy runs do not learn; pass learn=False")
  state = np.empty(5, dtype=np.int64)
  episode = np.empty(3, dtype=np.int64)
  mask = np.zeros(rules.MAX_CHILDREN, dtype=np.bool_)
  probs = np.empty(rules.MAX_CHILDREN)
  index = np.empty(rules.MAX_CHILDREN, dtype=np.int64)
  psi = np.empty(rules.MAX_CHILDREN)
  total_steps = 0
  for e in range(n_episodes):
    if fixed_start.shape[0] == 5:
      state[:] = fixed_start
    else:
      sample_start(rng_state, world, state)
    episode[:] = 0
    ret = run_episode(root, get, put, refuel, nav, state, episode, world, alphas, gammas, learn,
                      greedy, rng_state, mask, probs, index, psi)
    record[e, RETURN] = ret
    record[e, STEPS] = episode[rules.E_STEPS]
    record[e, OUTCOME] = episode[rules.E_OUTCOME]
    record[e, ILLEGAL] = episode[rules.E_ILLEGAL]
    total_steps += episode[rules.E_STEPS]
  return total_steps


class TaxiHPG:
  """HPG on one taxi task: its learners, its generator, and a `run` for training
  and evaluation that wraps the compiled `train`."""

  def __init__(self, seed: int = 0, config: HPGConfig = HPGConfig(),
               rules_: core.TaxiRules = None):
    """Args:
      seed: the integer seed of the `learners.rng` generator.
      config: the hyper-parameters (`HPGConfig`).
      rules_: the taxi task (`taxi_core.TaxiRules`; SPEC taxi-fuel if None).
    """
    if not isinstance(config, HPGConfig):
      raise ValueError(f"TaxiHPG: config must be an HPGConfig, got {type(config).__name__}")
    self.task = rules_ if rules_ is not None else core.TaxiRules()
    self.world = rules.world_config(self.task)
    self.config = config
    self.rng_state = rng.make_state(seed)
    self.traces = new_traces(self.task.fuel_enabled, self.task.capacity, config.initial)
    self.primitive_steps = 0   # steps of learning so far

  def run(self, n_episodes: int, learn: bool = True, greedy: bool = False, fixed_start=None):
    """`n_episodes` episodes; returns the (n_episodes, N_RECORD) record.

    learn=True trains; learn=False evaluates the current policies, sampling
    from them or, with greedy=True, taking each subtask's most probable child.
    """
    if not isinstance(n_episodes, (int, np.integer)) or n_episodes < 0:
      raise ValueError(f"TaxiHPG.run: n_episodes must be an integer >= 0, got {n_episodes!r}")
    if learn and greedy:
      raise ValueError("TaxiHPG.run: greedy=True evaluates without learning; pass learn=False")
    start = np.zeros(0, dtype=np.int64)
    if fixed_start is not None:
      start = np.array(self.task.check_state(fixed_start), dtype=np.int64)
    record = np.zeros((int(n_episodes), N_RECORD))
    steps = train(int(n_episodes), bool(learn), bool(greedy), self.rng_state, self.world,
                  *self.traces, self.config.alphas(), self.config.gammas(), record, start)
    if learn:
      self.primitive_steps += int(steps)
    return record

  def policy_tables(self):
    """Each subtask's current parameters, an (abstract states, children) table."""
    return tuple(policy_table(t, rules.N_CHILDREN[i]) for i, t in enumerate(self.traces))
