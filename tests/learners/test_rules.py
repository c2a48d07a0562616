"""Known answers for the learning rules (Eq. 3, the policies, the CMAC, Q(lambda))."""
import math

import numpy as np
import pytest

from hpg_mj.learners import stepwise
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import qlambda
from hpg_mj.learners import rng
from hpg_mj.learners import tiles


@pytest.mark.parametrize("gamma", [1.0, 0.9, 0.5])
def test_lazy_trace_equals_equation_3_applied_literally(gamma):
  gen = np.random.default_rng(0)
  n = 30
  lazy = el.new_trace(n)
  w = np.zeros(n)
  z = np.zeros(n)
  for step in range(400):
    if step % 97 == 0:                         # a subtask starts: z <- 0
      el.reset(lazy)
      z[:] = 0.0
    index = gen.choice(n, size=3, replace=False).astype(np.int64)
    psi = gen.normal(size=3)
    alpha, signal = 0.05, gen.normal()
    el.add_score(lazy, index, psi)
    z[index] += psi                            # z <- z + psi
    el.learn(lazy, alpha, signal, gamma)
    w += alpha * signal * z                    # theta <- theta + alpha (R + G) z
    z *= gamma                                 # discounted trace, for the next step
    current = el.parameters(lazy)
    np.testing.assert_allclose(current, w, rtol=1e-9, atol=1e-9)


def test_lazy_trace_touches_only_the_score():
  t = el.new_trace(1000)
  el.add_score(t, np.array([3, 7], dtype=np.int64), np.array([1.0, -1.0]))
  el.learn(t, 0.5, 2.0, 1.0)
  assert t.count[0] == 2 and np.count_nonzero(t.theta) == 0   # nothing written yet
  assert el.parameter(t, 3) == pytest.approx(1.0)
  assert el.parameter(t, 7) == pytest.approx(-1.0)
  el.reset(t)
  assert t.theta[3] == pytest.approx(1.0) and t.theta[7] == pytest.approx(-1.0)
  assert t.count[0] == 0 and not t.zs.any()


def test_softmax_probabilities_and_score():
  t = el.new_trace(2 * 3)
  t.theta[3:6] = [0.0, math.log(2.0), math.log(3.0)]      # state 1: probabilities 1:2:3
  probs = np.empty(3)
  policies.softmax_probabilities(t, 1, 3, np.ones(3, dtype=np.bool_), probs)
  np.testing.assert_allclose(probs, [1 / 6, 2 / 6, 3 / 6])
  policies.softmax_probabilities(t, 1, 3, np.array([True, False, True]), probs)
  np.testing.assert_allclose(probs, [0.25, 0.0, 0.75])
  state = rng.make_state(1)
  index, psi = np.empty(3, dtype=np.int64), np.empty(3)
  a = policies.softmax_act(t, 1, 3, np.ones(3, dtype=np.bool_), state, probs, index,
                           psi)
  expected = -np.array([1 / 6, 2 / 6, 3 / 6])
  expected[a] += 1.0                                       # psi = e_a - pi
  np.testing.assert_allclose(t.zs[3:6], expected)
  assert t.zs[3:6].sum() == pytest.approx(0.0, abs=1e-12)


def test_gaussian_sigmoid_policy_and_score():
  t = el.new_trace(20)
  active = np.arange(0, 18, 2, dtype=np.int64)           # 9 active tiles
  t.theta[active] = np.linspace(-1, 1, 9) + 0.5           # mean m = 0.5
  state = rng.make_state(3)
  probe = state.copy()
  u = 0.5 + rng.normal(probe)
  r = policies.gaussian_act(t, active, 15.0, state, np.empty(9))
  assert r == pytest.approx(15.0 * (2.0 / (1.0 + math.exp(-u)) - 1.0))
  np.testing.assert_allclose(t.zs[active], (u - 0.5) / 9)     # psi = (u - m) phi / sum phi
  assert not t.zs[1::2].any()
  fresh = el.new_trace(20)
  fresh.theta[:] = t.theta                                 # no pending trace: u = m
  assert policies.gaussian_greedy(fresh, active, 15.0) == pytest.approx(15 * math.tanh(0.25))


