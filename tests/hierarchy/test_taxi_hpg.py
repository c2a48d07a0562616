"""The taxi task graph (hpg_mj.hierarchy.taxi_rules) on hand-built states, and
HPG's compiled loop (hpg_mj.hierarchy.taxi_compiled): exact returns of a
hand-set optimal policy, determinism under a seed, and (slow) learning to 95%
of the optimal mean return."""
import collections
import functools

import numpy as np
import pytest

from hpg_mj.hierarchy import taxi_compiled as tcp
from hpg_mj.hierarchy import taxi_rules as tr
from hpg_mj.learners import rng
from hpg_mj.worlds import taxi_core as tc
from hpg_mj.worlds import taxi_values as tv

R, G, Y, B = 0, 1, 2, 3
AT = {R: (0, 0), G: (0, 4), Y: (4, 0), B: (4, 3), tr.TARGET_F: (2, 1)}
IN_TAXI = tc.IN_TAXI
WORLD = tr.world_config()
CLASSIC_WORLD = tr.world_config(tc.TaxiRules(False))


def state(row, col, passenger, destination, fuel):
  return np.array([row, col, passenger, destination, fuel], dtype=np.int64)


def mask_of(fill, *args):
  mask = np.zeros(tr.MAX_CHILDREN, dtype=np.bool_)
  fill(*args, mask)
  return mask


@functools.lru_cache(maxsize=None)
def moves_from(start):
  """Shortest number of moves from `start` to every square (breadth-first)."""
  dist = {start: 0}
  queue = collections.deque([start])
  while queue:
    square = queue.popleft()
    for action in (tc.SOUTH, tc.NORTH, tc.EAST, tc.WEST):
      nxt = tuple(int(v) for v in tc.taxi_step(*square, 0, 1, 12, action, False)[:2])
      if nxt not in dist:
        dist[nxt] = dist[square] + 1
        queue.append(nxt)
  return dist


# --- abstract states ------------------------------------------------------------

def test_abstract_states_of_hand_built_states():
  waiting = state(2, 3, G, Y, 7)
  aboard = state(2, 3, IN_TAXI, Y, 7)
  square = 2 * 5 + 3
  assert tr.root_state(waiting, WORLD) == (square * 4 + G) * 13 + 7
  assert tr.root_state(aboard, WORLD) == ((25 + square) * 4 + Y) * 13 + 7
  # While the passenger waits Root does not see the destination; fuel it does.
  assert tr.root_state(state(2, 3, G, B, 7), WORLD) == tr.root_state(waiting, WORLD)
  assert tr.root_state(state(2, 3, G, Y, 8), WORLD) != tr.root_state(waiting, WORLD)
  # The classic task has no fuel to see.
  assert tr.root_state(state(2, 3, G, Y, 12), CLASSIC_WORLD) == square * 4 + G
  assert tr.get_state(waiting) == square * 4 + G
  assert tr.put_state(aboard) == square * 4 + Y
  assert tr.refuel_state(aboard) == square
  assert tr.navigate_state(tr.TARGET_F, aboard) == 4 * 25 + square
  assert tr.carry_state(tr.GET, waiting) == tr.get_state(waiting)
  assert tr.carry_state(tr.PUT, aboard) == tr.put_state(aboard)
  assert tr.carry_state(tr.REFUEL, aboard) == tr.refuel_state(aboard)


def test_abstract_states_fill_their_tables():
  sizes = tr.n_abstract_states()
  assert sizes == (2600, 100, 100, 25, 125)
  assert tr.n_abstract_states(False) == (200, 100, 100, 25, 125)
  seen = collections.defaultdict(set)
  for s in range(tc.NUM_FUEL_STATES):
    row, col, passenger, destination, fuel = tc.decode_state(s)
    if passenger == destination:
      continue   # delivered: no subtask runs there
    x = state(row, col, passenger, destination, fuel)
    seen[tr.ROOT].add(tr.root_state(x, WORLD))
    if passenger < IN_TAXI:
      seen[tr.GET].add(tr.get_state(x))
    else:
      seen[tr.PUT].add(tr.put_state(x))
    seen[tr.REFUEL].add(tr.refuel_state(x))
    for t in range(tr.N_TARGETS):
      seen[tr.NAVIGATE].add(tr.navigate_state(t, x))
  for subtask, size in enumerate(sizes):
    assert seen[subtask] == set(range(size)), tr.SUBTASK_NAMES[subtask]


