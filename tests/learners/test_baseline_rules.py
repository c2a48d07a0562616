"""Known answers for the baselines' rules: the actor-critic's TD(lambda) critic
converges to the exact action values of a fixed policy; single updates of the
flat learners match hand-worked steps."""
import math

import numba
import numpy as np

import dataclasses

from hpg_mj.agents import ship_actor_critic, ship_flat_pg
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import qlambda
from hpg_mj.learners import rng

# A small episodic MDP: 3 states, 2 actions, P[s, a, s'] with s' = 3 terminal.
P = np.array([[[0.1, 0.6, 0.0, 0.3], [0.0, 0.2, 0.5, 0.3]],
              [[0.3, 0.0, 0.4, 0.3], [0.5, 0.1, 0.0, 0.4]],
              [[0.0, 0.3, 0.2, 0.5], [0.2, 0.2, 0.2, 0.4]]])
R = np.array([[1.0, -1.0], [0.5, 2.0], [-2.0, 0.0]])
PI = np.array([[0.7, 0.3], [0.4, 0.6], [0.5, 0.5]])    # the fixed policy


def exact_q():
  """Q^pi by solving the linear Bellman equations over (s, a)."""
  n = 6
  m = np.eye(n)
  for s in range(3):
    for a in range(2):
      for s2 in range(3):
        for a2 in range(2):
          m[s * 2 + a, s2 * 2 + a2] -= P[s, a, s2] * PI[s2, a2]
  return np.linalg.solve(m, R.ravel())


@numba.njit
def _td_lambda(episodes, lam, seed_state, t):
  one = np.ones(1)
  index = np.zeros(1, dtype=np.int64)
  for e in range(episodes):
    alpha = 0.5 / (1.0 + e / 100.0)
    el.reset(t)
    s = rng.randint(seed_state, 3)
    a = policies.sample_index(PI[s], rng.uniform(seed_state))
    while True:
      s2 = policies.sample_index(P[s, a], rng.uniform(seed_state))
      q = el.parameter(t, s * 2 + a)
      target = R[s, a]
      if s2 < 3:
        a2 = policies.sample_index(PI[s2], rng.uniform(seed_state))
        target += el.parameter(t, s2 * 2 + a2)
      index[0] = s * 2 + a
      el.add_score(t, index, one)                  # e <- lambda e + phi
      el.learn(t, alpha, target - q, lam)
      if s2 == 3:
        break
      s, a = s2, a2


def test_td_lambda_critic_converges_to_the_exact_action_values():
  expected = exact_q()
  for lam in (0.0, 0.9):
    t = el.new_trace(6)
    _td_lambda(1_000_000, lam, rng.make_state(5), t)
    current = el.parameters(t)
    np.testing.assert_allclose(current, expected, atol=0.03)


def test_flat_policy_gradient_single_step_by_hand():
  # One control step from a fixed start: w changes by alpha * R * psi on the 9 tiles.
  c = ship_flat_pg.Config()
  agent = ship_flat_pg.ShipFlatPG(dataclasses.replace(
      c, environment=dataclasses.replace(c.environment, max_steps=1),
      policy=ship_flat_pg.Policy(alpha=0.01, trace_gamma=1.0)), seed=9)
  probe = agent.rng_state.copy()
  start = np.array([500.0, 500.0, 30.0, 2.0])
  tiles = agent.coder.active(start)
  u = 0.0 + rng.normal(probe)                          # m = 0 for zero weights
  record = agent.as_record(agent.compiled(1, True, True, start=start))
  assert record["steps"][0] == 1 and record["return"][0] == -1.0
  w = agent.parameters()["policy.theta"]
  np.testing.assert_allclose(w[tiles], 0.01 * -1.0 * u / 9, rtol=1e-12)
  assert np.count_nonzero(w) == 9


def test_actor_critic_single_step_by_hand():
  c = ship_actor_critic.Config()
  agent = ship_actor_critic.ShipActorCritic(dataclasses.replace(
      c, environment=dataclasses.replace(c.environment, max_steps=1),
      actor=ship_actor_critic.Actor(alpha=0.1),
      critic=ship_actor_critic.Critic(alpha=0.5, trace_decay=0.9)), seed=4)
  state = agent.state()                      # the live arrays, by node name
  state["policy.critic_theta"][:] = 0.25     # Q(s, a) = 9 * 0.25 = 2.25 for every (s, a)
  probe = agent.rng_state.copy()
  start = np.array([200.0, 700.0, -45.0, 0.0])
  a_tiles = ship_flat_pg.actor_coder().active(start)
  u = rng.normal(probe)
  r = 15.0 * math.tanh(u / 2)
  c_tiles = ship_actor_critic.critic_coder().active([*start, r])
  agent.compiled(1, True, True, start=start)
  # Truncated after one step: delta = R + Q(s', a') - Q(s, a) = -1 + 2.25 - 2.25.
  parameters = agent.parameters()            # pending trace updates applied
  critic = parameters["policy.critic_theta"]
  np.testing.assert_allclose(critic[c_tiles], 0.25 + 0.5 * -1.0, rtol=1e-12)
  assert np.count_nonzero(critic != 0.25) == 9
  np.testing.assert_allclose(parameters["policy.actor_w"][a_tiles], 0.1 * 2.25 * u / 9,
                             rtol=1e-12)


def test_flat_q_learning_is_q_lambda_with_lambda_zero():
  q = np.zeros(8)
  index, value, count = qlambda.new_trace(4)
  qlambda.update(q, 2, index, value, count, 0, 1, -1.0, 2, 0, False, 1.0, 1.0, 0.0)
  assert q[1] == -1.0 and count[0] == 0          # Q(s, a) <- R + max Q(s'); no trace left
  q[4] = 5.0
  qlambda.update(q, 2, index, value, count, 1, 0, -1.0, 2, 0, False, 0.5, 1.0, 0.0)
  assert q[2] == 0.5 * (-1.0 + 5.0)
