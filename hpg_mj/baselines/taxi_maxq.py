"""MAXQ-Q (Dietterich 2000) on taxi-fuel, over the task graph of `taxi_rules`.

Each subtask i keeps completion functions over its abstract state and children:
C~(i, s, a), learned with i's pseudo-reward, which picks i's actions, and C(i, s, a)
without it, which gives i's value to its parent. Primitive actions keep
V(a, s) over the full state. Values are evaluated recursively:

    V(i, s) = V(a*, s) + C(i, s, a*),  a* = argmax_a [V(a, s) + C~(i, s, a)]
    V(i, s) = 0 when i has terminated in s, or the episode has ended.

When child a of i returns in s' (Dietterich's update, on the state where a was
chosen):
    C~(i, s, a) <- (1 - alpha) C~ + alpha [C~(i, s', a') + V(a', s')]   a' = argmax in s'
    C(i, s, a)  <- (1 - alpha) C  + alpha [C(i, s', a') + V(a', s')]
with the targets pseudo_reward(i) and 0 when i terminated in s', and 0 when the
episode ended (delivery, empty tank); a 200-step truncation bootstraps.
Primitive values: V(a, s) <- (1 - alpha) V(a, s) + alpha r. Exploration is
epsilon-greedy in every subtask, epsilon decaying linearly.

All rules are numba functions over plain arrays, used by the fused loop
(`train`). Work in progress (issue 4): the step-by-step learner objects on the
task-graph API, the task file, and the fuel task's level (about 73% of the
optimal mean return after 100,000 episodes; the classic taxi reaches its optimum).
The functions are not cached: numba's cache cannot resolve these mutually
referring functions.
"""
import numba
import numpy as np

from hpg_mj.hierarchy import taxi_compiled
from hpg_mj.hierarchy import taxi_rules as rules
from hpg_mj.learners import rng
from hpg_mj.worlds import taxi_core as core

RETURN, STEPS, OUTCOME = 0, 1, 2
N_RECORD = 3
N_PRIMITIVES = core.NUM_ACTIONS_FUEL


@numba.njit
def _full(state, world):
  return core.encode_state(state[0], state[1], state[2], state[3], state[4],
                           world[rules.W_FUEL_ENABLED] != 0)


@numba.njit
def v_primitive(vp, action, state, world):
  return vp[_full(state, world) * N_PRIMITIVES + action]


@numba.njit
def _abstract(node, target, state, world):
  """The subtask's abstract state: taxi_rules' abstraction, with the fuel added below
  Root. MAXQ's values must be safe to abstract: an empty tank ends the episode
  inside Get or Navigate, and a fuel-blind V(Get, s) would hide that from Root."""
  if node == rules.ROOT:
    return rules.root_state(state, world)
  levels = world[rules.W_CAPACITY] + 1 if world[rules.W_FUEL_ENABLED] != 0 else 1
  fuel = state[rules.FUEL] if world[rules.W_FUEL_ENABLED] != 0 else 0
  if node == rules.NAVIGATE:
    return rules.navigate_state(target, state) * levels + fuel
  return rules.carry_state(node, state) * levels + fuel


def table_sizes(fuel_enabled=True, capacity=core.FUEL_CAPACITY):
  """Rows of each subtask's completion tables, by subtask id."""
  sizes = rules.n_abstract_states(fuel_enabled, capacity)
  levels = capacity + 1 if fuel_enabled else 1
  return (sizes[0],) + tuple(n * levels for n in sizes[1:])


@numba.njit
def _done(node, target, state, world):
  if node == rules.NAVIGATE:
    return rules.navigate_done(target, state, world)
  if node == rules.ROOT:
    return False
  return rules.carry_done(node, state, world)


@numba.njit
def _mask(node, state, world, mask):
  if node == rules.ROOT:
    rules.root_children(state, world, mask)
  elif node == rules.NAVIGATE:
    rules.navigate_children(mask)
  else:
    rules.carry_children(node, state, world, mask)