# --- initiation -----------------------------------------------------------------

def test_root_children():
  get, put, refuel = tr.ROOT_GET, tr.ROOT_PUT, tr.ROOT_REFUEL
  waiting = mask_of(tr.root_children, state(0, 2, R, G, 6), WORLD)
  assert list(waiting[:3]) == [True, False, True]
  aboard = mask_of(tr.root_children, state(0, 2, IN_TAXI, G, 6), WORLD)
  assert list(aboard[:3]) == [False, True, True]
  # Refuel is terminated only at F with a full tank; a full tank elsewhere may
  # still need topping up on the way.
  assert not mask_of(tr.root_children, state(2, 1, R, G, 12), WORLD)[refuel]
  assert mask_of(tr.root_children, state(2, 1, R, G, 11), WORLD)[refuel]
  assert mask_of(tr.root_children, state(0, 0, R, G, 12), WORLD)[refuel]
  # No fuel, no Refuel.
  classic = mask_of(tr.root_children, state(2, 1, R, G, 12), CLASSIC_WORLD)
  assert list(classic[:3]) == [True, False, False]
  assert get == 0 and put == 1 and refuel == 2


def test_carry_children_and_targets():
  nav, prim = tr.CARRY_NAVIGATE, tr.CARRY_PRIMITIVE
  at_passenger = state(*AT[Y], Y, B, 8)
  away = state(1, 1, Y, B, 8)
  assert tr.carry_target(tr.GET, away) == Y
  assert tr.carry_target(tr.PUT, state(1, 1, IN_TAXI, B, 8)) == B
  assert tr.carry_target(tr.REFUEL, away) == tr.TARGET_F
  # Navigate(t) is terminated, so not available, when the taxi is at t.
  assert list(mask_of(tr.carry_children, tr.GET, at_passenger, WORLD)[:2]) == [False, True]
  assert list(mask_of(tr.carry_children, tr.GET, away, WORLD)[:2]) == [True, True]
  at_destination = state(*AT[B], IN_TAXI, B, 8)
  assert list(mask_of(tr.carry_children, tr.PUT, at_destination, WORLD)[:2]) == [False, True]
  at_f = state(*AT[tr.TARGET_F], R, G, 3)
  assert list(mask_of(tr.carry_children, tr.REFUEL, at_f, WORLD)[:2]) == [False, True]
  assert list(mask_of(tr.carry_children, tr.REFUEL, away, WORLD)[:2]) == [True, True]
  assert tr.carry_primitive(tr.GET) == tc.PICKUP
  assert tr.carry_primitive(tr.PUT) == tc.DROPOFF
  assert tr.carry_primitive(tr.REFUEL) == tc.FILLUP
  assert nav == 0 and prim == 1
  assert mask_of(tr.navigate_children).all()


# --- termination ----------------------------------------------------------------

def test_terminations():
  for t, square in AT.items():
    x = state(*square, R, G, 5)
    for u in AT:
      assert tr.navigate_done(u, x, WORLD) == (u == t)
  assert tr.carry_done(tr.GET, state(0, 0, IN_TAXI, G, 5), WORLD)
  assert not tr.carry_done(tr.GET, state(0, 0, R, G, 5), WORLD)
  assert tr.carry_done(tr.PUT, state(*AT[G], G, G, 5), WORLD)         # delivered
  assert not tr.carry_done(tr.PUT, state(*AT[G], IN_TAXI, G, 5), WORLD)
  assert tr.carry_done(tr.REFUEL, state(2, 1, R, G, 12), WORLD)
  assert not tr.carry_done(tr.REFUEL, state(2, 1, R, G, 11), WORLD)
  assert not tr.carry_done(tr.REFUEL, state(2, 2, R, G, 12), WORLD)


