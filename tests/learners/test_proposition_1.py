"""Eq. 3's gradient estimate is unbiased for the weighted reward-to-go (Proposition 1).

A small episodic MDP with two states, two actions and stochastic transitions is
solved exactly; the gradient of chi = sum_s pibar(s) J(s) is taken by central
differences of the exact solution. The Eq. 3 rule, run with a tiny step size so
the policy stays put, accumulates alpha * sum_k R_k z_{k+1} per episode; its mean
over many episodes, divided by alpha, must match within its statistical error.
"""
import numba
import numpy as np

from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import rng

N_STATES, N_ACTIONS = 2, 2
# P[s, a, s'] over s' in {0, 1, terminal}; R[s, a].
P = np.array([[[0.2, 0.5, 0.3], [0.0, 0.3, 0.7]],
              [[0.6, 0.1, 0.3], [0.1, 0.1, 0.8]]])
R = np.array([[1.0, -2.0], [0.5, 3.0]])
START = np.array([0.7, 0.3])
THETA = np.array([0.3, -0.2, -0.5, 0.4])


def exact_chi(theta):
  logits = theta.reshape(N_STATES, N_ACTIONS)
  mu = np.exp(logits - logits.max(axis=1, keepdims=True))
  mu /= mu.sum(axis=1, keepdims=True)
  p_mu = np.einsum("sa,sat->st", mu, P[:, :, :N_STATES])
  r_mu = (mu * R).sum(axis=1)
  j = np.linalg.solve(np.eye(N_STATES) - p_mu, r_mu)
  return START @ j


def exact_gradient(theta, h=1e-6):
  grad = np.empty_like(theta)
  for i in range(len(theta)):
    e = np.zeros_like(theta)
    e[i] = h
    grad[i] = (exact_chi(theta + e) - exact_chi(theta - e)) / (2 * h)
  return grad


@numba.njit
def _estimates(theta, episodes, alpha, seed_state, out):
  t_w = theta.copy()
  zs = np.zeros(theta.shape[0])
  y = np.zeros(theta.shape[0])
  touched = np.zeros(theta.shape[0], dtype=np.int64)
  marked = np.zeros(theta.shape[0], dtype=np.bool_)
  count = np.zeros(1, dtype=np.int64)
  acc = np.array([0.0, 1.0])
  t = el.Trace(t_w, zs, y, touched, marked, count, acc)
  mask = np.ones(N_ACTIONS, dtype=np.bool_)
  probs = np.empty(N_ACTIONS)
  index = np.empty(N_ACTIONS, dtype=np.int64)
  psi = np.empty(N_ACTIONS)
  start = np.array([0.7, 0.3])
  for e in range(episodes):
    t_w[:] = theta
    el.reset(t)                                            # z <- 0 at the start
    t_w[:] = theta
    s = policies.sample_index(start, rng.uniform(seed_state))
    while s < N_STATES:
      a = policies.softmax_act(t, s, N_ACTIONS, mask, seed_state, probs, index, psi)
      el.learn(t, alpha, R[s, a], 1.0)
      s = policies.sample_index(P[s, a], rng.uniform(seed_state))
    for i in range(theta.shape[0]):
      out[e, i] = (el.parameter(t, i) - theta[i]) / alpha


def test_equation_3_estimates_the_exact_gradient():
  episodes = 60000
  out = np.empty((episodes, len(THETA)))
  _estimates(THETA, episodes, 1e-7, rng.make_state(11), out)
  mean = out.mean(axis=0)
  stderr = out.std(axis=0) / np.sqrt(episodes)
  exact = exact_gradient(THETA)
  assert np.all(np.abs(mean - exact) < 4.0 * stderr + 1e-4), (mean, exact, stderr)
  # The check has power: a wrong sign or a missing score term would be far off.
  assert np.all(stderr < 0.25 * np.abs(exact) + 0.02)
