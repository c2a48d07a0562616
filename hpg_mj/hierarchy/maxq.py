"""MAXQ-Q (Dietterich 2000) on taxi-fuel, over the task graph of `taxi_rules`.

Each subtask i keeps two completion functions over its abstract state and
children: C~(i, s, a), learned with i's pseudo-reward, which picks i's children,
and C(i, s, a) without it, which gives i's value to its parent. Primitive
actions keep V(a, s). Values are evaluated recursively (MAXQ's decomposition):

    V(i, s) = V(a*, s) + C(i, s, a*),  a* = argmax_a [V(a, s) + C~(i, s, a)]
    V(i, s) = 0 when i has terminated in s, or the episode has ended.

When child a of i, chosen in s, returns in s':
    C~(i, s, a) <- (1 - alpha_i) C~(i, s, a) + alpha_i [C~(i, s', a') + V(a', s')]
    C(i, s, a)  <- (1 - alpha_i) C(i, s, a)  + alpha_i [C(i, s', a') + V(a', s')]
with a' = argmax_a' [V(a', s') + C~(i, s', a')]; the targets are i's
pseudo-reward and 0 when i terminated in s', and 0 when the episode ended
(delivery, empty tank); a 200-step truncation bootstraps. A primitive a learns
V(a, s) <- (1 - alpha) V(a, s) + alpha r.

All-states updating (Dietterich's enhancement of MAXQ-Q): a child run from s
visits s = s_1, ..., s_k before it returns in s'; started in any s_j it would
have ended in the same s', so C(i, s_j, a) gets the same target for every j.
It multiplies the experience of the upper subtasks by the length of their
children's runs ([primitive] all_states_updating).

Exploration is epsilon-greedy in every subtask, each level's epsilon decaying
linearly to 0, bottom-up (see `Config`); greedy choices break ties at
random; Root's completions start optimistic.

State abstraction (MAXQ's, chosen so that every abstraction is safe: a
subtask's values and completions are exact functions of its abstract state, so
MAXQ-Q can converge to the recursively optimal values; `exact_values` computes
them, and raises if an abstraction were not safe):

- V(a, s) sees the classic state and whether the tank is empty: a primitive's
  reward depends on the fuel only through -20 on an empty tank.
- Navigate(t) sees (t, row, col, fuel): 5 * 25 * 13 states.
- Get sees (row, col, passenger station, fuel), Put (row, col, destination,
  fuel), Refuel (row, col, fuel).
- Root sees the full state (6,500 with fuel, 500 without).

Fuel appears in every subtask's view, unlike HPG's policies (`taxi_rules`): an
empty tank ends the episode inside any subtask, with -20, and a fuel-blind
V(Get, s) would hide that from Root. Root sees the destination while the
passenger waits: C(Root, s, Get) is the value of the ride that follows, which
depends on it. With these the recursively optimal policy is optimal: its
V(Root, s) is V*(s) on every start, 6.14458 on average with fuel, 7.93 without.
With the defaults (those of tasks/taxi_fuel_maxq.toml), the last 1,000 of 100,000
training episodes average 97.8% of 6.14458 (seeds 0-4: 97.8, 98.3, 99.5, 97.0,
96.5%), and the trailing 1,000-episode mean first reaches 95% after about 0.21
million primitive steps (seeds 0-9).

One implementation: the fused loop (`train`) and the per-subtask learners of
`hpg_mj.agents.taxi_maxq` (the task-graph path) call the same compiled
rules - `choose`, `update_primitive`, `update_completion` - on the same arrays.
Randomness (`learners.rng`): per episode the start (`taxi_subtasks.sample_start`),
then per choice of any subtask, when sampling (training), one uniform (explore or not),
and one randint when it explores or when the best children tie.

Speed and the first compile (about 5 million primitive steps per second learning,
`hpg-mj bench train`; about 8 s to compile `train` into an empty numba cache): as
in `taxi_hpg`, the graph's fixed depth gives one function per level
(`run_navigate`, `run_carry`, `run_episode`; `navigate_value`, `carry_value`,
`root_scores` for the recursive values), compiled without reference counting
(`_nrt=False`) and allocating nothing: the scratch arrays come from the caller.
The rules (`choose`, `update_completion`, `scores`, ...) are called functions,
the fused loop and the step-by-step nodes calling the same ones; only leaves
without branches over subtasks (`greedy`, `with_fuel`, `update_primitive`, ...)
are inlined. numba inlines a function by copying and re-typing its body at every
call site, nested copies included: with `choose` and `update_completion`
inlined into Navigate's loop and the values into Root's, the loop ran 1.6 times
faster (8 million steps per second) but its first compile took 12 s rather
than 8, and Figure 6 spends only a few seconds in MAXQ-Q. Functions that only
compiled code calls have no Python entry point (`no_cpython_wrapper`), which
numba would otherwise compile for each. The first `run` in a process compiles the
rules leaves first, then `train` (`learners.jit`: from the command line, 1.5 s less
of system time on Python 3.11).

This module is MAXQ-Q's engine: its tables, rules, fused loop and exact values.
The agent (`hpg_mj.agents.taxi_maxq`, a baseline of HPG, tag "baseline") holds its
configuration, its step-by-step nodes and its metrics.

Why MAXQ-Q has its own engine and does not run on the task-graph machine
(`hierarchy.program`): it is a different algorithm, value decomposition. A
subtask's choice needs its children's values V(a, s), computed recursively through
the whole graph below it (`scores`), and a returning child updates its parent's
two completion functions over every state of the child's run (all-states
updating, `path`); the machine's learners choose and learn from their own
state and the reward of their child's run only.
"""