def test_cmac_activates_nine_tiles_wraps_and_shares():
  coder = tiles.TileCoder((0.0, 0.0, -180.0, -15.0), (150.0, 150.0, 180.0, 15.0),
                          (5, 5, 36, 5), (False, False, True, False), 9)
  assert coder.size == 9 * 4500
  a = coder.active([40.0, 40.0, 10.0, 0.0])
  assert len(a) == 9 and len(set(a)) == 9
  assert all(k * 4500 <= i < (k + 1) * 4500 for k, i in enumerate(a))
  # The heading wraps: -180 and 179.99 are neighbours, +180 is -180.
  assert len(set(coder.active([40, 40, -180.0, 0])) & set(coder.active([40, 40, 179.99, 0]))) >= 7
  np.testing.assert_array_equal(coder.active([40, 40, 180.0, 0]), coder.active([40, 40, -180.0, 0]))
  # Neighbouring states share tiles, distant ones share none.
  near = set(coder.active([41.0, 40.0, 10.5, 0.1]))
  assert len(near & set(a)) >= 6
  assert not set(coder.active([140.0, 120.0, -100.0, 12.0])) & set(a)
  # Outside the box the edge tiles are used.
  np.testing.assert_array_equal(coder.active([-5.0, 40, 10, 0]), coder.active([0.0, 40, 10, 0]))
  with pytest.raises(ValueError, match="high > low"):
    tiles.TileCoder((0.0,), (0.0,), (5,), (False,))
  # A float count of tiles (even 12.0) or tilings is refused, not truncated.
  with pytest.raises(ValueError, match=r"^tile coder: n_tiles must be integers >= 1, got "
                                       r"\(12.0, 6\)$"):
    tiles.TileCoder((0.0, 0.0), (1.0, 1.0), (12.0, 6), (False, False))
  with pytest.raises(ValueError, match=r"^tile coder: n_tilings must be an integer >= 1, "
                                       r"got 9.0$"):
    tiles.TileCoder((0.0,), (1.0,), (5,), (False,), n_tilings=9.0)


def test_cmac_baseline_hand_worked():
  # Three active tiles; b(s) = mean of their values = (3 + 0 + 6) / 3 = 3.
  values = np.array([3.0, 0.0, 6.0, 9.0])
  w = np.array([1.0, 1.0, 1.0, 1.0])
  tiles_s = np.array([0, 1, 2], dtype=np.int64)
  psi = np.array([0.5, 0.5, 0.5])
  policies.subtract_baseline(w, values, tiles_s, 0.1, psi)      # w -= alpha b(s) psi
  np.testing.assert_allclose(w, [1 - 0.15, 1 - 0.15, 1 - 0.15, 1.0])
  # TD(0): delta = -2 + 0.5 * b(s') - b(s) = -2 + 0.5 * 9 - 3 = -0.5; each tile moves beta delta.
  policies.learn_baseline(values, tiles_s, 0.2, -2.0, 0.5, 9.0)
  np.testing.assert_allclose(values, [2.9, -0.1, 5.9, 9.0])
  # A doomed choice (b(s) = -100, the local failure): the baseline's step is the exact
  # opposite of the -100 that Eq. 3 then applies along psi, so the choice moves w by 0.
  values = np.array([-100.0, -100.0, -100.0, 0.0])
  w = np.zeros(4)
  policies.subtract_baseline(w, values, tiles_s, 0.1, psi)
  np.testing.assert_allclose(w[:3], 0.1 * 100 * 0.5)


def test_gaussian_agent_baseline_equals_the_compiled_rule_order():
  """The step-by-step learner subtracts b(s) psi for the choice it made, applies Eq. 3,
  then learns b, with the tiles of the choice even though the view's array is reused."""
  gen = np.random.default_rng(2)
  agent = stepwise.GaussianPolicyGradient(40, 3, 15.0, 0.05, 0.9, baseline=0.3)
  w, values, z = np.zeros(40), np.zeros(40), np.zeros(40)
  view = np.empty(3, dtype=np.int64)
  probe = rng.make_state(4)
  state = probe.copy()
  agent.start()
  for step in range(30):
    view[:] = gen.choice(40, size=3, replace=False)
    tiles_s = view.copy()
    m = w[tiles_s].mean()
    u = m + rng.normal(probe)
    agent.act(view, None, state, True)
    psi = (u - m) / 3
    w[tiles_s] -= 0.05 * values[tiles_s].mean() * psi          # the baseline's step
    z *= 0.9 if step else 0.0
    z[tiles_s] += psi
    signal = gen.normal() - 1.0
    w += 0.05 * signal * z                                    # Eq. 3, literally
    done = step == 29
    view[:] = gen.choice(40, size=3, replace=False)          # the next state's view
    next_value = 0.0 if done else values[view].mean()
    values[tiles_s] += 0.3 * (signal + 0.9 * next_value - values[tiles_s].mean())
    agent.observe(signal, view, done, done, True)
  np.testing.assert_allclose(agent.parameters(), w, atol=1e-10)
  np.testing.assert_allclose(agent.values, values, atol=1e-12)
  assert np.abs(values).max() > 0.1


