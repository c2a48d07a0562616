"""Known answers for the analytic ship and the ship rules (SPEC sections 1-3)."""
import math

import numpy as np
import pytest

from hpg_mj.worlds import ship
from hpg_mj.worlds import ship_core as core


def test_euler_sample_is_equation_1():
  state = np.array([100.0, 200.0, 30.0, 5.0])
  core.euler_sample(state, 15.0, 3.0, 5.0, 0.2)
  assert state[0] == pytest.approx(100.0 + 0.2 * 3.0 * math.sin(math.radians(30.0)), abs=1e-12)
  assert state[1] == pytest.approx(200.0 + 0.2 * 3.0 * math.cos(math.radians(30.0)), abs=1e-12)
  assert state[2] == pytest.approx(31.0, abs=1e-12)
  assert state[3] == pytest.approx(5.0 + 0.2 * (15.0 - 5.0) / 5.0, abs=1e-12)


def test_heading_zero_is_north_and_positive_turns_towards_east():
  state = np.array([500.0, 500.0, 0.0, 0.0])
  samples = np.empty((4, 2))
  core.euler_control(state, 0.0, samples)
  np.testing.assert_allclose(state[:2], [500.0, 501.8], atol=1e-12)
  state = np.array([500.0, 500.0, 90.0, 0.0])
  core.euler_control(state, 0.0, samples)
  np.testing.assert_allclose(state[:2], [501.8, 500.0], atol=1e-12)


@pytest.mark.parametrize("angle,wrapped", [(180.0, -180.0), (-180.0, -180.0), (190.0, -170.0),
                                           (-181.0, 179.0), (720.0, 0.0), (359.5, -0.5)])
def test_wrap_deg(angle, wrapped):
  assert core.wrap_deg(angle) == pytest.approx(wrapped)


def _steer_event(points):
  return core.steer_event(np.array(points, dtype=float), core.GATE, core.FIELD_SIZE)


@pytest.mark.parametrize("points", [
    [(400, 399), (400, 401)],            # south to north through the middle
    [(400, 401), (400, 399)],            # north to south
    [(360, 390), (362, 400.5)],          # near the west post
    [(350, 399), (350, 401)],            # exactly at a post counts (between posts, inclusive)
    [(449.9, 402), (449.9, 398)],
    [(300, 398), (300, 399), (400, 399.5), (400.2, 400.7)],  # crossing in the third segment
])
def test_gate_crossed_between_posts_from_either_side(points):
  event, k = _steer_event(points)
  assert event == core.SUCCESS
  assert k == len(points) - 1


@pytest.mark.parametrize("points", [
    [(349, 399), (349, 401)],            # west of the posts
    [(451, 401), (451, 399)],            # east of the posts
    [(360, 400), (440, 400)],            # sailing along the gate line is no crossing
    [(400, 390), (400, 399.99)],         # short of the line
])
def test_gate_not_crossed(points):
  assert _steer_event(points) == (core.NO_EVENT, 0)


def test_stopping_on_the_gate_line_counts_once():
  assert _steer_event([(400, 399), (400, 400)])[0] == core.SUCCESS
  assert _steer_event([(400, 400), (400, 401)])[0] == core.NO_EVENT


@pytest.mark.parametrize("start,end", [((0.5, 500), (-0.1, 500)), ((999.5, 500), (1000.1, 500)),
                                       ((500, 0.5), (500, -0.1)), ((500, 999.5), (500, 1000.1))])
def test_each_boundary_left_is_failure(start, end):
  assert _steer_event([start, end]) == (core.FAILURE, 1)


def test_on_the_boundary_is_still_inside():
  assert _steer_event([(1, 500), (0, 500)]) == (core.NO_EVENT, 0)


def test_first_event_wins():
  # Through the gate in the first segment, then (impossibly fast) out of the field.
  assert _steer_event([(400, 399), (400, 401), (400, 1001)]) == (core.SUCCESS, 1)


def test_steer_rewards():
  rules = ship.ShipRules("steer")
  state = np.array([500.0, 500.0, 0.0, 0.0])
  assert rules.evaluate(np.array([[500, 500], [500, 501]]), state, 1) == (-1.0, False, False, None)
  assert rules.evaluate(np.array([[400, 399], [400, 401]]), state, 1) == (99.0, True, False, "gate")
  assert rules.evaluate(np.array([[1, 5], [-1, 5]]), state, 1) == (-101.0, True, False,
                                                                    "out_of_bounds")
  # The time limit truncates; it is not a failure.
  assert rules.evaluate(np.array([[500, 500], [500, 501]]), state, 5000) == (-1.0, False, True,
                                                                              None)


