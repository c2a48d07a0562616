"""Average-reward SMDP Q-learning (hpg_mj.learners.average_reward) against a small
continuing SMDP solved exactly: the learned gain and relative values match."""
import itertools

import numpy as np
import pytest

from hpg_mj.learners import average_reward as ar

# A continuing SMDP of 3 states, 2 actions each, with durations that vary by action
# and transitions that are random: P[s, a, s'], mean reward R[s, a], mean duration
# TAU[s, a] (each duration is drawn uniformly from TAU +- 1, each reward from R +- 1).
P = np.array([[[0.0, 1.0, 0.0], [0.5, 0.0, 0.5]],
              [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
              [[1.0, 0.0, 0.0], [0.0, 0.7, 0.3]]])
R = np.array([[2.0, 5.0], [0.0, 1.0], [6.0, 3.0]])
TAU = np.array([[2.0, 3.0], [2.0, 1.5], [4.0, 2.0]])


def solve(policy):
  """(gain, relative values with h[0] = 0) of a stationary policy: the average-reward
  Bellman equations h(s) + g tau(s) = r(s) + sum P h, solved as a linear system."""
  n = len(policy)
  a = np.zeros((n, n))
  b = np.zeros(n)
  for s, act in enumerate(policy):
    # unknowns: g, h[1], ..., h[n-1]
    a[s, 0] = TAU[s, act]
    for t in range(1, n):
      a[s, t] = (s == t) - P[s, act, t]
    b[s] = R[s, act]
  x = np.linalg.solve(a, b)
  return x[0], np.concatenate([[0.0], x[1:]])


def exact_optimum():
  """The gain-optimal policy (all 8 enumerated), then improved by policy iteration
  until it is greedy in its own relative values: a transient state's action
  changes no gain, but the Bellman optimality equation fixes it."""
  best = max(itertools.product(range(2), repeat=3), key=lambda pi: solve(pi)[0])
  while True:
    gain, h = solve(best)
    q = R - gain * TAU + P @ h
    better = tuple(int(a) if q[s, a] > q[s, best[s]] + 1e-12 else best[s]
                   for s, a in enumerate(q.argmax(axis=1)))
    if better == best:
      return best, gain, h, q
    best = better


def test_the_exact_solution_satisfies_bellman_optimality():
  best, gain, h, q = exact_optimum()
  np.testing.assert_allclose(q.max(axis=1), h, atol=1e-12)
  assert tuple(q.argmax(axis=1)) == best
  # The optimum is not what a short-sighted rate maximiser would pick everywhere.
  assert gain == max(solve(pi)[0] for pi in itertools.product(range(2), repeat=3))


def learn(transitions, seed, epsilon=0.2, gain_step=None, power=0.7):
  """Learns on the SMDP with epsilon-greedy exploration; step sizes 1 / visits^power
  per (s, a), and for the gain `gain_step`, or by default 0.1 / (1 + n / 500) over
  the n greedy transitions so far (Robbins-Monro, so that the test can be tight)."""
  rng = np.random.default_rng(seed)
  q = np.zeros(6)
  gain = ar.new_gain()
  visits = np.zeros(6)
  s = 0
  for _ in range(transitions):
    greedy = int(np.argmax(q[2 * s:2 * s + 2]))
    a = int(rng.integers(2)) if rng.uniform() < epsilon else greedy
    s_next = int(rng.choice(3, p=P[s, a]))
    reward = R[s, a] + rng.uniform(-1.0, 1.0)
    duration = TAU[s, a] + rng.uniform(-1.0, 1.0)
    visits[2 * s + a] += 1
    alpha = 1.0 / visits[2 * s + a] ** power
    beta = 0.1 / (1.0 + gain[ar.GREEDY_SEEN] / 500.0) if gain_step is None else gain_step
    ar.update(q, 2, gain, s, a, reward, duration, s_next, alpha, beta,
              ar.is_greedy(q, s, a, 2))
    s = s_next
  return q, gain


@pytest.mark.parametrize("seed", [0, 3])
def test_learned_gain_and_relative_values_match_the_exact_ones(seed):
  best, gain, h, q_exact = exact_optimum()
  q, learned = learn(60000, seed, power=0.85)
  assert learned[ar.RHO] == pytest.approx(gain, rel=0.03)
  np.testing.assert_allclose(ar.relative_values(q, 3, 2), h, atol=0.1)
  # Every action's relative value, not only the greedy ones (shifted as h is).
  shift = q.reshape(3, 2).max(axis=1)[0]
  np.testing.assert_allclose(q.reshape(3, 2) - shift, q_exact, atol=0.15)
  assert tuple(q.reshape(3, 2).argmax(axis=1)) == best


def test_planning_corrects_a_loop_whose_values_are_stale():
  # Issue 24's collapse in miniature: states A = 0 and B = 1 far from a gate loop
  # G = 2 whose gain is rho = 1 (+100 every 50 steps, -1 a step). A and B were last
  # valued while rho was ~ -1, so their calls (100 steps, -100) are worth ~0 and
  # their order is noise: the greedy root sails A -> B -> A forever. Planning
  # backs the kept transitions up with today's rho: A's way to G wins, rho and
  # the entries never taken stay as they were.
  n = 2
  q = np.zeros(3 * n)
  q[0 * n + 0], q[1 * n + 0], q[2 * n + 0] = 14.0, 13.0, 500.0
  gain = ar.new_gain()
  gain[ar.RHO] = 1.0
  model = ar.new_model(q.size)
  for s, a, r, tau, s_next in ((0, 0, -100.0, 100.0, 1), (1, 0, -100.0, 100.0, 0),
                               (0, 1, -100.0, 100.0, 2), (2, 0, 50.0, 50.0, 2)):
    ar.remember_and_plan(q, n, gain, model, s, a, r, tau, s_next, 0.1, 1000)
  assert model[3][0] == 4 and q[0 * n + 1] == 0.0 and np.argmax(q[0:2]) == 0
  for _ in range(100):
    ar.plan(q, n, gain, model, 0.1)
  assert np.argmax(q[0:2]) == 1                       # A now heads for the gate loop
  assert q[0 * n + 1] == pytest.approx(-200.0 + q[2 * n + 0], abs=1.0)
  assert q[1 * n + 1] == 0.0 and q[2 * n + 1] == 0.0  # never taken: not backed up
  assert gain[ar.RHO] == 1.0 and gain[ar.GREEDY_SEEN] == 0.0


def test_remember_and_plan_sweeps_every_so_many_transitions():
  n = 2
  q = np.zeros(2 * n)
  gain = ar.new_gain()
  model = ar.new_model(q.size)
  ar.remember_and_plan(q, n, gain, model, 0, 1, 5.0, 1.0, 1, 0.5, 0)    # 0: no planning
  assert model[3][0] == 0 and (model[0] == -1).all() and (q == 0).all()
  ar.remember_and_plan(q, n, gain, model, 0, 1, 5.0, 1.0, 1, 0.5, 2)
  assert model[3][0] == 1 and model[0][1] == 1 and (q == 0).all()       # kept, no sweep yet
  ar.remember_and_plan(q, n, gain, model, 1, 0, 1.0, 2.0, 0, 0.5, 2)
  assert q[1] == pytest.approx(2.5) and q[2] == pytest.approx(0.5 + 0.5 * 2.5)