def test_cmac_displacement_is_coprime_with_the_number_of_tilings():
  np.testing.assert_array_equal(tiles.coprime_displacement(5, 9), [1, 2, 4, 5, 7])
  np.testing.assert_array_equal(tiles.coprime_displacement(4, 8), [1, 3, 5, 7])
  np.testing.assert_array_equal(tiles.coprime_displacement(3, 1), [1, 2, 3])


@pytest.mark.parametrize("task_name,coder_names", [
    ("ship_hybrid", ["coder"]), ("ship_flat_pg", ["coder"]),
    ("ship_actor_critic", ["actor_coder", "critic_coder"]),
    ("ship_hybrid_beyond", ["root_coder", "coder"])])
def test_shipped_cmacs_offset_every_pair_of_tilings_in_every_dimension(task_name, coder_names):
  """SPEC section 3: tiling k is shifted by k/n of a tile along a vector coprime with n."""
  from hpg_mj import agents as registry
  agent = registry.build(registry.load_task(task_name), seed=0)
  for name in coder_names:
    coder = getattr(agent, name)
    offsets = coder.arrays().offsets
    assert offsets.shape == (coder.n_tilings, len(coder.low))
    for d in range(offsets.shape[1]):
      assert len(set(offsets[:, d])) == coder.n_tilings, (task_name, name, d, offsets[:, d])
    # And the tiles themselves: sliding across one tile in dimension d, in steps of
    # a quarter of 1/n of a tile, every tiling changes tile once, each at its own step.
    width = coder.arrays().width
    for d in range(len(coder.low)):
      x = np.array([(lo + hi) / 2 for lo, hi in zip(coder.low, coder.high)])
      x[d] = coder.low[d] + 1.5 * width[d] + 1e-9
      crossed = {}
      previous = coder.active(x)
      for step in range(1, 4 * coder.n_tilings + 1):
        x[d] += width[d] / (4 * coder.n_tilings)
        now = coder.active(x)
        for k in np.flatnonzero(now != previous):
          crossed.setdefault(int(k), []).append(step)
        previous = now
      assert sorted(crossed) == list(range(coder.n_tilings)), (task_name, name, d, crossed)
      steps = [s for k in crossed for s in crossed[k]]
      assert len(steps) == len(set(steps)) == coder.n_tilings, (task_name, name, d, crossed)


def test_watkins_q_lambda_hand_worked():
  # 3 states x 2 actions, alpha 0.5, lambda 0.9, gamma 1.
  q = np.zeros(6)
  index, value, count = qlambda.new_trace(16)
  # (s0, a1) -R=-1-> s1, next action a0 greedy (all zero: a tie counts as greedy).
  d = qlambda.update(q, 2, index, value, count, 0, 1, -1.0, 1, 0, False, 0.5, 1.0, 0.9)
  assert d == -1.0
  np.testing.assert_allclose(q, [0, -0.5, 0, 0, 0, 0])
  assert count[0] == 1 and value[0] == pytest.approx(0.9)
  # (s1, a0) -R=-1-> s2, next action a1 also greedy (tie): delta = -1.
  d = qlambda.update(q, 2, index, value, count, 1, 0, -1.0, 2, 1, False, 0.5, 1.0, 0.9)
  assert d == -1.0
  np.testing.assert_allclose(q, [0, -0.5 - 0.45, -0.5, 0, 0, 0])
  np.testing.assert_allclose(sorted(value[:count[0]]), [0.81, 0.9])
  # (s2, a1) -R=10-> terminal: delta = 10, all traced pairs move, traces cleared.
  d = qlambda.update(q, 2, index, value, count, 2, 1, 10.0, 0, 0, True, 0.5, 1.0, 0.9)
  assert d == 10.0
  np.testing.assert_allclose(q, [0, -0.95 + 0.5 * 10 * 0.81, -0.5 + 0.5 * 10 * 0.9, 0, 0, 5.0])
  assert count[0] == 0