import collections

import numba
import numpy as np

from hpg_mj.hierarchy import taxi_subtasks as rules
from hpg_mj.learners import jit
from hpg_mj.learners import rng
from hpg_mj.learners import schedules
from hpg_mj.worlds import taxi_core as core
from hpg_mj.worlds import taxi_rules as world_rules

# Per-episode record columns, as taxi_flat_q's.
RETURN, STEPS, OUTCOME = 0, 1, 2
N_RECORD = 3
N_PRIMITIVES = core.NUM_ACTIONS_FUEL      # V(a, s) columns (the classic taxi leaves Fillup 0)

# Levels of the graph, for scratch rows and per-level settings: Navigate 0,
# Get/Put/Refuel 1, Root 2.
LEVEL = (2, 1, 1, 1, 0)                   # by subtask id
N_LEVELS = 3

# Rows of the per-subtask settings array (`settings`).
P_ALPHA, P_PSEUDO_REWARD, P_EPSILON_START, P_EPSILON_END, P_EPSILON_EPISODES = range(5)




LEVELS = ("root", "carry", "navigate")

NO_TARGET = np.int64(0)


def settings(config) -> np.ndarray:
  """float64[5, 5]: rows P_* by subtask id (Root, Get, Put, Refuel, Navigate), from the
  task file's [root], [carry] and [navigate] (Root has no pseudo-reward)."""
  def by_subtask(key):
    root, carry, navigate = (float(getattr(getattr(config, level), key, 0.0))
                             for level in LEVELS)
    return [root, carry, carry, carry, navigate]
  return np.array([by_subtask("alpha"), by_subtask("pseudo_reward"), by_subtask("epsilon"),
                   [0.0] * 5, by_subtask("epsilon_episodes")], dtype=np.float64)


def table_sizes(fuel_enabled: bool = True, capacity: int = core.FUEL_CAPACITY):
  """Rows (abstract states) of each subtask's completion tables, by subtask id."""
  levels = capacity + 1 if fuel_enabled else 1
  classic = rules.n_abstract_states(False)
  return (core.num_states(fuel_enabled, capacity),) + tuple(n * levels for n in classic[1:])


def table_offsets(fuel_enabled: bool = True, capacity: int = core.FUEL_CAPACITY):
  """int64[6]: subtask i's completions are entries offsets[i]:offsets[i + 1] of the
  flat C~ and C arrays, row-major over (abstract state, child)."""
  sizes = table_sizes(fuel_enabled, capacity)
  return np.concatenate([[0], np.cumsum([sizes[i] * rules.N_CHILDREN[i]
                                         for i in range(rules.N_SUBTASKS)])]).astype(np.int64)


Tables = collections.namedtuple("Tables", ("values", "c_tilde", "c", "offsets"))
Tables.__doc__ = """MAXQ-Q's tables as the compiled functions take them: V(a, s) of the
primitives, the completions C~ and C of every subtask (flat), and each subtask's
offset in them."""


def new_tables(fuel_enabled: bool = True, capacity: int = core.FUEL_CAPACITY):
  """(V, C~, C, offsets): V(a, s) float64[states * 7]; C~ and C flat over the subtasks."""
  offsets = table_offsets(fuel_enabled, capacity)
  return (np.zeros(n_primitive_states(fuel_enabled) * N_PRIMITIVES),
          np.zeros(offsets[-1]), np.zeros(offsets[-1]), offsets)


def completion_table(flat, offsets, subtask):
  """Subtask i's part of a flat C~ or C array as an (abstract states, children) view."""
  return flat[offsets[subtask]:offsets[subtask + 1]].reshape(-1, rules.N_CHILDREN[subtask])


