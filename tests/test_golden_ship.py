"""Golden trajectories of the ship tasks: a dependency upgrade that changes the
physics or the rules is caught here (regenerate with tests/golden/make_golden_ship.py);
and `hpg-mj verify golden`, which replays every task's for a user."""
import pathlib
import shutil

import numpy as np
import pytest

import hpg_mj
from hpg_mj import cli, suite, verify

GOLDEN = verify.golden_dir()


def test_the_golden_trajectories_ship_inside_the_package():
  assert GOLDEN == pathlib.Path(hpg_mj.__file__).resolve().parent / "golden"
  assert sorted(p.name for p in GOLDEN.glob("*.npz")) == sorted(
      f"{domain}_{task}.npz" for domain, task in suite.ALL_TASKS)


@pytest.mark.parametrize("task", ["steer", "diagonal", "straight", "patrol"])
def test_analytic_ship_replays_exactly(task):
  golden = np.load(GOLDEN / f"ship_{task}.npz", allow_pickle=False)
  np.testing.assert_array_equal(golden["actions"], verify.ship_golden_actions(task))
  obs, rewards, ends = verify.ship_analytic_rollout(task)
  np.testing.assert_array_equal(obs, golden["analytic_obs"])
  np.testing.assert_array_equal(rewards, golden["analytic_rewards"])
  np.testing.assert_array_equal(ends, golden["analytic_ends"])


@pytest.mark.parametrize("task", ["steer", "diagonal", "straight", "patrol"])
def test_mujoco_ship_replays_within_tolerance(task):
  golden = np.load(GOLDEN / f"ship_{task}.npz", allow_pickle=False)
  obs, rewards, ends = verify.ship_mujoco_rollout(task)
  tol = verify.MUJOCO_TOLERANCE
  np.testing.assert_allclose(obs, golden["mujoco_obs"], rtol=0, atol=tol)
  np.testing.assert_allclose(rewards, golden["mujoco_rewards"], rtol=0, atol=tol)
  np.testing.assert_array_equal(ends, golden["mujoco_ends"])


@pytest.mark.parametrize("path", ["analytic", "mujoco"])
def test_the_patrol_golden_holds_a_gate_pass_and_a_restart(path):
  # The continuing task's defining events (SPEC section 8): the gate passed without
  # an end, then the field left (-100 - 1) and the ship put at a fresh start.
  golden = np.load(GOLDEN / "ship_patrol.npz", allow_pickle=False)
  rewards, obs = golden[f"{path}_rewards"], golden[f"{path}_obs"]
  assert not golden[f"{path}_ends"].any()                     # nothing ends the process
  gate, = np.nonzero(rewards == 99.0)
  left, = np.nonzero(rewards == -101.0)
  assert len(gate) == 1 and len(left) == 1 and gate[0] < left[0]
  before, after = obs[left[0]], obs[left[0] + 1]
  assert before[0] < 2.0                                      # about to cross x = 0
  assert np.all((after[:2] >= 0.0) & (after[:2] <= 1000.0))
  assert np.hypot(*(after[:2] - before[:2])) > 50.0          # a jump, not a step


def test_verify_golden_passes_every_task_and_fails_a_changed_one(tmp_path, capsys, monkeypatch):
  assert cli.main(["verify", "golden"]) == 0
  out = capsys.readouterr().out.splitlines()
  rows = [line.split() for line in out[1:-1]]
  assert [r[0] for r in rows] == ["ship/steer"] * 2 + ["ship/diagonal"] * 2 + \
      ["ship/straight"] * 2 + ["ship/patrol"] * 2 + ["taxi/fuel", "taxi/classic"] + \
      [f"{domain}/{level}" for domain in ("ship_current", "ship_goal", "ship_regatta",
                                           "ship_harbour")
       for level in ("easy", "medium", "hard") for _ in range(2)]
  assert all("pass" in r for r in rows), out
  assert "largest deviation 0 (tolerance exact)" in out[1]          # the analytic ship
  assert "(tolerance 1e-06)" in out[2]                              # the MuJoCo ship
  assert out[-1] == "  34 of 34 passed"
  # A stored trajectory that the installed code no longer gives fails, with its deviation.
  changed = tmp_path / "golden"
  shutil.copytree(GOLDEN, changed)
  with np.load(changed / "ship_diagonal.npz") as golden:
    arrays = dict(golden)
  arrays["mujoco_obs"] = arrays["mujoco_obs"] + 1e-3
  np.savez(changed / "ship_diagonal.npz", **arrays)
  (changed / "taxi_classic.npz").unlink()
  monkeypatch.setattr(verify, "golden_dir", lambda: changed)
  assert cli.main(["verify", "golden"]) == 1
  out = capsys.readouterr().out
  assert "ship/diagonal  MuJoCo (dm_control)    FAIL  largest deviation 0.001 (tolerance 1e-06)" in out
  assert "taxi/classic   -                      FAIL  no golden trajectory stored" in out
  assert "32 of 34 passed; FAILED: ship/diagonal MuJoCo (dm_control), taxi/classic -" in out
