"""Known answers for the learned exploration width (`policies.gaussian_width_act`,
SPEC section 8): a hand-worked step, the score as the exact gradient of log pi,
the clip, and width_alpha = 0 as the paper's rule to the bit."""
import math

import numpy as np
import pytest

from hpg_mj.hierarchy import ship_subtask
from hpg_mj.hierarchy import blocks
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import rng

TILES = np.array([0, 3, 5, 7, 11, 13, 17, 19, 23], dtype=np.int64)


def _traces(theta_value=0.2, width_value=-0.3):
  t, w = el.new_trace(30), el.new_trace(30)
  t.theta[TILES] = theta_value + 0.01 * np.arange(9)
  w.theta[TILES] = width_value - 0.02 * np.arange(9)
  return t, w


def _log_pi(u, theta, width):
  m = theta[TILES].mean()
  ls = width[TILES].mean()
  return -0.5 * ((u - m) / math.exp(ls)) ** 2 - ls - 0.5 * math.log(2 * math.pi)


def test_a_sampled_step_by_hand():
  t, w = _traces()
  theta0, width0 = t.theta.copy(), w.theta.copy()
  state = rng.make_state(7)
  probe = state.copy()
  psi, psi_w = np.empty(9), np.empty(9)
  r = policies.gaussian_width_act(t, w, TILES, 15.0, math.log(0.25), math.log(4.0), state,
                                  psi, psi_w)
  m = theta0[TILES].mean()
  sigma = math.exp(width0[TILES].mean())
  u = m + sigma * rng.normal(probe)
  assert r == pytest.approx(15.0 * (2.0 / (1.0 + math.exp(-u)) - 1.0), rel=1e-12)
  np.testing.assert_array_equal(state, probe)              # one normal draw, nothing else
  # z <- z + psi on both traces; theta <- theta + alpha (R + G) z with alpha (R + G) = 1.
  el.learn(t, 1.0, 1.0, 1.0)
  el.learn(w, 1.0, 1.0, 1.0)
  np.testing.assert_allclose(el.parameters(t)[TILES] - theta0[TILES],
                             (u - m) / sigma ** 2 / 9, rtol=1e-12)
  np.testing.assert_allclose(el.parameters(w)[TILES] - width0[TILES],
                             ((u - m) ** 2 / sigma ** 2 - 1.0) / 9, rtol=1e-12)
  assert np.count_nonzero(el.parameters(t) - theta0) == 9


def test_the_scores_are_the_gradient_of_log_pi():
  t, w = _traces()
  theta0, width0 = t.theta.copy(), w.theta.copy()
  psi, psi_w = np.empty(9), np.empty(9)
  state = rng.make_state(3)
  probe = state.copy()
  policies.gaussian_width_act(t, w, TILES, 15.0, math.log(0.25), math.log(4.0), state, psi,
                              psi_w)
  u = theta0[TILES].mean() + math.exp(width0[TILES].mean()) * rng.normal(probe)
  h = 1e-6
  for k, i in enumerate(TILES):
    for base, other, score in ((theta0, width0, psi), (width0, theta0, psi_w)):
      up, down = base.copy(), base.copy()
      up[i] += h
      down[i] -= h
      args = (lambda b: (u, b, other)) if base is theta0 else (lambda b: (u, other, b))
      numeric = (_log_pi(*args(up)) - _log_pi(*args(down))) / (2 * h)
      assert score[k] == pytest.approx(numeric, rel=1e-6, abs=1e-9)


def test_a_clipped_width_has_no_score_and_the_clipped_sigma():
  t, w = _traces(width_value=3.0)                    # log sigma ~ 2.9 > log 4
  psi, psi_w = np.empty(9), np.empty(9)
  state = rng.make_state(11)
  probe = state.copy()
  policies.gaussian_width_act(t, w, TILES, 15.0, math.log(0.25), math.log(4.0), state, psi,
                              psi_w)
  u = t.theta[TILES].mean() + 4.0 * rng.normal(probe)
  np.testing.assert_array_equal(psi_w, 0.0)
  np.testing.assert_allclose(psi, (u - t.theta[TILES].mean()) / 16.0 / 9, rtol=1e-12)


def test_width_alpha_zero_is_the_papers_rule_to_the_bit():
  t1, w1 = _traces()
  t2, _ = _traces()
  values = np.linspace(-1, 1, 30)
  s1, s2 = rng.make_state(5), rng.make_state(5)
  psi1, psi2, psi_w = np.empty(9), np.empty(9), np.empty(9)
  r1 = policies.gaussian_choose(t1, values, TILES, psi1, 0.01, 0.3, 15.0, True, True, s1, w1,
                                psi_w, 0.0, math.log(0.25), 0.0)
  r2 = policies.gaussian_act(t2, TILES, 15.0, s2, psi2)
  policies.subtract_baseline(t2.theta, values, TILES, 0.01, psi2)
  assert r1 == r2
  for a, b in zip(t1, t2):
    np.testing.assert_array_equal(a, b)
  np.testing.assert_array_equal(s1, s2)


def test_bad_width_options_are_refused_with_what_is_allowed():
  with pytest.raises(ValueError, match=r"width_alpha = -0.1: must be a finite number >= 0"):
    blocks.check_width(-0.1, 0.25, 1.0)
  with pytest.raises(ValueError, match=r"need 0 < sigma_low <= 1 <= sigma_high"):
    blocks.GaussianCMAC(ship_subtask.paper_coder(), width_alpha=0.01, sigma_low=2.0)
  with pytest.raises(ValueError, match=r"subtask 'diag' is not known; allowed: \['diagonal'"):
    ship_subtask.train_subtask("diag", 10, 0)


def test_stand_alone_subtasks_learn():
  for task in ship_subtask.TASKS:
    run = ship_subtask.train_subtask(task, 3000, 1, width_alpha=0.003, sigma_high=1.0)
    assert run["success"][-1000:].mean() > run["success"][:500].mean() + 0.1
    assert 0.25 <= run["sigma"].min() and run["sigma"].max() <= 1.0