def new_scratch():
  """The scratch arrays the compiled functions write in (nothing there allocates):
  q, v float64[levels, children], mask bool[levels, children]."""
  return (np.zeros((N_LEVELS, rules.MAX_CHILDREN)), np.zeros((N_LEVELS, rules.MAX_CHILDREN)),
          np.zeros((N_LEVELS, rules.MAX_CHILDREN), dtype=np.bool_))


# --- abstraction, initiation, termination ------------------------------------------

@numba.njit(cache=True, inline="always")
def full_state(state, world):
  """The full state's index (`taxi_core.encode_state`): Root's rows."""
  return core.encode_state(state[world_rules.ROW], state[world_rules.COL], state[world_rules.PASSENGER],
                           state[world_rules.DESTINATION], state[world_rules.FUEL],
                           world[world_rules.W_FUEL_ENABLED] != 0)


def n_primitive_states(fuel_enabled: bool = True):
  """Rows of V(a, s): the classic state, and with fuel whether the tank is empty."""
  return core.NUM_CLASSIC_STATES * (2 if fuel_enabled else 1)


@numba.njit(cache=True, inline="always")
def primitive_state(state, world):
  """The primitives' abstract state, V(a, s)'s row: a primitive's reward depends on
  the fuel only through an empty tank (-20), so the level itself is left out
  (Dietterich's leaf irrelevance)."""
  s = core.encode_state(state[world_rules.ROW], state[world_rules.COL], state[world_rules.PASSENGER],
                        state[world_rules.DESTINATION], 0, False)
  if world[world_rules.W_FUEL_ENABLED] != 0:
    return s * 2 + (state[world_rules.FUEL] == 0)
  return s


@numba.njit(cache=True, inline="always")
def with_fuel(row, state, world):
  """`taxi_rules`' abstract row with the fuel level added (module docstring)."""
  if world[world_rules.W_FUEL_ENABLED] != 0:
    return row * (world[world_rules.W_CAPACITY] + 1) + state[world_rules.FUEL]
  return row


@numba.njit(cache=True, _nrt=False)
def abstract_state(subtask, target, state, world):
  """The subtask's row in its completion tables (module docstring): `taxi_rules`'
  abstraction with the fuel level added, and the full state for Root."""
  if subtask == rules.ROOT:
    return full_state(state, world)
  if subtask == rules.NAVIGATE:
    return with_fuel(rules.navigate_state(target, state), state, world)
  return with_fuel(rules.carry_state(subtask, state), state, world)


@numba.njit(cache=True, _nrt=False)
def terminated(subtask, target, state, world):
  """Has the subtask terminated in `state` (MAXQ's termination, `taxi_rules`)?"""
  if subtask == rules.NAVIGATE:
    return rules.navigate_done(target, state, world)
  if subtask == rules.ROOT:
    return False
  return rules.carry_done(subtask, state, world)


@numba.njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def available(subtask, state, world, mask):
  """The children available in `state` (`taxi_rules`' initiation) into mask[:n]."""
  if subtask == rules.ROOT:
    rules.root_children(state, world, mask)
  elif subtask == rules.NAVIGATE:
    rules.navigate_children(mask)
  else:
    rules.carry_children(subtask, state, world, mask)


@numba.njit(cache=True, inline="always")
def episode_ended(episode):
  """A delivery or an empty tank ends the episode; a truncation does not (SPEC 5)."""
  o = episode[world_rules.E_OUTCOME]
  return o == world_rules.DELIVERED or o == world_rules.OUT_OF_FUEL


@numba.njit(cache=True, inline="always")
def greedy(q, mask, n):
  """The first best available index of q[:n] (the values' a*: any tie gives the same value)."""
  best = -np.inf
  first = -1
  for a in range(n):
    if mask[a] and q[a] > best:
      best = q[a]
      first = a
  return first


@numba.njit(cache=True, inline="always")
def greedy_random_ties(q, mask, n, rng_state):
  """The best available index of q[:n], one of the ties at random (one randint,
  only when there is a tie)."""
  first = greedy(q, mask, n)
  ties = 0
  for a in range(first, n):
    ties += mask[a] and q[a] == q[first]
  if ties < 2:
    return first
  pick = rng.randint(rng_state, ties)
  for a in range(first, n):
    if mask[a] and q[a] == q[first]:
      if pick == 0:
        return a
      pick -= 1
  return first


# --- values: one function per level (the graph's depth is fixed) --------------------
# `*_scores` fill, for every available child a of the subtask in `state`, the
# level's scratch rows: v = V(a, s) and q = V(a, s) + C~(i, s, a). They return
# the subtask's row offset in the flat tables.