@numba.njit
def _argmax(q, mask, n, rng_state, ties_random):
  """The best available index of q[:n] (uniformly random among ties if asked)."""
  best = -np.inf
  ties = 0
  for a in range(n):
    if mask[a]:
      if q[a] > best:
        best = q[a]
        ties = 1
      elif q[a] == best:
        ties += 1
  pick = rng.randint(rng_state, ties) if (ties_random and ties > 1) else 0
  for a in range(n):
    if mask[a] and q[a] == best:
      if pick == 0:
        return a
      pick -= 1
  return -1


# The graph has a fixed depth, so values are evaluated level by level (numba
# handles neither mutual recursion nor its caching): Navigate's children are
# primitives, Get/Put/Refuel's are Navigate and a primitive, Root's are those three.

@numba.njit
def _scores(node, target, state, world, vp, ct, c, q, v, mask):
  """For every available child a: v[a] = V(a, s) and q[a] = V(a, s) + C~(i, s, a)."""
  n = rules.N_CHILDREN[node]
  _mask(node, state, world, mask)
  base = _abstract(node, target, state, world) * n
  for a in range(n):
    if not mask[a]:
      continue
    if node == rules.NAVIGATE:
      v[a] = v_primitive(vp, a, state, world)
    elif node == rules.ROOT:
      v[a] = carry_value(a + 1, state, world, vp, ct, c)
    elif a == rules.CARRY_PRIMITIVE:
      v[a] = v_primitive(vp, rules.carry_primitive(node), state, world)
    else:
      v[a] = navigate_value(rules.carry_target(node, state), state, world, vp, ct, c)
    q[a] = v[a] + ct[node][base + a]
  return base


@numba.njit
def navigate_value(target, state, world, vp, ct, c):
  """V(Navigate(t), s)."""
  if rules.navigate_done(target, state, world):
    return 0.0
  q = np.empty(rules.MAX_CHILDREN)
  v = np.empty(rules.MAX_CHILDREN)
  mask = np.zeros(rules.MAX_CHILDREN, dtype=np.bool_)
  base = _scores(rules.NAVIGATE, target, state, world, vp, ct, c, q, v, mask)
  a = _argmax(q, mask, rules.N_CHILDREN[rules.NAVIGATE], np.zeros(4, dtype=np.uint64), False)
  return v[a] + c[rules.NAVIGATE][base + a]
@numba.njit
def carry_value(node, state, world, vp, ct, c):
  """V(Get / Put / Refuel, s)."""
  if rules.carry_done(node, state, world):
    return 0.0
  q = np.empty(rules.MAX_CHILDREN)
  v = np.empty(rules.MAX_CHILDREN)
  mask = np.zeros(rules.MAX_CHILDREN, dtype=np.bool_)
  n = rules.N_CHILDREN[node]
  _mask(node, state, world, mask)
  base = _abstract(node, 0, state, world) * n
  for a in range(n):
    if mask[a]:
      if a == rules.CARRY_PRIMITIVE:
        v[a] = v_primitive(vp, rules.carry_primitive(node), state, world)
      else:
        v[a] = navigate_value(rules.carry_target(node, state), state, world, vp, ct, c)
      q[a] = v[a] + ct[node][base + a]
  a = _argmax(q, mask, n, np.zeros(4, dtype=np.uint64), False)
  return v[a] + c[node][base + a]


@numba.njit
def best_child(node, target, state, world, vp, ct, c, rng_state, ties_random):
  """argmax_a [V(a, s) + C~(i, s, a)] over the available children; also V(a, s)."""
  q = np.empty(rules.MAX_CHILDREN)
  v = np.empty(rules.MAX_CHILDREN)
  mask = np.zeros(rules.MAX_CHILDREN, dtype=np.bool_)
  base = _scores(node, target, state, world, vp, ct, c, q, v, mask)
  a = _argmax(q, mask, rules.N_CHILDREN[node], rng_state, ties_random)
  return a, v[a], base


@numba.njit
def choose(node, target, state, world, vp, ct, c, epsilon, rng_state):
  """Epsilon-greedy choice of a child of `node`."""
  if rng.uniform(rng_state) < epsilon:
    mask = np.zeros(rules.MAX_CHILDREN, dtype=np.bool_)
    _mask(node, state, world, mask)
    k = 0
    for a in range(rules.N_CHILDREN[node]):
      k += mask[a]
    pick = rng.randint(rng_state, k)
    for a in range(rules.N_CHILDREN[node]):
      if mask[a]:
        if pick == 0:
          return a
        pick -= 1
  return best_child(node, target, state, world, vp, ct, c, rng_state, True)[0]


