"""The MuJoCo ship against the continuous ODE and the analytic ship (SPEC section 1)."""
import mujoco
import numpy as np
import pytest

from hpg_mj import verify
from hpg_mj.worlds import ship
from hpg_mj.worlds import ship_core as core


@pytest.fixture(scope="module")
def physics():
  return ship.Physics.from_xml_string(*ship.get_model_and_assets())


def test_bow_site_is_half_a_step_ahead(physics):
  # The reported position is the trapezoidal point V*h/2 ahead (assets/ship.xml).
  assert physics.bow_offset() == pytest.approx(core.SPEED * physics.model.opt.timestep / 2)
  assert physics.model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST


def test_state_round_trip(physics):
  state = np.array([123.0, 456.0, -170.0, 7.5])
  physics.set_ship_state(state)
  np.testing.assert_allclose(physics.ship_state(), state, atol=1e-12)


def test_verification_bounds_hold():
  # SPEC section 1: under 0.25 m and 0.25 deg, and at most half the Euler error.
  result = verify.verify_ship(controls=1000, starts=2, seed=7)
  assert result.mujoco_position_m < 0.25
  assert result.mujoco_heading_deg < 0.25
  assert result.mujoco_position_m <= 0.5 * result.euler_position_m
  # The Euler model's own error is real and reported (about half a metre or more).
  assert 0.2 < result.euler_position_m < 3.0


def test_exact_solution_is_exact_for_a_steady_turn():
  # theta_dot = r = 10 deg/s from the start: a circle of radius V / omega.
  omega = np.radians(10.0)
  path = verify.exact_trajectory([0.0, 0.0, 0.0, 10.0], [10.0] * 10)
  t = 0.2 * np.arange(1, 31)
  radius = core.SPEED / omega
  np.testing.assert_allclose(path[:, 0], radius * (1 - np.cos(omega * t)), atol=1e-10)
  np.testing.assert_allclose(path[:, 1], radius * np.sin(omega * t), atol=1e-10)


def test_mujoco_and_analytic_ships_agree(physics):
  rng = np.random.default_rng(3)
  start = np.array([500.0, 500.0, 20.0, -4.0])
  controls = rng.uniform(-15, 15, 150)
  mj = verify.mujoco_trajectory(start, controls, physics)
  eu = verify.euler_trajectory(start, controls)
  # Both approximate the same ODE: Euler's own error bounds their distance.
  assert np.max(np.hypot(*(mj[:, :2] - eu[:, :2]).T)) < 1.0
  assert np.max(np.abs(core.wrap_deg_array(mj[:, 2] - eu[:, 2]))) < 1.0
  np.testing.assert_allclose(mj[:, 3], verify.exact_trajectory(start, controls)[:, 3], atol=1e-9)


def test_speed_is_constant_along_the_heading(physics):
  physics.set_ship_state([500.0, 500.0, 30.0, 15.0])
  physics.set_turn_command(-15.0)
  before = physics.position()
  physics.step(2)
  after = physics.position()
  assert np.hypot(*(after - before)) == pytest.approx(core.SPEED * 0.2, rel=2e-3)


def test_step_must_cover_whole_sampling_intervals(physics):
  with pytest.raises(ValueError, match="whole 0.2 s sampling intervals"):
    physics.step(1)


def _sail(physics, controls):
  physics.set_ship_state([500.0, 500.0, 20.0, -4.0])
  rows = []
  for r in controls:
    physics.set_turn_command(r)
    physics.step(6)
    rows.append(np.concatenate([physics.sampled_positions().ravel(), physics.stepped_state]))
  return np.array(rows)


def test_disabling_the_constraint_stage_changes_no_bit():
  # assets/ship.xml disables the constraint stage: the ship has no constraint to solve,
  # so with the stage enabled there is none either, and the trajectory is the same.
  controls = np.random.default_rng(5).uniform(-15, 15, 200)
  shipped = ship.Physics.from_xml_string(*ship.get_model_and_assets())
  assert shipped.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
  enabled = ship.Physics.from_xml_string(*ship.get_model_and_assets())
  enabled.model.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
  expected = _sail(enabled, controls)
  assert enabled.data.nefc == 0
  np.testing.assert_array_equal(_sail(shipped, controls), expected)


def test_compiled_steps_are_the_bindings_steps_bit_for_bit(monkeypatch):
  # `step` calls MuJoCo's C mj_step from compiled code (ship_model.sail); through the
  # bindings' mj_step (MJ_STEP = 0, where the library is not found) it sails the same.
  from hpg_mj.worlds import ship_model
  assert ship_model.MJ_STEP != 0
  controls = np.random.default_rng(6).uniform(-15, 15, 200)
  compiled = ship.Physics.from_xml_string(*ship.get_model_and_assets())
  through_compiled = _sail(compiled, controls)
  monkeypatch.setattr(ship_model, "MJ_STEP", 0)
  bindings = ship.Physics.from_xml_string(*ship.get_model_and_assets())
  np.testing.assert_array_equal(_sail(bindings, controls), through_compiled)
  np.testing.assert_array_equal(bindings.data.qvel, compiled.data.qvel)
  np.testing.assert_array_equal(bindings.data.act, compiled.data.act)
  assert bindings.data.time == compiled.data.time


def test_profiler_clock_is_stopped_but_a_users_clock_is_kept():
  physics = ship.Physics.from_xml_string(*ship.get_model_and_assets())
  assert mujoco.get_mjcb_time() is not None          # the stopped clock (a C function)
  physics.step(6)
  step_timer = physics.data.timer[mujoco.mjtTimer.mjTIMER_STEP]
  assert step_timer.number == 6 and step_timer.duration == 0.0
  try:
    mujoco.set_mjcb_time(lambda: 1.0)                # the user's own clock
    clock = mujoco.get_mjcb_time()
    ship.Physics.from_xml_string(*ship.get_model_and_assets())
    assert mujoco.get_mjcb_time() is clock
  finally:
    mujoco.set_mjcb_time(None)                       # the bindings' clock, then ours again
    ship.stop_profiler_clock()
  assert mujoco.get_mjcb_time() is not None
