"""The taxi task graph (hpg_mj.hierarchy.taxi_subtasks) on hand-built states, and
HPG on the task-graph machine (hpg_mj.agents.taxi_hpg: GibbsTables over the taxi
blocks): exact returns of a hand-set optimal policy, determinism under a seed, the
step sizes' warm-up and the baseline, and (slow) learning to 95% of the optimal
mean return."""
import collections

import numpy as np
import pytest
from taxi_grid import moves_from

from hpg_mj.agents import taxi_hpg as tcp
from hpg_mj.taskfile import updated
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.program import Program
from hpg_mj.hierarchy import taxi_subtasks as tr
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import rng
from hpg_mj.worlds import taxi_core as tc
from hpg_mj.worlds import taxi_rules as world_rules
from hpg_mj.worlds import taxi_values as tv

R, G, Y, B = 0, 1, 2, 3
AT = {R: (0, 0), G: (0, 4), Y: (4, 0), B: (4, 3), tr.TARGET_F: (2, 1)}
IN_TAXI = tc.IN_TAXI
WORLD = world_rules.world_config()
CLASSIC_WORLD = world_rules.world_config(tc.TaxiRules(False))


def state(row, col, passenger, destination, fuel):
  return np.array([row, col, passenger, destination, fuel], dtype=np.int64)


def mask_of(fill, *args):
  mask = np.zeros(tr.MAX_CHILDREN, dtype=np.bool_)
  fill(*args, mask)
  return mask


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
  assert world_rules.primitive_step(x, episode, tc.DROPOFF, WORLD) == 20.0
  assert list(episode) == [1, world_rules.DELIVERED, 0] and world_rules.episode_over(episode)

  episode[:] = 0
  x = state(1, 1, R, G, 0)
  assert world_rules.primitive_step(x, episode, tc.NORTH, WORLD) == -20.0
  assert episode[world_rules.E_OUTCOME] == world_rules.OUT_OF_FUEL

  episode[:] = 0
  x = state(1, 1, R, G, 9)
  assert world_rules.primitive_step(x, episode, tc.PICKUP, WORLD) == -10.0
  assert list(episode) == [1, world_rules.RUNNING, 1] and list(x) == [1, 1, R, G, 8]

  short = world_rules.world_config(tc.TaxiRules(max_steps=3))
  episode[:] = 0
  for _ in range(3):
    assert not world_rules.episode_over(episode)
    world_rules.primitive_step(x, episode, tc.SOUTH, short)
  assert episode[world_rules.E_OUTCOME] == world_rules.TRUNCATED and episode[world_rules.E_STEPS] == 3


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


def _agent(seed, config=None):
  return tcp.TaxiHPG(config or tcp.Config(), seed=seed)


def test_optimal_hierarchy_earns_v_star_exactly():
  values = tv.taxi_values(True)
  agent = _agent(0)
  state = agent.machine.state()                       # the live arrays, by node name
  for name, optimal in zip(blocks.TAXI_SUBTASKS, optimal_tables()):
    state[f"{name}.theta"][:] = optimal.ravel()
  starts, expected = [], []
  for square in range(25):
    for destination in range(4):
      for fuel in range(13):
        starts.append((*divmod(square, 5), IN_TAXI, destination, fuel))
        expected.append(values.state_value(*starts[-1]))
  greedy = agent.as_record(agent.compiled(len(starts), False, False, starts=starts))
  np.testing.assert_array_equal(greedy["return"], expected)
  # Sampling from these tables is as good: a parameter gap of 50 leaves e^-50.
  sampled = agent.as_record(agent.compiled(len(starts), False, True, starts=starts))
  np.testing.assert_array_equal(sampled["return"], expected)


# --- learning ----------------------------------------------------------------------

def tables_of(agent):
  return [t.copy() for t in agent.policy_tables()]


def test_same_seed_same_run():
  a, b, c = (_agent(seed) for seed in (3, 3, 4))
  rec_a, rec_b, rec_c = a.train(3000), b.train(3000), c.train(3000)
  np.testing.assert_array_equal(rec_a, rec_b)
  for ta, tb in zip(tables_of(a), tables_of(b)):
    np.testing.assert_array_equal(ta, tb)
  np.testing.assert_array_equal(a.rng_state, b.rng_state)
  assert not np.array_equal(rec_a, rec_c)
  assert a.episodes == 3000