@numba.njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def navigate_scores(target, state, world, tables, scratch):
  """Navigate(target)'s scores of its children in `state` into the scratch rows
  (v = V(a, s), q = V(a, s) + C~); returns its row offset in the flat tables."""
  values = tables.values
  c_tilde = tables.c_tilde
  offsets = tables.offsets
  q, v, mask = scratch
  n = rules.N_CHILDREN[rules.NAVIGATE]
  lv = LEVEL[rules.NAVIGATE]
  rules.navigate_children(mask[lv])
  s = primitive_state(state, world) * N_PRIMITIVES
  base = offsets[rules.NAVIGATE] + with_fuel(rules.navigate_state(target, state), state, world) * n
  for a in range(n):
    v[lv, a] = values[s + a]                   # Navigate's child index is the move's action
    q[lv, a] = v[lv, a] + c_tilde[base + a]
  return base


@numba.njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def navigate_value(target, state, world, tables, scratch):
  """V(Navigate(t), s)."""
  c = tables.c
  q, v, mask = scratch
  if rules.navigate_done(target, state, world):
    return 0.0
  lv = LEVEL[rules.NAVIGATE]
  base = navigate_scores(target, state, world, tables, scratch)
  a = greedy(q[lv], mask[lv], rules.N_CHILDREN[rules.NAVIGATE])
  return v[lv, a] + c[base + a]


@numba.njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def carry_scores(subtask, state, world, tables, scratch):
  """Get's, Put's or Refuel's scores of its children in `state` into the scratch rows
  (v = V(a, s), q = V(a, s) + C~); returns its row offset in the flat tables."""
  values = tables.values
  c_tilde = tables.c_tilde
  offsets = tables.offsets
  q, v, mask = scratch
  n = rules.N_CHILDREN[subtask]
  lv = LEVEL[subtask]
  rules.carry_children(subtask, state, world, mask[lv])
  base = offsets[subtask] + with_fuel(rules.carry_state(subtask, state), state, world) * n
  for a in range(n):
    if mask[lv, a]:
      if a == rules.CARRY_PRIMITIVE:
        v[lv, a] = values[primitive_state(state, world) * N_PRIMITIVES
                          + rules.carry_primitive(subtask)]
      else:
        v[lv, a] = navigate_value(rules.carry_target(subtask, state), state, world, tables, scratch)
      q[lv, a] = v[lv, a] + c_tilde[base + a]
  return base


@numba.njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def carry_value(subtask, state, world, tables, scratch):
  """V(Get / Put / Refuel, s)."""
  c = tables.c
  q, v, mask = scratch
  if rules.carry_done(subtask, state, world):
    return 0.0
  lv = LEVEL[subtask]
  base = carry_scores(subtask, state, world, tables, scratch)
  a = greedy(q[lv], mask[lv], rules.N_CHILDREN[subtask])
  return v[lv, a] + c[base + a]


@numba.njit(cache=True, _nrt=False)
def root_scores(state, world, tables, scratch):
  """Root's scores of its children in `state` into the scratch rows (v = V(a, s),
  q = V(a, s) + C~); returns its row offset in the flat tables."""
  c_tilde = tables.c_tilde
  offsets = tables.offsets
  q, v, mask = scratch
  n = rules.N_CHILDREN[rules.ROOT]
  lv = LEVEL[rules.ROOT]
  rules.root_children(state, world, mask[lv])
  base = offsets[rules.ROOT] + full_state(state, world) * n
  for a in range(n):
    if mask[lv, a]:
      v[lv, a] = carry_value(a + 1, state, world, tables, scratch)
      q[lv, a] = v[lv, a] + c_tilde[base + a]
  return base


@numba.njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def scores(subtask, target, state, world, tables, scratch):
  """The subtask's scores in its level's scratch rows; returns its row offset."""
  if subtask == rules.NAVIGATE:
    return navigate_scores(target, state, world, tables, scratch)
  if subtask == rules.ROOT:
    return root_scores(state, world, tables, scratch)
  return carry_scores(subtask, state, world, tables, scratch)


# --- the rules the two paths share ----------------------------------------------------

@numba.njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def explore(subtask, state, world, mask, rng_state):
  """A uniformly random available child (one randint)."""
  n = rules.N_CHILDREN[subtask]
  available(subtask, state, world, mask)
  k = 0
  for a in range(n):
    k += mask[a]
  pick = rng.randint(rng_state, k)
  for a in range(n):
    if mask[a]:
      if pick == 0:
        return a
      pick -= 1
  return -1


