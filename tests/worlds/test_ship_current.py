"""The ship in a current (hpg_mj.worlds.ship_current_core, ship_current): the field of
each level, Equation 1 with the drift, and the MuJoCo ship against both."""
import math

import numpy as np
import pytest

from hpg_mj import verify
from hpg_mj import verify_ladder
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_current
from hpg_mj.worlds import ship_current_core as current_core
from hpg_mj.worlds import ship_model


def test_the_field_of_each_level_at_known_points():
  hard = current_core.level_field("hard")
  assert current_core.current_at(hard, 0.0, 500.0) == (2.7, -0.8)         # mid-river, west
  assert current_core.current_at(hard, 1000.0, 0.0) == (0.5, 0.8)         # edge, east
  assert current_core.current_at(hard, 500.0, 250.0) == pytest.approx((0.5 + 2.2 * 0.75, 0.0))
  assert current_core.current_at(hard, -5.0, 1003.0) == (0.5, -0.8)       # clamped outside
  medium = current_core.level_field("medium")
  assert current_core.current_at(medium, 123.0, 500.0) == (2.0, 0.0)
  easy = current_core.level_field("easy")
  assert current_core.current_at(easy, 77.0, 901.0) == (1.0, 0.0)
  assert [current_core.max_speed(current_core.LEVELS[lv]) for lv in ("easy", "medium")] == \
      [1.0, 2.0]
  assert current_core.max_speed(hard) == pytest.approx(math.hypot(2.7, 0.8))   # 2.82 < 3 m/s
  assert current_core.max_speed(hard) < core.SPEED


def test_still_water_is_the_steering_ship_bit_for_bit():
  rng = np.random.default_rng(0)
  a = np.array([300.0, 600.0, 40.0, -5.0])
  b = a.copy()
  samples_a, samples_b = np.empty((4, 2)), np.empty((4, 2))
  for r in rng.uniform(-15, 15, 200):
    core.euler_control(a, r, samples_a)
    current_core.drift_control(b, r, samples_b, np.zeros(4))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(samples_a, samples_b)


def test_a_uniform_current_carries_the_ship_by_its_speed_times_the_time():
  # easy: 1 m/s east; 100 controls (60 s) sail the still-water track moved 60 m east.
  rng = np.random.default_rng(1)
  still = np.array([300.0, 600.0, 40.0, -5.0])
  moving = still.copy()
  samples = np.empty((4, 2))
  for r in rng.uniform(-15, 15, 100):
    core.euler_control(still, r, samples)
    current_core.drift_control(moving, r, samples, current_core.level_field("easy"))
  np.testing.assert_allclose(moving - still, [60.0, 0.0, 0.0, 0.0], atol=1e-9)


def test_the_batch_is_the_single_ship():
  field = current_core.level_field("hard")
  rng = np.random.default_rng(2)
  states = np.column_stack([rng.uniform(0, 1000, 5), rng.uniform(0, 1000, 5),
                            rng.uniform(-180, 180, 5), rng.uniform(-15, 15, 5)])
  singles = states.copy()
  active = np.array([True, False, True, True, True])
  samples = np.zeros((5, 4, 2))
  r = rng.uniform(-15, 15, 5)
  current_core.drift_batch(states, r, active, samples, field)
  for i in range(5):
    one = np.empty((4, 2))
    if active[i]:
      current_core.drift_control(singles[i], r[i], one, field)
      np.testing.assert_array_equal(samples[i], one)
    np.testing.assert_array_equal(states[i], singles[i])


def test_an_unknown_level_is_a_one_line_error_naming_the_allowed():
  with pytest.raises(ValueError, match=r"^ship current: unknown level 'stormy'; allowed levels: "
                                       r"\['easy', 'medium', 'hard'\]$"):
    current_core.level_field("stormy")


def test_the_mujoco_ship_crabs_with_the_water():
  # Heading north in the easy current: 1 m/s east over ground, 3 m/s north.
  physics = ship_current.Physics.from_xml_string(*ship_current.get_model_and_assets())
  physics.set_field(current_core.level_field("easy"))
  physics.set_ship_state([500.0, 500.0, 0.0, 0.0])
  physics.set_turn_command(0.0)
  physics.step(2 * core.SAMPLES_PER_CONTROL * 10)       # 10 controls, 6 s
  np.testing.assert_allclose(physics.position(), [506.0, 518.0], atol=1e-3)
  assert physics.heading_deg() == 0.0
  np.testing.assert_array_equal(physics.current(), [1.0, 0.0])


@pytest.mark.parametrize("level", list(current_core.LEVELS))
def test_both_ships_within_spec_bounds_of_the_continuous_ship(level):
  # SPEC section 1's bounds, kept in the current (`hpg-mj verify current`, shorter).
  result, = verify_ladder.verify_current(controls=150, starts=1, seed=3, levels=[level])
  assert result.passed, result.line()
  assert result.mujoco_position_m < 0.05 and result.euler_position_m > 0.05


def test_the_reference_solution_is_exact_for_uniform_water():
  # A uniform current adds c * t to the still-water solution (closed form there).
  controls = np.random.default_rng(4).uniform(-15, 15, 20)
  start = [200.0, 300.0, 10.0, 2.0]
  still = verify.exact_trajectory(start, controls)
  moving = verify_ladder.exact_current_trajectory(start, controls, [0.7, -0.4, 0.0, 0.0])
  t = core.SAMPLING_INTERVAL * np.arange(1, len(still) + 1)
  np.testing.assert_allclose(moving[:, 0] - still[:, 0], 0.7 * t, atol=1e-6)
  np.testing.assert_allclose(moving[:, 1] - still[:, 1], -0.4 * t, atol=1e-6)


def test_compiled_steps_are_the_bindings_steps_bit_for_bit(monkeypatch):
  def sail(compiled):
    monkeypatch.setattr(ship_model, "MJ_STEP", ship_model.MJ_STEP if compiled else 0)
    physics = ship_current.Physics.from_xml_string(*ship_current.get_model_and_assets())
    physics.set_field(current_core.level_field("hard"))
    physics.set_ship_state([100.0, 450.0, 70.0, 3.0])
    out = []
    for r in np.random.default_rng(5).uniform(-15, 15, 30):
      physics.set_turn_command(r)
      physics.step(6)
      out.append(physics.stepped_state.copy())
    return np.array(out)
  assert ship_model.MJ_STEP
  np.testing.assert_array_equal(sail(True), sail(False))


def test_cli_verify_current(capsys):
  from hpg_mj import cli
  assert cli.main(["verify", "current", "--controls", "100", "--starts", "1"]) == 0
  out = capsys.readouterr().out.splitlines()
  assert [line.split()[0] for line in out[1:4]] == ["easy", "medium", "hard"]
  assert out[-1].endswith("met") and "NOT" not in out[-1]
