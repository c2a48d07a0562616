"""The goal-conditioned ship's rule (hpg_mj.worlds.ship_goal_core): when a goal is
reached, from goals alone, and the gates each level draws."""
import math

import numpy as np
import pytest

from hpg_mj import verify_ladder
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_goal_core as goal_core


def _gate(x, y, heading_deg):
  return goal_core.check_gate([x, y, heading_deg], "test")


def _achieved(x, y, heading_deg):
  return goal_core.goal_of(np.array([x, y, heading_deg, 0.0]))


def test_the_window_is_between_the_posts_one_step_deep_and_45_degrees_wide():
  gate = _gate(400.0, 400.0, 0.0)                 # ship/steer's gate, passed northwards
  reward = lambda *a: goal_core.compute_reward(_achieved(*a), gate, 100.0, -100.0)  # noqa: E731
  assert reward(400.0, 400.0, 0.0) == 99.0        # on the line
  assert reward(400.0, 401.79, 0.0) == 99.0       # just inside one step's sailing
  assert reward(400.0, 401.8, 0.0) == -1.0        # 1.8 m past: the step before saw it
  assert reward(400.0, 399.99, 0.0) == -1.0       # not yet through
  assert reward(350.0, 400.5, 0.0) == 99.0        # at a post
  assert reward(349.9, 400.5, 0.0) == -1.0        # outside it
  assert reward(400.0, 400.5, 44.9) == 99.0
  assert reward(400.0, 400.5, -45.1) == -1.0
  assert reward(400.0, 400.5, 180.0) == -1.0      # through, the wrong way
  assert reward(-0.1, 500.0, 0.0) == -101.0       # off the field


def test_the_hard_gate_is_half_as_wide_and_asks_for_the_heading_within_30_degrees():
  gate = _gate(400.0, 400.0, 0.0)
  hard = goal_core.level_tolerance("hard")
  reward = lambda *a: goal_core.compute_reward(_achieved(*a), gate, 100.0, -100.0,  # noqa: E731
                                               hard)
  assert reward(400.0, 400.5, 0.0) == 99.0
  assert reward(375.0, 400.5, 0.0) == 99.0        # at a post, 25 m from the centre
  assert reward(374.9, 400.5, 0.0) == -1.0        # medium's gate would take it
  assert reward(400.0, 400.5, 29.9) == 99.0
  assert reward(400.0, 400.5, -30.1) == -1.0      # medium's 45 degrees would take it
  np.testing.assert_allclose(goal_core.gate_posts(gate, hard[0]), [[375.0, 400.0],
                                                                   [425.0, 400.0]], atol=1e-12)
  for level in ("easy", "medium"):
    np.testing.assert_array_equal(goal_core.level_tolerance(level), goal_core.STEER_TOLERANCE)
  with pytest.raises(ValueError, match=r"^ship goal: unknown level 'windy'; allowed levels: "):
    goal_core.level_tolerance("windy")


def test_a_turned_gate_is_the_same_rule_turned():
  # The gate heading east (90 deg) at (600, 300): its posts at y = 250 and 350.
  gate = _gate(600.0, 300.0, 90.0)
  np.testing.assert_allclose(goal_core.gate_posts(gate), [[600.0, 350.0], [600.0, 250.0]],
                             atol=1e-12)
  assert goal_core.gate_heading_deg(gate) == pytest.approx(90.0)
  assert goal_core.compute_reward(_achieved(601.0, 349.0, 80.0), gate, 100, -100) == 99.0
  assert goal_core.compute_reward(_achieved(601.0, 351.0, 80.0), gate, 100, -100) == -1.0
  assert goal_core.compute_reward(_achieved(599.0, 300.0, 90.0), gate, 100, -100) == -1.0