def test_evaluate_reads_any_kind_of_array_and_refuses_a_wrong_shape():
  """`evaluate` hands `judge` (numba's entry point, which would misread them) float64
  arrays in C order: integer, Fortran-ordered and strided samples give what their
  values give; samples that are not rows of (x, y), or a state not of four numbers,
  are refused in one line."""
  rules = ship.ShipRules("steer")
  state = np.array([500.0, 500.0, 0.0, 0.0])
  samples = np.array([[400.0, 399.0], [400.0, 401.0]])
  expected = (99.0, True, False, "gate")
  wide = np.zeros((2, 4))
  wide[:, ::2] = samples
  for kind in (samples.astype(np.int64), np.asfortranarray(samples), wide[:, ::2]):
    assert rules.evaluate(kind, state[::1], 1) == expected
  assert rules.evaluate(samples, np.repeat(state, 2)[::2], 1) == expected
  for bad_samples, bad_state in ((samples.ravel(), state), (samples, state[:3])):
    with pytest.raises(ValueError, match=r"^ShipRules.evaluate: samples must be rows of "
                                         r"\(x, y\) and end_state .*, got shapes"):
      rules.evaluate(bad_samples, bad_state, 1)


def test_shaping_reward():
  # Pointing straight at the goal: G = 0; 30 degrees off: exp(-1) - 1.
  assert core.shaping_reward(40.0, 40.0, 45.0, 140.0, 140.0) == pytest.approx(0.0, abs=1e-12)
  assert core.shaping_reward(40.0, 40.0, 75.0, 140.0, 140.0) == pytest.approx(math.exp(-1) - 1)
  assert core.shaping_reward(40.0, 40.0, 15.0, 140.0, 140.0) == pytest.approx(math.exp(-1) - 1)
  # The difference is wrapped: goal due south (bearing 180), heading -179 -> 1 degree off.
  assert core.shaping_reward(75.0, 100.0, -179.0, 75.0, 0.0) == pytest.approx(
      math.exp(-1 / 900) - 1)


@pytest.mark.parametrize("kind", ["diagonal", "straight"])
def test_subtask_success_failure_and_timeout(kind):
  rules = ship.ShipRules(kind)
  gx, gy = rules.goal
  heading = 45.0 if kind == "diagonal" else 90.0
  end = np.array([gx - 5.0, gy, heading, 0.0])
  g = core.shaping_reward(end[0], end[1], end[2], gx, gy)
  reward, terminated, truncated, event = rules.evaluate(
      np.array([[gx - 12.0, gy], [gx - 9.0, gy]]), end, 10)
  assert (terminated, truncated, event) == (True, False, "goal")
  assert reward == pytest.approx(-1.0 + g + 100.0)
  for outside in ([-0.5, 75.0], [150.5, 75.0], [75.0, -0.5], [75.0, 150.5]):
    start = np.clip(outside, 0.0, 150.0)
    reward, terminated, _, event = rules.evaluate(np.array([start, outside]),
                                                  np.array([*outside, 0.0, 0.0]), 10)
    assert (terminated, event) == (True, "out_of_bounds")
  mid = np.array([75.0, 75.0, 0.0, 0.0])
  g = core.shaping_reward(75.0, 75.0, 0.0, gx, gy)
  assert rules.evaluate(np.array([[75.0, 74.0], [75.0, 75.0]]), mid, 299) == (
      pytest.approx(-1.0 + g), False, False, None)
  reward, terminated, truncated, event = rules.evaluate(np.array([[75.0, 74.0], [75.0, 75.0]]),
                                                        mid, 300)
  assert (terminated, truncated, event) == (True, False, "timeout")
  assert reward == pytest.approx(-1.0 + g - 100.0)


def _sail(state, controls):
  """Sails a state through controls; returns every sampled state (analytic ship)."""
  s = np.array(state, dtype=float)
  out = []
  for r in controls:
    for _ in range(3):
      core.euler_sample(s, r, core.SPEED, core.TIME_CONSTANT, core.SAMPLING_INTERVAL)
      out.append(s.copy())
  return np.array(out)