@numba.njit(cache=True, _nrt=False)
def choose(subtask, target, state, world, tables, epsilon, sample, rng_state, scratch):
  """Epsilon-greedy choice of a child of `subtask` in `state` (greedy if not
  `sample`): one uniform when sampling; a randint to explore or to break a tie."""
  q = scratch[0]
  mask = scratch[2]
  n = rules.N_CHILDREN[subtask]
  lv = LEVEL[subtask]
  if sample and rng.uniform(rng_state) < epsilon:
    return explore(subtask, state, world, mask[lv], rng_state)
  scores(subtask, target, state, world, tables, scratch)
  return greedy_random_ties(q[lv], mask[lv], n, rng_state)


@numba.njit(cache=True, inline="always")
def update_primitive(values, index, reward, alpha):
  """V(a, s) <- (1 - alpha) V(a, s) + alpha r, at index = full state * 7 + a."""
  values[index] = (1.0 - alpha) * values[index] + alpha * reward


@numba.njit(cache=True, _nrt=False)
def update_completion(subtask, target, child, path, first, last, after, ended, world, tables,
                      settings, all_states, scratch):
  """Dietterich's update of C~(i, s, a) and C(i, s, a) after child a of subtask i,
  chosen in s = path[first], returned in `after` (`ended`: the episode ended).
  With `all_states`, every state path[first:last] the child's run visited gets
  the same target (module docstring)."""
  c_tilde = tables.c_tilde
  c = tables.c
  offsets = tables.offsets
  q, v, mask = scratch
  alpha = settings[P_ALPHA, subtask]
  if ended:
    tilde = 0.0
    plain = 0.0
  elif terminated(subtask, target, after, world):
    tilde = settings[P_PSEUDO_REWARD, subtask]
    plain = 0.0
  else:
    lv = LEVEL[subtask]
    base = scores(subtask, target, after, world, tables, scratch)
    a = greedy(q[lv], mask[lv], rules.N_CHILDREN[subtask])
    tilde = c_tilde[base + a] + v[lv, a]
    plain = c[base + a] + v[lv, a]
  n = rules.N_CHILDREN[subtask]
  stop = last if all_states else first + 1
  for j in range(first, stop):
    i = offsets[subtask] + abstract_state(subtask, target, path[j], world) * n + child
    c_tilde[i] = (1.0 - alpha) * c_tilde[i] + alpha * tilde
    c[i] = (1.0 - alpha) * c[i] + alpha * plain




@numba.njit(cache=True, inline="always")
def record_state(path, state, steps):
  """path[steps] <- state: the state a primitive is taken in (all-states updating)."""
  for k in range(5):
    path[steps, k] = state[k]


@numba.njit(cache=True, inline="always")
def epsilons_at(settings, episode_index, epsilons):
  """Each subtask's epsilon for learning episode e: linear from its start to its end."""
  for i in range(epsilons.shape[0]):
    epsilons[i] = schedules.linear(episode_index, settings[P_EPSILON_START, i],
                                   settings[P_EPSILON_END, i], settings[P_EPSILON_EPISODES, i])


# --- the fused loop: Algorithm 1's stack discipline, one function per level -----------

@numba.njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def run_navigate(target, state, episode, world, tables, settings, epsilons, alpha_primitive,
                 all_states, learn, sample, rng_state, path, scratch):
  """One call of Navigate(target); returns the rewards earned."""
  values = tables.values
  total = 0.0
  while not world_rules.episode_over(episode) and not rules.navigate_done(target, state, world):
    a = choose(rules.NAVIGATE, target, state, world, tables,
               epsilons[rules.NAVIGATE], sample, rng_state, scratch)
    first = episode[world_rules.E_STEPS]
    record_state(path, state, first)
    s = primitive_state(state, world)
    reward = world_rules.primitive_step(state, episode, a, world)
    if learn:
      update_primitive(values, s * N_PRIMITIVES + a, reward, alpha_primitive)
      update_completion(rules.NAVIGATE, target, a, path, first, first + 1, state,
                        episode_ended(episode), world, tables, settings,
                        all_states, scratch)
    total += reward
  return total