def test_watkins_cuts_the_trace_after_an_exploratory_action():
  q = np.array([0.0, 0.0, 1.0, 0.0])            # in s1 action 0 is greedy
  index, value, count = qlambda.new_trace(8)
  qlambda.update(q, 2, index, value, count, 0, 0, 0.0, 1, 1, False, 0.1, 1.0, 0.9)
  assert count[0] == 0                          # a' = 1 is not greedy: e <- 0
  qlambda.update(q, 2, index, value, count, 0, 0, 0.0, 1, 0, False, 0.1, 1.0, 0.9)
  assert count[0] == 1


def test_replacing_traces_clear_the_other_actions_of_the_state():
  q = np.zeros(4)
  index, value, count = qlambda.new_trace(8)
  qlambda.update(q, 2, index, value, count, 0, 0, 0.0, 0, 1, False, 0.1, 1.0, 1.0)
  qlambda.update(q, 2, index, value, count, 0, 1, 0.0, 1, 0, False, 0.1, 1.0, 1.0)
  traces = dict(zip(index[:count[0]], value[:count[0]]))
  assert traces.get(0, 0.0) == 0.0 and traces[1] == 1.0


def test_generator_is_reproducible_and_well_spread():
  a, b = rng.make_state(42), rng.make_state(42)
  xs = np.array([rng.uniform(a) for _ in range(20000)])
  assert all(rng.uniform(b) == x for x in xs[:100])
  assert 0.0 <= xs.min() and xs.max() < 1.0 and abs(xs.mean() - 0.5) < 0.01
  normals = np.array([rng.normal(a) for _ in range(20000)])
  assert abs(normals.mean()) < 0.03 and abs(normals.std() - 1.0) < 0.03
  counts = np.bincount([rng.randint(a, 8) for _ in range(8000)], minlength=8)
  assert counts.min() > 850
  with pytest.raises(ValueError, match="integer"):
    rng.make_state(1.5)


def test_q_learner_object_matches_the_rule_functions():
  learner = stepwise.QLambda(3, 2, alpha=0.5, lam=0.9, epsilon=0.0)
  state = rng.make_state(0)
  learner.start()
  a0 = learner.act(0, None, state, True)
  learner.observe(-1.0, 1, False, False, True)
  a1 = learner.act(1, None, state, True)
  learner.observe(10.0, None, True, True, True)
  q = np.zeros(6)
  index, value, count = qlambda.new_trace(16)
  qlambda.update(q, 2, index, value, count, 0, a0, -1.0, 1, a1, False, 0.5, 1.0, 0.9)
  qlambda.update(q, 2, index, value, count, 1, a1, 10.0, 0, 0, True, 0.5, 1.0, 0.9)
  np.testing.assert_array_equal(learner.q, q)
  assert learner.count[0] == 0


def test_tiled_q_lambda_with_one_tiling_is_the_table():
  # The same random SMDP transitions through both: the same deltas, values, traces.
  rs = np.random.default_rng(5)
  q_table, q_tiles = np.zeros(12), np.zeros(12)
  table, tiled = qlambda.new_trace(64), qlambda.new_trace(64)
  for _ in range(300):
    s, s_next = rs.integers(4, size=2)
    a, a_next = rs.integers(3, size=2)
    reward, terminal = rs.normal(), rs.random() < 0.2
    d1 = qlambda.update(q_table, 3, *table, s, a, reward, s_next, a_next, terminal, 0.3, 1.0,
                        0.8)
    d2 = qlambda.tiled_update(q_tiles, 3, *tiled, np.array([s]), a, reward,
                              np.array([s_next]), 3, a_next, terminal, 0.3, 1.0, 0.8)
    assert d1 == d2
    np.testing.assert_array_equal(q_table, q_tiles)
    assert table[2][0] == tiled[2][0]
    if terminal:
      qlambda.clear(table[2])
      qlambda.clear(tiled[2])