def test_evaluation_leaves_the_policies_alone():
  agent = _agent(5)
  agent.train(2000)
  before = tables_of(agent)
  sampled = agent.evaluate(500, policy="sampled")
  agent.evaluate(500)
  # Each call still folds its pending Eq. 3 updates into theta (z <- 0), as every
  # path's calls do: the same parameters, but for the rounding of that sum.
  for t0, t1 in zip(before, tables_of(agent)):
    np.testing.assert_allclose(t0, t1, rtol=1e-12, atol=1e-12)
  assert agent.episodes == 2000
  assert set(np.unique(sampled["outcome"])) <= {world_rules.DELIVERED, world_rules.OUT_OF_FUEL,
                                                world_rules.TRUNCATED}


def test_greedy_runs_draw_only_the_starts():
  agent = _agent(6)
  expected = agent.rng_state.copy()
  scratch = np.zeros(5, dtype=np.int64)
  for _ in range(50):
    tr.sample_start(expected, agent.world, scratch)
  agent.evaluate(50)
  np.testing.assert_array_equal(agent.rng_state, expected)


def test_start_states_follow_the_spec_distribution():
  state_ = np.zeros(5, dtype=np.int64)
  rs = rng.make_state(11)
  counts = collections.Counter()
  for _ in range(48_000):
    tr.sample_start(rs, WORLD, state_)
    row, col, passenger, destination, fuel = state_
    assert passenger != destination and 5 <= fuel <= 12
    counts[(row, col, passenger, destination, fuel)] += 1
  assert len(counts) == 2400 and max(counts.values()) < 45   # about 20 each


def test_classic_task_never_refuels():
  agent = _agent(7, updated(tcp.Config(), environment={"fuel": False}))
  record = agent.train(2000)
  assert not np.any(record["outcome"] == world_rules.OUT_OF_FUEL)
  assert not np.any(agent.policy_tables()[tr.REFUEL])


def _step_sizes(agent, learned_episodes):
  """The GibbsTables' step sizes in episodes after `learned_episodes` learning ones
  (each node's, set when it is called: 30 episodes sampled from the fresh uniform
  tables call every subtask)."""
  agent.episodes = learned_episodes
  m = agent.machine
  for name in blocks.TAXI_SUBTASKS:
    m._field(f"N{m.index[name]}").alpha[0] = np.nan
  agent.compiled(30, False, True)
  return np.array([m._field(f"N{m.index[name]}").alpha[0] for name in blocks.TAXI_SUBTASKS])


def test_step_size_warm_up():
  config = tcp.Config()
  agent = _agent(0)
  alphas = _step_sizes(agent, 0)                   # by table: root, get, put, refuel, navigate
  assert alphas[tr.ROOT] == 0.0
  # The ramp starts at once for Navigate (no delay): 0.1 + 0.9 / 25,000 of alpha.
  assert alphas[tr.NAVIGATE] == pytest.approx((0.1 + 0.9 / 25_000) * config.navigate.alpha)
  assert _step_sizes(agent, config.root.delay - 1)[tr.ROOT] == 0.0
  np.testing.assert_allclose(_step_sizes(agent, config.root.delay + config.root.ramp),
                             [config.root.alpha] + [config.carry.alpha] * 3
                             + [config.navigate.alpha])


def test_baseline_steps_by_hand():
  # theta <- theta - alpha b(s) psi(s, a), on the allowed children's entries only.
  t = el.new_trace(9)
  values = np.array([0.0, 2.0, 0.0])
  mask = np.array([True, False, True])
  probs, index, psi = np.zeros(3), np.zeros(3, dtype=np.int64), np.zeros(3)
  a = policies.softmax_choose(t, values, 1, 3, mask, 0.5, True, True, rng.make_state(0), probs,
                              index, psi)
  assert a in (0, 2) and list(index[:2]) == [3, 5]
  np.testing.assert_array_equal(psi[:2], [0.5, -0.5] if a == 0 else [-0.5, 0.5])
  np.testing.assert_array_equal(t.theta, [0, 0, 0, -psi[0], 0, -psi[1], 0, 0, 0])
  np.testing.assert_array_equal(t.zs[[3, 5]], psi[:2])                # z <- z + psi
  before = t.theta.copy()
  policies.softmax_choose(t, values, 0, 3, mask, 0.5, True, True, rng.make_state(0), probs,
                          index, psi)                                  # b(s) = 0
  policies.softmax_choose(t, values, 1, 3, mask, 0.5, False, True, rng.make_state(0), probs,
                          index, psi)                                  # not learning
  np.testing.assert_array_equal(t.theta, before)
  # b(s) <- b(s) + beta (R + b(s') - b(s)), with b(s') = 0 once the call is over.
  values = np.array([1.0, 3.0])
  policies.softmax_learn(el.new_trace(4), values, 0, 1, 0.1, 1.0, 0.5, -1.0, False)
  assert values[0] == 1.5                                  # target -1 + 3
  policies.softmax_learn(el.new_trace(4), values, 0, 1, 0.1, 1.0, 0.5, -1.0, True)
  assert values[0] == 0.25                                 # target -1
  policies.softmax_learn(el.new_trace(4), values, 0, 1, 0.1, 1.0, 0.0, -1.0, True)
  assert list(values) == [0.25, 3.0]