@pytest.mark.parametrize("direction", range(8))
def test_local_frame_is_an_isometry_of_the_dynamics(direction):
  rng = np.random.default_rng(direction)
  origin = np.array([600.0, 300.0])
  start = np.array([*origin, rng.uniform(-180, 180), rng.uniform(-15, 15)])
  controls = rng.uniform(-15, 15, 200)
  local = np.empty(4)
  core.global_to_local(start, origin, direction, local)
  sx, sy = core.local_start(direction)
  assert local[:2] == pytest.approx([sx, sy])
  # Sailing globally and mapping each state == sailing in the local frame.
  global_path = _sail(start, controls)
  local_path = _sail(local, controls)
  mapped = np.empty(4)
  for g, l in zip(global_path, local_path):
    core.global_to_local(g, origin, direction, mapped)
    assert mapped[:2] == pytest.approx(l[:2], abs=1e-8)
    assert core.wrap_deg(mapped[2] - l[2]) == pytest.approx(0.0, abs=1e-8)
    assert mapped[3] == pytest.approx(l[3], abs=1e-12)
  # The local goal lies in the global direction 45 * direction degrees.
  goal = np.array([*core.local_goal(direction), 0.0, 0.0])
  goal_global = np.empty(4)
  core.local_to_global(goal, origin, direction, goal_global)
  offset = goal_global[:2] - origin
  assert math.degrees(math.atan2(offset[0], offset[1])) % 360.0 == pytest.approx(
      (45.0 * direction) % 360.0)
  assert np.hypot(*offset) == pytest.approx(100.0 * (math.sqrt(2) if direction % 2 else 1.0))
  # Sampled positions map like states, and the two maps are inverse.
  local_samples = np.empty((len(global_path), 2))
  core.samples_to_local(global_path[:, :2].copy(), origin, direction, local_samples)
  np.testing.assert_allclose(local_samples, local_path[:, :2], atol=1e-8)
  back = np.empty(4)
  core.local_to_global(local_path[-1], origin, direction, back)
  np.testing.assert_allclose(back[:2], global_path[-1, :2], atol=1e-8)


def test_batch_matches_single_ships():
  rng = np.random.default_rng(0)
  states = np.column_stack([rng.uniform(0, 1000, 5), rng.uniform(0, 1000, 5),
                            rng.uniform(-180, 180, 5), rng.uniform(-15, 15, 5)])
  r = rng.uniform(-15, 15, 5)
  expected = states.copy()
  one = np.empty((4, 2))
  for i in range(5):
    core.euler_control(expected[i], r[i], one)
  samples = np.empty((5, 4, 2))
  core.euler_batch(states, r, samples)
  np.testing.assert_array_equal(states, expected)


@pytest.mark.parametrize("bad,match", [
    ([1, 2, 3], "shape"), ([np.nan, 1, 0, 0], "x must be finite"),
    ([1001, 5, 0, 0], "off the field"), ([5, -1, 0, 0], "off the field"),
    ([5, 5, 0, 16], "theta_dot_deg=16"), ([5, 5, np.inf, 0], "theta_deg must be finite")])
def test_impossible_states_are_refused(bad, match):
  with pytest.raises(ValueError, match=match):
    core.check_state(bad, "ship-steer")


def test_scripted_pilot_passes_the_gate_mostly():
  rules = ship.ShipRules("steer")
  rng = np.random.default_rng(0)
  samples = np.empty((4, 2))
  passed = 0
  for _ in range(40):
    s, phase = rules.sample_start(rng), 0
    for t in range(1, 5001):
      x, y, phase = core.gate_pilot_target(s, phase)
      core.euler_control(s, core.pilot_turn_rate(s, x, y), samples)
      _, terminated, truncated, event = rules.evaluate(samples, s, t)
      if terminated or truncated:
        break
    passed += event == "gate"
  assert passed >= 36


def test_wrap_deg_is_the_float_modulo_to_the_bit():
  # wrap_deg skips the fmod where it knows the answer; it must equal the formula exactly.
  rng = np.random.default_rng(0)
  edges = [-900.0, -540.0, -540.0000000000001, -539.9999999999999, -180.0, -180.00000000000003,
           -0.0, 0.0, 5e-324, 179.99999999999997, 180.0, 539.9999999999999, 540.0, 900.0,
           1e300, -1e300, math.inf, -math.inf, math.nan]
  angles = np.concatenate([edges, rng.uniform(-185.0, 185.0, 20000),
                           rng.uniform(-2000.0, 2000.0, 20000)])
  for angle in angles.tolist():
    expected = (angle + 180.0) % 360.0 - 180.0
    got = core.wrap_deg(angle)
    assert (got == expected or (math.isnan(got) and math.isnan(expected))), angle
    assert math.copysign(1.0, got) == math.copysign(1.0, expected), angle