@numba.njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def run_carry(subtask, state, episode, world, tables, settings, epsilons, alpha_primitive,
              all_states, learn, sample, rng_state, path, scratch):
  """One call of Get, Put or Refuel; returns the rewards earned."""
  values = tables.values
  total = 0.0
  while not world_rules.episode_over(episode) and not rules.carry_done(subtask, state, world):
    a = choose(subtask, NO_TARGET, state, world, tables,
               epsilons[subtask], sample, rng_state, scratch)
    first = episode[world_rules.E_STEPS]
    if a == rules.CARRY_PRIMITIVE:
      action = rules.carry_primitive(subtask)
      record_state(path, state, first)
      s = primitive_state(state, world)
      reward = world_rules.primitive_step(state, episode, action, world)
      if learn:
        update_primitive(values, s * N_PRIMITIVES + action, reward, alpha_primitive)
    else:
      reward = run_navigate(rules.carry_target(subtask, state), state, episode, world, tables, settings, epsilons, alpha_primitive, all_states,
                            learn, sample, rng_state, path, scratch)
    if learn:
      update_completion(subtask, NO_TARGET, a, path, first, episode[world_rules.E_STEPS], state,
                        episode_ended(episode), world, tables, settings,
                        all_states, scratch)
    total += reward
  return total


@numba.njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def run_episode(state, episode, world, tables, settings, epsilons, alpha_primitive, all_states,
                learn, sample, rng_state, path, scratch):
  """One call of Root: the whole episode from `state`; returns its return."""
  total = 0.0
  while not world_rules.episode_over(episode):
    a = choose(rules.ROOT, NO_TARGET, state, world, tables,
               epsilons[rules.ROOT], sample, rng_state, scratch)
    first = episode[world_rules.E_STEPS]
    reward = run_carry(a + 1, state, episode, world, tables, settings,
                       epsilons, alpha_primitive, all_states, learn, sample, rng_state, path, scratch)
    if learn:
      update_completion(rules.ROOT, NO_TARGET, a, path, first, episode[world_rules.E_STEPS], state,
                        episode_ended(episode), world, tables, settings,
                        all_states, scratch)
    total += reward
  return total


@numba.njit(cache=True, _nrt=False)
def train(n_episodes, first_episode, learn, sample, rng_state, world, tables, settings,
          alpha_primitive, all_states, record, scratch_int, path, epsilons, scratch):
  """MAXQ-Q for `n_episodes` from random starts (SPEC section 5): learning
  (`learn`), exploring by each subtask's epsilon (`sample`) or greedy.

  `first_episode` places the episodes on the epsilon schedule; `record`
  (n_episodes, N_RECORD) receives one row per episode. Scratch (nothing here
  allocates): `scratch_int` int64[8], `path` int64[max_steps, 5], `epsilons`
  float64[5], and `new_scratch()`'s q, v, mask. Returns the primitive steps run.
  """
  state = scratch_int[0:5]
  episode = scratch_int[5:8]
  total_steps = 0
  for e in range(n_episodes):
    rules.sample_start(rng_state, world, state)
    for i in range(3):
      episode[i] = 0
    epsilons_at(settings, first_episode + e, epsilons)
    ret = run_episode(state, episode, world, tables, settings, epsilons,
                      alpha_primitive, all_states, learn, sample, rng_state, path, scratch)
    record[e, RETURN] = ret
    record[e, STEPS] = episode[world_rules.E_STEPS]
    record[e, OUTCOME] = episode[world_rules.E_OUTCOME]
    total_steps += episode[world_rules.E_STEPS]
  return total_steps


