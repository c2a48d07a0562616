"""Golden trajectories of the ship tasks: a dependency upgrade that changes the
physics or the rules is caught here (regenerate with tests/golden/make_golden_ship.py)."""
import importlib.util
import pathlib

import numpy as np
import pytest

GOLDEN = pathlib.Path(__file__).resolve().parent / "golden"
_spec = importlib.util.spec_from_file_location("make_golden_ship", GOLDEN / "make_golden_ship.py")
make_golden_ship = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(make_golden_ship)

# MuJoCo's arithmetic may differ in the last bits across CPUs and builds; a change
# of integrator, actuation or model moves these trajectories by far more.
MUJOCO_TOLERANCE = 1e-6


@pytest.mark.parametrize("task", ["steer", "diagonal", "straight"])
def test_analytic_ship_replays_exactly(task):
  golden = np.load(GOLDEN / f"ship_{task}.npz", allow_pickle=False)
  obs, rewards, ends = make_golden_ship.analytic_rollout(task)
  np.testing.assert_array_equal(obs, golden["analytic_obs"])
  np.testing.assert_array_equal(rewards, golden["analytic_rewards"])
  np.testing.assert_array_equal(ends, golden["analytic_ends"])


@pytest.mark.parametrize("task", ["steer", "diagonal", "straight"])
def test_mujoco_ship_replays_within_tolerance(task):
  golden = np.load(GOLDEN / f"ship_{task}.npz", allow_pickle=False)
  obs, rewards, ends = make_golden_ship.mujoco_rollout(task)
  np.testing.assert_allclose(obs, golden["mujoco_obs"], rtol=0, atol=MUJOCO_TOLERANCE)
  np.testing.assert_allclose(rewards, golden["mujoco_rewards"], rtol=0, atol=MUJOCO_TOLERANCE)
  np.testing.assert_array_equal(ends, golden["mujoco_ends"])