def test_primitive_step_records_how_the_episode_ends():
  episode = np.zeros(3, dtype=np.int64)
  x = state(*AT[G], IN_TAXI, G, 5)
  assert tr.primitive_step(x, episode, tc.DROPOFF, WORLD) == 20.0
  assert list(episode) == [1, tr.DELIVERED, 0] and tr.episode_over(episode)

  episode[:] = 0
  x = state(1, 1, R, G, 0)
  assert tr.primitive_step(x, episode, tc.NORTH, WORLD) == -20.0
  assert episode[tr.E_OUTCOME] == tr.OUT_OF_FUEL

  episode[:] = 0
  x = state(1, 1, R, G, 9)
  assert tr.primitive_step(x, episode, tc.PICKUP, WORLD) == -10.0
  assert list(episode) == [1, tr.RUNNING, 1] and list(x) == [1, 1, R, G, 8]

  short = tr.world_config(tc.TaxiRules(max_steps=3))
  episode[:] = 0
  for _ in range(3):
    assert not tr.episode_over(episode)
    tr.primitive_step(x, episode, tc.SOUTH, short)
  assert episode[tr.E_OUTCOME] == tr.TRUNCATED and episode[tr.E_STEPS] == 3


# --- the compiled loop: a hand-set optimal policy -------------------------------------

BIG = 50.0   # a parameter gap that makes the softmax deterministic in practice


def optimal_tables():
  """Policy tables of a recursively optimal hierarchy for passengers aboard."""
  sizes = tr.n_abstract_states()
  tables = [np.zeros((n, k)) for n, k in zip(sizes, tr.N_CHILDREN)]
  for t, target in AT.items():
    to_target = moves_from(target)   # the grid's moves are symmetric
    for square in range(25):
      here = divmod(square, 5)
      for action in (tc.SOUTH, tc.NORTH, tc.EAST, tc.WEST):
        nxt = tuple(int(v) for v in tc.taxi_step(*here, 0, 1, 12, action, False)[:2])
        if to_target[nxt] < to_target[here]:
          tables[tr.NAVIGATE][t * 25 + square, action] = BIG
  tables[tr.GET][:, tr.CARRY_NAVIGATE] = BIG     # Navigate is unavailable at the target
  tables[tr.PUT][:, tr.CARRY_NAVIGATE] = BIG
  tables[tr.REFUEL][:, tr.CARRY_NAVIGATE] = BIG
  for square in range(25):
    here = divmod(square, 5)
    for destination in range(4):
      for fuel in range(13):
        direct = moves_from(here)[AT[destination]] + 1
        child = tr.ROOT_PUT if fuel >= direct else tr.ROOT_REFUEL
        tables[tr.ROOT][((25 + square) * 4 + destination) * 13 + fuel, child] = BIG
  return tables


def test_optimal_hierarchy_earns_v_star_exactly():
  values = tv.taxi_values(True)
  agent = tcp.TaxiHPG(0)
  for trace, table in zip(agent.traces, optimal_tables()):
    trace[0][:] = table.ravel()
  starts, expected = [], []
  for square in range(25):
    for destination in range(4):
      for fuel in range(13):
        starts.append((*divmod(square, 5), IN_TAXI, destination, fuel))
        expected.append(values.state_value(*starts[-1]))
  greedy = agent.run(len(starts), learn=False, greedy=True, starts=starts)
  np.testing.assert_array_equal(greedy[:, tcp.RETURN], expected)
  # Sampling from these tables is as good: a parameter gap of 50 leaves e^-50.
  sampled = agent.run(len(starts), learn=False, starts=starts)
  np.testing.assert_array_equal(sampled[:, tcp.RETURN], expected)


# --- the compiled loop: learning ------------------------------------------------------

def tables_of(agent):
  return [t.copy() for t in agent.policy_tables()]


def test_same_seed_same_run():
  a, b, c = tcp.TaxiHPG(3), tcp.TaxiHPG(3), tcp.TaxiHPG(4)
  rec_a, rec_b, rec_c = a.run(3000), b.run(3000), c.run(3000)
  np.testing.assert_array_equal(rec_a, rec_b)
  for ta, tb in zip(tables_of(a), tables_of(b)):
    np.testing.assert_array_equal(ta, tb)
  np.testing.assert_array_equal(a.rng_state, b.rng_state)
  assert not np.array_equal(rec_a, rec_c)
  assert a.episodes == 3000 and a.primitive_steps == int(rec_a[:, tcp.STEPS].sum())