class MAXQEngine:
  """MAXQ-Q on one taxi task: its tables, its generator, and `run`, which wraps
  the compiled `train`."""

  def __init__(self, config, seed: int = 0, task: core.TaxiRules = None):
    """`config`: the agent's Config (`hpg_mj.agents.taxi_maxq.Config`)."""
    for level in ("root", "carry", "navigate", "primitive"):
      if not hasattr(config, level):
        raise ValueError(f"MAXQEngine: config must be a taxi_maxq.Config (with [{level}]), "
                         f"got {type(config).__name__}")
    self.task = task if task is not None else core.TaxiRules()
    self.world = world_rules.world_config(self.task)
    self.config = config
    self.settings = settings(config)
    self.tables = Tables(*new_tables(self.task.fuel_enabled, self.task.capacity))
    self.values, self.c_tilde, self.c, self.offsets = self.tables
    for i, level in enumerate(("root", "carry", "carry", "carry", "navigate")):
      initial = getattr(config, level).initial
      completion_table(self.c_tilde, self.offsets, i)[:] = initial
      completion_table(self.c, self.offsets, i)[:] = initial
    self.rng_state = rng.make_state(seed)
    self.episodes = 0          # learning episodes so far (they drive the epsilon schedule)
    self.primitive_steps = 0   # primitive steps of learning so far

  def run(self, n_episodes: int, learn: bool = True, sample=None):
    """`n_episodes` episodes from random starts; returns the (n, N_RECORD) record.
    Learning explores (epsilon-greedy); without learning the policy is greedy
    unless `sample`."""
    if not isinstance(n_episodes, (int, np.integer)) or n_episodes < 0:
      raise ValueError(f"MAXQEngine.run: n_episodes must be an integer >= 0, got {n_episodes!r}")
    sample = learn if sample is None else bool(sample or learn)
    record = np.zeros((int(n_episodes), N_RECORD))
    scratch_int, path, epsilons, scratch = self._train_scratch()
    jit.compile_first(train, lambda: self._rules_bottom_up(scratch_int, path, epsilons, scratch))
    steps = train(int(n_episodes), self.episodes, bool(learn), sample, self.rng_state,
                  self.world, self.tables, self.settings,
                  float(self.config.primitive.alpha), bool(self.config.primitive.all_states_updating), record,
                  scratch_int, path, epsilons, scratch)
    if learn:
      self.episodes += int(n_episodes)
      self.primitive_steps += int(steps)
    return record

  def _train_scratch(self):
    """`train`'s scratch arrays: int64[8], the path int64[max_steps, 5], the epsilons
    float64[5], and `new_scratch()`."""
    return (np.zeros(8, dtype=np.int64), np.zeros((self.task.max_steps, 5), dtype=np.int64),
            np.zeros(rules.N_SUBTASKS), new_scratch())

  def _rules_bottom_up(self, scratch_int, path, epsilons, scratch):
    """The rules `train` calls, callees first, with arguments of the types it calls
    them with (`learners.jit.compile_first`)."""
    state, episode = scratch_int[0:5], scratch_int[5:8]
    mask = scratch[2][0]
    level = (self.world, self.tables, scratch)
    i, f, b = NO_TARGET, 0.0, False
    rs = self.rng_state
    return [
        (navigate_scores, (i, state) + level), (navigate_value, (i, state) + level),
        (carry_scores, (i, state) + level), (carry_value, (i, state) + level),
        (root_scores, (state,) + level), (scores, (i, i, state) + level),
        (available, (i, state, self.world, mask)), (explore, (i, state, self.world, mask, rs)),
        (terminated, (i, i, state, self.world)), (abstract_state, (i, i, path[0], self.world)),
        (choose, (i, i, state, self.world, self.tables, f, b, rs, scratch)),
        (update_completion, (i, i, i, path, i, i, state, b, self.world, self.tables,
                             self.settings, b, scratch)),
        (run_navigate, (i, state, episode, self.world, self.tables, self.settings, epsilons, f,
                        b, b, b, rs, path, scratch)),
        (run_carry, (i, state, episode, self.world, self.tables, self.settings, epsilons, f,
                     b, b, b, rs, path, scratch)),
        (run_episode, (state, episode, self.world, self.tables, self.settings, epsilons, f,
                       b, b, b, rs, path, scratch)),
    ]

  def completions(self, subtask: int, pseudo: bool = False):
    """Subtask i's C (or C~ with `pseudo`) as an (abstract states, children) view."""
    return completion_table(self.c_tilde if pseudo else self.c, self.offsets, subtask)


# --- the exact values of the recursively optimal policy ------------------------------