def test_compute_reward_takes_any_batch_shape():
  rng = np.random.default_rng(0)
  achieved = np.column_stack([rng.uniform(0, 1000, 60), rng.uniform(0, 1000, 60),
                              np.zeros(60), np.ones(60)]).reshape(3, 20, 4)
  desired = achieved + [0.0, -1.0, 0.0, 0.0]     # each goal 1 m short of its gate: reached
  rewards = goal_core.compute_reward(achieved, desired, 100.0, -100.0)
  assert rewards.shape == (3, 20) and (rewards == 99.0).all()
  one = goal_core.compute_reward(achieved[1, 2], desired[1, 2], 100.0, -100.0)
  assert isinstance(one, float) and one == 99.0
  with pytest.raises(ValueError, match=r"^compute_reward: goals are .* got shapes \(3,\) and"):
    goal_core.compute_reward([1.0, 2.0, 3.0], desired[0, 0], 100.0, -100.0)


def test_every_pass_between_the_posts_with_the_gate_is_seen_at_its_step():
  # Ships sailing straight through the gate at any offset, angle within 40 degrees and
  # phase of their control steps: the step whose end is the first past the line reaches
  # the goal, and no step before it does.
  gate = _gate(500.0, 500.0, 30.0)
  normal = np.array([math.sin(math.radians(30.0)), math.cos(math.radians(30.0))])
  rng = np.random.default_rng(1)
  samples = np.empty((4, 2))
  for _ in range(300):
    lateral, angle = rng.uniform(-48.0, 48.0), rng.uniform(-40.0, 40.0)
    back = rng.uniform(20.0, 25.0)                # metres to sail to the line
    heading = math.radians(30.0 + angle)
    across = math.radians(30.0 + 90.0)
    x = 500.0 + lateral * math.sin(across) - back * math.sin(heading)
    y = 500.0 + lateral * math.cos(across) - back * math.cos(heading)
    state = np.array([x, y, 30.0 + angle, 0.0])
    for _ in range(40):
      core.euler_control(state, 0.0, samples)
      past = (state[:2] - [500.0, 500.0]) @ normal >= 0.0
      reached = goal_core.compute_reward(goal_core.goal_of(state), gate, 100.0, -100.0) == 99.0
      assert reached == past
      if past:
        break
    assert reached


@pytest.mark.parametrize("level", list(goal_core.LEVELS))
def test_each_level_draws_gates_in_its_ranges_with_posts_on_the_field(level):
  low, high, largest = goal_core.LEVELS[level]
  rng = np.random.default_rng(2)
  gates = np.array([goal_core.sample_gate(rng, level)
                    for _ in range(2000)])
  assert gates[:, :2].min() >= low and gates[:, :2].max() <= high
  headings = np.degrees(np.arctan2(gates[:, 2], gates[:, 3]))
  assert np.abs(headings).max() <= largest and np.abs(headings).max() > 0.9 * largest
  np.testing.assert_allclose(np.hypot(gates[:, 2], gates[:, 3]), 1.0)
  posts = np.array([goal_core.gate_posts(g) for g in gates])
  assert posts.min() >= 0.0 and posts.max() <= core.FIELD_SIZE


def test_bad_levels_and_gates_are_one_line_errors():
  with pytest.raises(ValueError, match=r"^ship goal: unknown level 'far'; allowed levels: "
                                       r"\['easy', 'medium', 'hard'\]$"):
    goal_core.level_range("far")
  with pytest.raises(ValueError, match=r"^g: a gate is \[x, y, heading_deg\] \(3 finite numbers\)"):
    goal_core.check_gate([1.0, 2.0], "g")
  with pytest.raises(ValueError, match=r"^g: gate \[20.0, 500.0, 0.0\] puts its posts at "
                                       r".*; allowed: both posts on the field \[0, 1000.0\] m$"):
    goal_core.check_gate([20.0, 500.0, 0.0], "g")


def test_verify_goal_the_two_ships_end_alike():
  results = verify_ladder.verify_goal(episodes=6, seed=1)
  assert [r.level for r in results] == ["easy", "medium", "hard"]
  for result in results:
    assert result.passed, result.line()
    assert result.gate_geoms_m < 1e-9 and result.ranges_m < 1e-6
    # The helmsman lines up with the gate, blind to the hard level's obstacles.
    assert result.analytic_passes >= (5 if result.level != "hard" else 2)
    assert (result.aground > 0) == (result.level == "hard")