def test_tiled_q_lambda_hand_worked():
  # 2 tilings x 3 tiles, 2 actions: state A has tiles (0, 3), its neighbour B (0, 4).
  q = np.zeros(12)
  index, value, count = qlambda.new_trace(32)
  A, B, C = np.array([0, 3]), np.array([0, 4]), np.array([2, 5])
  # (A, a1) -R=-4-> terminal: delta = -4; each of A's two weights moves by 0.5 * -4 / 2,
  # so Q(A, a1) moves by alpha * delta = -2, and B, sharing tile 0, by half of it.
  d = qlambda.tiled_update(q, 2, index, value, count, A, 1, -4.0, C, 2, 0, True, 0.5, 1.0,
                           0.9)
  assert d == -4.0
  assert qlambda.tiled_value(q, A, 2, 1) == -2.0
  assert qlambda.tiled_value(q, B, 2, 1) == -1.0 and qlambda.tiled_value(q, B, 2, 0) == 0.0
  assert count[0] == 0
  # In B, a0 (0) is greedy over a1 (-1).
  rs = rng.make_state(0)
  assert qlambda.tiled_greedy(q, B, 2, 2, rs) == 0
  assert qlambda.tiled_greedy(q, A, 2, 2, rs) == 0 and qlambda.tiled_max(q, A, 2, 2) == 0.0
  # Where only the first action is offered, it is the greedy one and the max.
  assert qlambda.tiled_greedy(q, np.array([1, 5]), 2, 1, rs) == 0
  assert qlambda.tiled_epsilon_greedy(q, A, 2, 1, 1.0, rs) == 0
  # (B, a0) -R=-1-> A, a' = a0 greedy in A (0 > -2): delta = -1 + 0 - 0; traces on
  # B's tiles (0, 4) for a0, decayed by lambda.
  d = qlambda.tiled_update(q, 2, index, value, count, B, 0, -1.0, A, 2, 0, False, 0.5, 1.0,
                           0.9)
  assert d == -1.0
  np.testing.assert_allclose(q[[0, 8]], [-0.25, -0.25])          # tiles 0 and 4, action 0
  traced = dict(zip(index[:count[0]], value[:count[0]]))
  assert traced == {0: pytest.approx(0.9), 8: pytest.approx(0.9)}
  # (A, a0): A shares tile 0 with B: its trace is replaced (1), not accumulated.
  qlambda.tiled_update(q, 2, index, value, count, A, 0, 0.0, C, 2, 1, True, 0.5, 1.0, 0.9)
  assert count[0] == 0
  # The target maximises over the actions s' offers: with B's first alone, Q(B, a0).
  q[[1, 9]] += 5.0                                  # B's tiles 0 and 4, a1: Q(B, a1) = 9
  assert qlambda.tiled_value(q, B, 2, 1) > qlambda.tiled_value(q, B, 2, 0)
  expected = qlambda.tiled_value(q, B, 2, 0) - qlambda.tiled_value(q, A, 2, 0)
  d = qlambda.tiled_update(q, 2, index, value, count, A, 0, 0.0, B, 1, 0, False, 0.5, 1.0,
                           0.9)
  assert d == pytest.approx(expected) and count[0] == 2        # a0 is greedy among those


def test_tiled_q_learner_object_matches_the_rule_functions():
  learner = stepwise.TiledQLambda(6, 2, 2, alpha=0.5, lam=0.9, epsilon=0.0)
  state = rng.make_state(0)
  A, B = np.array([0, 3]), np.array([1, 4])
  learner.start()
  a0 = learner.act(A, None, state, True)
  A[:] = -1                                   # the learner keeps its own copy
  learner.observe(-1.0, (B, 1), False, False, True)
  a1 = learner.act((B, 1), None, state, True)
  assert a1 == 0                              # B offers only its first action
  learner.observe(10.0, None, True, True, True)
  q = np.zeros(12)
  index, value, count = qlambda.new_trace(16)
  qlambda.tiled_update(q, 2, index, value, count, np.array([0, 3]), a0, -1.0, B, 1, a1, False,
                       0.5, 1.0, 0.9)
  qlambda.tiled_update(q, 2, index, value, count, B, a1, 10.0, B, 1, 0, True, 0.5, 1.0, 0.9)
  np.testing.assert_array_equal(learner.q, q)
  with pytest.raises(ValueError, match="features must be 2 active tiles, got shape"):
    learner.act(np.array([1, 2, 3]), None, state, True)
  with pytest.raises(ValueError, match="a state offers 1 to 2 actions, got 3"):
    learner.act((B, 3), None, state, True)