@numba.njit
def update_primitive(vp, action, before, reward, alpha, world):
  i = _full(before, world) * N_PRIMITIVES + action
  vp[i] = (1.0 - alpha) * vp[i] + alpha * reward


@numba.njit
def update_completion(node, target, before, child, after, episode_ended, world, vp, ct, c,
                      alpha, pseudo_reward):
  """Dietterich's completion update after `child` of `node` returned in `after`."""
  n = rules.N_CHILDREN[node]
  i = _abstract(node, target, before, world) * n + child
  if episode_ended:
    tilde = 0.0
    plain = 0.0
  elif _done(node, target, after, world):
    tilde = pseudo_reward[node]
    plain = 0.0
  else:
    a, value, base = best_child(node, target, after, world, vp, ct, c,
                                np.zeros(4, dtype=np.uint64), False)
    tilde = ct[node][base + a] + value
    plain = c[node][base + a] + value
  ct[node][i] = (1.0 - alpha) * ct[node][i] + alpha * tilde
  c[node][i] = (1.0 - alpha) * c[node][i] + alpha * plain


@numba.njit
def _ended(episode):
  o = episode[rules.E_OUTCOME]
  return o == rules.DELIVERED or o == rules.OUT_OF_FUEL


def _make_level(level, child_call):
  """One level of Algorithm 1's stack discipline as its own compiled function
  (2 Root, 1 Get/Put/Refuel, 0 Navigate): numba does not compile recursion
  through these arguments, and the graph's depth is fixed."""

  @numba.njit
  def call(node, target, state, episode, world, vp, ct, c, alpha, epsilon, pseudo_reward,
           learn, rng_state):
    total = 0.0
    before = np.empty(5, dtype=np.int64)
    while not rules.episode_over(episode) and not _done(node, target, state, world):
      a = choose(node, target, state, world, vp, ct, c, epsilon, rng_state)
      before[:] = state
      if level == 0 or (level == 1 and a == rules.CARRY_PRIMITIVE):
        action = a if level == 0 else rules.carry_primitive(node)
        reward = rules.primitive_step(state, episode, action, world)
        if learn:
          update_primitive(vp, action, before, reward, alpha, world)
      elif level == 1:
        reward = child_call(rules.NAVIGATE, rules.carry_target(node, state), state, episode,
                            world, vp, ct, c, alpha, epsilon, pseudo_reward, learn, rng_state)
      else:
        reward = child_call(a + 1, 0, state, episode, world, vp, ct, c, alpha, epsilon,
                            pseudo_reward, learn, rng_state)
      if learn:
        update_completion(node, target, before, a, state, _ended(episode), world, vp, ct, c,
                          alpha, pseudo_reward)
      total += reward
    return total

  return call


@numba.njit
def _no_child(node, target, state, episode, world, vp, ct, c, alpha, epsilon, pseudo_reward,
              learn, rng_state):
  return 0.0


_navigate = _make_level(0, _no_child)
_carry = _make_level(1, _navigate)
_root = _make_level(2, _carry)


@numba.njit
def train(n_episodes, first_episode, learn, sample, rng_state, world, vp, ct, c, alpha,
          epsilon_start, epsilon_end, epsilon_episodes, pseudo_reward, record):
  """MAXQ-Q for `n_episodes`; `first_episode` places them on the epsilon schedule."""
  state = np.empty(5, dtype=np.int64)
  episode = np.zeros(3, dtype=np.int64)
  for e in range(n_episodes):
    taxi_compiled.sample_start(rng_state, world, state)
    episode[:] = 0
    epsilon = 0.0
    if sample:
      k = first_episode + e
      epsilon = epsilon_end if k >= epsilon_episodes else (
          epsilon_start + (epsilon_end - epsilon_start) * k / epsilon_episodes)
    record[e, RETURN] = _root(rules.ROOT, 0, state, episode, world, vp, ct, c, alpha, epsilon,
                              pseudo_reward, learn, rng_state)
    record[e, STEPS] = episode[rules.E_STEPS]
    record[e, OUTCOME] = episode[rules.E_OUTCOME]