def test_evaluation_leaves_the_policies_alone():
  agent = tcp.TaxiHPG(5)
  agent.run(2000)
  before = tables_of(agent)
  sampled = agent.run(500, learn=False)
  agent.run(500, learn=False, greedy=True)
  for t0, t1 in zip(before, tables_of(agent)):
    np.testing.assert_array_equal(t0, t1)
  assert agent.episodes == 2000
  assert set(np.unique(sampled[:, tcp.OUTCOME])) <= {tr.DELIVERED, tr.OUT_OF_FUEL, tr.TRUNCATED}


def test_greedy_runs_draw_only_the_starts():
  agent = tcp.TaxiHPG(6)
  expected = agent.rng_state.copy()
  scratch = np.zeros(5, dtype=np.int64)
  for _ in range(50):
    tcp.sample_start(expected, agent.world, scratch)
  agent.run(50, learn=False, greedy=True)
  np.testing.assert_array_equal(agent.rng_state, expected)


def test_start_states_follow_the_spec_distribution():
  state_ = np.zeros(5, dtype=np.int64)
  rs = rng.make_state(11)
  counts = collections.Counter()
  for _ in range(48_000):
    tcp.sample_start(rs, WORLD, state_)
    row, col, passenger, destination, fuel = state_
    assert passenger != destination and 5 <= fuel <= 12
    counts[(row, col, passenger, destination, fuel)] += 1
  assert len(counts) == 2400 and max(counts.values()) < 45   # about 20 each


def test_classic_task_never_refuels():
  agent = tcp.TaxiHPG(7, task=tc.TaxiRules(False))
  record = agent.run(2000)
  assert not np.any(record[:, tcp.OUTCOME] == tr.OUT_OF_FUEL)
  assert not np.any(agent.policy_tables()[tr.REFUEL])


def test_step_size_warm_up():
  config = tcp.HPGConfig()
  alphas = np.zeros(5)
  tcp.step_sizes(config.schedule(), 0, alphas)
  assert alphas[tr.ROOT] == 0.0
  # The ramp starts at once for Navigate (no delay): 0.1 + 0.9 / 25,000 of alpha.
  assert alphas[tr.NAVIGATE] == pytest.approx((0.1 + 0.9 / 25_000) * config.alpha_navigate)
  tcp.step_sizes(config.schedule(), config.delay_root - 1, alphas)
  assert alphas[tr.ROOT] == 0.0
  tcp.step_sizes(config.schedule(), config.delay_root + config.ramp_root, alphas)
  np.testing.assert_allclose(alphas, [config.alpha_root] + [config.alpha_carry] * 3
                             + [config.alpha_navigate])


def test_bad_arguments():
  with pytest.raises(ValueError, match="alpha_root"):
    tcp.HPGConfig(alpha_root=-0.1)
  with pytest.raises(ValueError, match="gamma_navigate"):
    tcp.HPGConfig(gamma_navigate=0.0)
  with pytest.raises(ValueError, match="ramp_carry"):
    tcp.HPGConfig(ramp_carry=0)
  agent = tcp.TaxiHPG(0)
  with pytest.raises(ValueError, match="greedy"):
    agent.run(1, learn=True, greedy=True)
  with pytest.raises(ValueError, match="n_episodes"):
    agent.run(-1)
  with pytest.raises(ValueError, match="own destination"):
    agent.run(1, starts=[0, 0, R, R, 5])


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(5))
def test_hpg_reaches_95_percent_of_optimal(seed):
  """The issue's requirement: the online mean return over a trailing window of
  1,000 episodes reaches 95% of the optimal mean return within 100,000 episodes.

  The window's mean wanders by about +-0.1 around the learner's level, which
  at 100,000 episodes is about 93% of the optimum (evaluated on 20,000 episodes);
  the window first touches 95% between episodes 57,000 and 82,000 (seeds 0-4).
  """
  optimal = tv.optimal_mean_return(True)
  agent = tcp.TaxiHPG(seed)
  returns = agent.run(100_000)[:, tcp.RETURN]
  trailing = np.convolve(returns, np.ones(1000) / 1000, mode="valid")
  assert trailing.max() >= tv.performance_threshold(optimal, 0.95)
  assert trailing[-1] >= tv.performance_threshold(optimal, 0.90)