def test_baseline_is_an_option():
  off = updated(tcp.Config(), root={"baseline": 0.0}, carry={"baseline": 0.0},
                navigate={"baseline": 0.0})
  plain, based = _agent(2, off), _agent(2)
  plain.train(3000)
  based.train(3000)
  assert not any(np.any(v) for v in plain.baselines())     # b = 0: Eq. 3 exactly
  assert all(np.any(v) for v in based.baselines())
  # A Navigate baseline estimates the (negative) moves left to the target: the
  # targets themselves are never a state of their own calls.
  navigate = based.baselines()[tr.NAVIGATE].reshape(tr.N_TARGETS, 25)
  for t, (row, col) in AT.items():
    assert navigate[t, row * 5 + col] == 0.0
  assert np.all(navigate <= 0.0)
  # Root's baseline learns while Root itself waits (step size 0 for 15,000 episodes).
  assert not np.any(tables_of(based)[tr.ROOT])
  for t1, t2 in zip(tables_of(plain)[1:], tables_of(based)[1:]):
    assert not np.array_equal(t1, t2)


def test_bad_arguments():
  config = tcp.Config()
  with pytest.raises(ValueError, match=r"alpha = -0.1 is out of range; allowed: >= 0"):
    updated(config, root={"alpha": -0.1})
  with pytest.raises(ValueError, match=r"baseline = 1.5 is out of range; allowed: >= 0 and <= 1"):
    updated(config, carry={"baseline": 1.5})
  with pytest.raises(ValueError, match=r"trace_gamma = 0.0 is out of range; allowed: > 0"):
    updated(config, navigate={"trace_gamma": 0.0})
  with pytest.raises(ValueError, match=r"ramp = 0 is out of range; allowed: >= 1"):
    updated(config, carry={"ramp": 0})
  with pytest.raises(ValueError, match=r"\[carry\] unknown key\(s\) \['ramp_carry'\]"):
    updated(config, carry={"ramp_carry": 0})
  agent = _agent(0)
  with pytest.raises(ValueError, match="episodes must be a non-negative integer"):
    agent.train(-1)
  with pytest.raises(ValueError, match="own destination"):
    agent.compiled(1, False, False, starts=[0, 0, R, R, 5])


@pytest.mark.slow
def test_hpg_reaches_95_percent_of_optimal():
  """The issue's requirement, as `hpg-mj train tasks/taxi_fuel_hpg.toml --json`
  measures it: the online mean return of the last 1,000 of 100,000 training
  episodes, mean of seeds 0-4, is at least 95% of the optimal mean return.

  With the defaults (those of the task file) the five windows give 5.98, 6.11,
  5.95, 6.11 and 6.19: 6.07, 98.8% of 6.1446; over seeds 5-24 they range from
  5.80 to 6.12 (mean 97.2%). Each window's mean wanders by about +-0.1 (one
  fuel-out costs about 30).
  """
  optimal = tv.optimal_mean_return(True)
  last = []
  for seed in range(5):
    returns = _agent(seed).train(100_000)["return"]
    last.append(returns[-1000:].mean())
  assert np.mean(last) >= tv.performance_threshold(optimal, 0.95)
  assert min(last) >= tv.performance_threshold(optimal, 0.90)


def test_taxi_blocks_need_the_taxi_world():
  agent = _agent(0)
  with pytest.raises(GraphError, match="subtask 'root': its Taxi[A-Za-z]+ reads the world's "
                     r"settings, and this program was built without them \(Program\(graph, "
                     "world="):
    Program(agent.graph(), obs_size=5)