def exact_values(task: core.TaxiRules = None):
  """The values MAXQ-Q converges to, computed exactly on the full state space.

  Bottom-up, each subtask's SMDP is solved by value iteration over the full
  states given its children's exact values V(a, s) and the states their
  (greedy, first-of-ties) runs end in, as in Dietterich's recursive
  optimality: Navigate(t) for each t, then Get, Put and Refuel, then Root.

      V(i, s) = max_a [V(a, s) + C(i, s, a)],   C(i, s, a) = V(i, s'_a)
      V(i, s) = 0 where i has terminated or the episode ended (s'_a = ended)

  (zero pseudo-rewards, so C~ = C). The taxi is deterministic with integer
  rewards, so the iterates are exact integers and stop when one repeats.

  Returns `(c, known, v)`: `c` float64 in the flat layout of the learner's C
  (`table_offsets`), `known` bool marking the entries of states where the
  subtask can run and the child is available (the others are never updated),
  and `v` float64[4 + 5, full states]: V(i, s) of Root, Get, Put and Refuel by
  subtask id, then of Navigate(t) in row 4 + t. Raises ValueError if two full
  states that share an abstract state get different completions: the
  abstraction would not be safe.
  """
  from hpg_mj.worlds import taxi_values
  task = task if task is not None else core.TaxiRules()
  fuel = task.fuel_enabled
  model = taxi_values.taxi_values(fuel, tuple(task.fuel_station), task.capacity)
  world = world_rules.world_config(task)
  n = model.v.shape[0]
  ended = n                                     # the extra index: "the episode ended"
  nxt = np.where(model.terminal, ended, model.next_state)
  states = np.array([core.decode_state(s, fuel) for s in range(n)], dtype=np.int64)
  offsets = table_offsets(fuel, task.capacity)
  c = np.zeros(offsets[-1])
  known = np.zeros(offsets[-1], dtype=np.bool_)
  mask = np.zeros(rules.MAX_CHILDREN, dtype=np.bool_)

  def by_state(fn):
    return np.array([fn(s) for s in states])

  def solve(children_value, children_result, live, done):
    """V(i, .) and the end state of i's greedy run, over the full states (+ ended)."""
    v = np.zeros(n + 1)
    while True:
      q = np.where(live, children_value + v[children_result], -np.inf)
      new = np.where(done, 0.0, q.max(axis=1))
      new = np.append(np.where(np.isfinite(new), new, 0.0), 0.0)
      if np.array_equal(new, v):
        break
      v = new
    best = np.argmax(q, axis=1)                  # the first of the ties, as `greedy`
    result = np.append(np.arange(n), ended)
    step = np.append(children_result[np.arange(n), best], ended)
    for _ in range(n + 1):
      new = np.where(np.append(done, True), result, result[step])
      if np.array_equal(new, result):
        break
      result = new
    return v, result

  def store(subtask, target_of, q_children, live, active):
    """C(i, s, a) = q - V(a, s) into the flat layout, checking the abstraction."""
    k = rules.N_CHILDREN[subtask]
    for s in np.flatnonzero(active):
      row = offsets[subtask] + abstract_state(subtask, target_of(s), states[s], world) * k
      for a in range(k):
        if live[s, a]:
          if known[row + a] and c[row + a] != q_children[s, a]:
            raise ValueError(f"exact_values: subtask {rules.SUBTASK_NAMES[subtask]} sees two "
                             f"completions for one abstract state (at {states[s]})")
          c[row + a] = q_children[s, a]
          known[row + a] = True

  moves = np.arange(4)
  nav_v, nav_result = [], []
  for t in range(rules.N_TARGETS):
    done = by_state(lambda s: rules.navigate_done(t, s, world))
    live = np.ones((n, 4), dtype=np.bool_)
    v, result = solve(model.reward[:, moves], nxt[:, moves], live, done)
    nav_v.append(v)
    nav_result.append(result)
    store(rules.NAVIGATE, lambda s: t, np.where(live, v[nxt[:, moves]], 0.0), live, ~done)
  carry_v, carry_result = {}, {}
  waiting = states[:, world_rules.PASSENGER] != core.IN_TAXI
  reachable = ~waiting | (states[:, world_rules.PASSENGER] != states[:, world_rules.DESTINATION])
  domain = {rules.GET: waiting & reachable, rules.PUT: ~waiting,
            rules.REFUEL: reachable if fuel else np.zeros(n, dtype=np.bool_)}
  for subtask in (rules.GET, rules.PUT, rules.REFUEL):
    prim = rules.carry_primitive(subtask)
    target = by_state(lambda s: rules.carry_target(subtask, s))
    idx = np.arange(n)
    value = np.stack([np.array([nav_v[t][s] for s, t in zip(idx, target)]),
                      model.reward[:, prim] if prim < model.reward.shape[1] else np.zeros(n)], 1)
    result = np.stack([np.array([nav_result[t][s] for s, t in zip(idx, target)]),
                       nxt[:, prim] if prim < nxt.shape[1] else np.full(n, ended)], 1)
    done = by_state(lambda s: rules.carry_done(subtask, s, world)) | ~domain[subtask]

    def live_of(s):
      rules.carry_children(subtask, s, world, mask)
      return mask[:2].copy()
    live = by_state(live_of)
    v, res = solve(value, result, live, done)
    carry_v[subtask], carry_result[subtask] = v, res
    store(subtask, lambda s: 0, np.where(live, v[result], 0.0), live, ~done)
  value = np.stack([carry_v[i][:n] for i in (rules.GET, rules.PUT, rules.REFUEL)], 1)
  result = np.stack([carry_result[i][:n] for i in (rules.GET, rules.PUT, rules.REFUEL)], 1)

  def root_live(s):
    rules.root_children(s, world, mask)
    return mask[:3].copy()
  live = by_state(root_live)
  v, _ = solve(value, result, live, ~reachable)
  store(rules.ROOT, lambda s: 0, np.where(live, v[result], 0.0), live, reachable)
  rows = [v] + [carry_v[i] for i in (rules.GET, rules.PUT, rules.REFUEL)] + nav_v
  return c, known, np.stack(rows)[:, :n]
