"""The Gymnasium ship environments (SPEC sections 1-3)."""
import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import hpg_mj
from hpg_mj import envs

SHIP_IDS = ["hpg_mj/ShipSteering-v0", "hpg_mj/ShipSteeringDiagonal-v0",
            "hpg_mj/ShipSteeringStraight-v0", "hpg_mj/ShipPatrol-v0"]


def test_import_registers_every_id():
  for env_id in envs.ENV_IDS:
    assert env_id in gymnasium.registry
  assert hpg_mj.__version__


@pytest.mark.parametrize("backend", ["mujoco", "analytic"])
@pytest.mark.parametrize("env_id", SHIP_IDS)
def test_check_env(env_id, backend):
  env = gymnasium.make(env_id, backend=backend)
  check_env(env.unwrapped, skip_render_check=True)
  assert env.observation_space.dtype == np.float64
  assert env.action_space.shape == (1,)
  np.testing.assert_array_equal(env.action_space.low, [-15.0])
  np.testing.assert_array_equal(env.action_space.high, [15.0])


@pytest.mark.parametrize("backend", ["mujoco", "analytic"])
def test_reset_from_an_exact_state(backend):
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend=backend)
  obs, _ = env.reset(options={"state": [100.0, 200.0, 370.0, -3.0]})
  np.testing.assert_allclose(obs, [100.0, 200.0, 10.0, -3.0], atol=1e-12)


@pytest.mark.parametrize("backend", ["mujoco", "analytic"])
def test_passing_the_gate_ends_the_episode(backend):
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend=backend)
  env.reset(options={"state": [400.0, 397.0, 0.0, 0.0]})
  obs, reward, terminated, truncated, info = env.step(np.array([0.0]))
  assert obs[1] == pytest.approx(398.8, abs=1e-6)
  assert (reward, terminated, truncated, info["event"]) == (-1.0, False, False, None)
  obs, reward, terminated, truncated, info = env.step(np.array([0.0]))
  assert (reward, terminated, truncated, info["event"]) == (99.0, True, False, "gate")


def test_leaving_and_time_limit():
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic")
  env.reset(options={"state": [1.0, 500.0, -90.0, 0.0]})
  _, reward, terminated, _, info = env.step(np.array([0.0]))
  assert (reward, terminated, info["event"]) == (-101.0, True, "out_of_bounds")
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic", max_steps=3)
  env.reset(options={"state": [500.0, 800.0, 0.0, 0.0]})
  results = [env.step(np.array([15.0]))[2:4] for _ in range(3)]
  assert results == [(False, False), (False, False), (False, True)]


def test_subtask_starts_at_its_local_start():
  for env_id, start in (("hpg_mj/ShipSteeringDiagonal-v0", [40, 40]),
                        ("hpg_mj/ShipSteeringStraight-v0", [40, 75])):
    env = gymnasium.make(env_id)
    for seed in range(3):
      obs, _ = env.reset(seed=seed)
      np.testing.assert_allclose(obs[:2], start, atol=1e-9)


@pytest.mark.parametrize("bad", [np.array([np.nan]), np.array([np.inf]), np.array([-np.inf])])
def test_non_finite_actions_are_errors(bad):
  env = gymnasium.make("hpg_mj/ShipSteering-v0")
  env.reset(seed=0)
  with pytest.raises(ValueError, match=r"ShipSteering\(steer, backend=mujoco\).*finite.*(nan|inf)"):
    env.step(bad)


@pytest.mark.parametrize("bad", [np.zeros(2), np.zeros((2, 1)), np.array(["a"])])
def test_wrong_shapes_are_errors(bad):
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic")
  env.reset(seed=0)
  with pytest.raises(ValueError, match="ShipSteering"):
    env.step(bad)


def test_out_of_range_rates_are_clipped_or_refused_when_strict():
  a = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic")
  b = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic")
  a.reset(seed=1)
  b.reset(seed=1)
  np.testing.assert_array_equal(a.step(np.array([40.0]))[0], b.step(np.array([15.0]))[0])
  strict = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic", strict=True)
  strict.reset(seed=1)
  with pytest.raises(ValueError, match=r"40.0 is outside the allowed range \[-15.0, 15.0\]"):
    strict.step(np.array([40.0]))


@pytest.mark.parametrize("state,match", [([1200.0, 5.0, 0.0, 0.0], "off the field"),
                                         ([5.0, 5.0, 0.0, -20.0], r"\[-15.0, 15.0\]"),
                                         ([5.0, 5.0, 0.0], "shape")])
def test_impossible_start_states_are_refused(state, match):
  env = gymnasium.make("hpg_mj/ShipSteering-v0")
  with pytest.raises(ValueError, match=match):
    env.reset(options={"state": state})


def test_subtask_start_state_must_lie_in_its_frame():
  env = gymnasium.make("hpg_mj/ShipSteeringDiagonal-v0")
  with pytest.raises(ValueError, match=r"\[0.0, 150.0\]"):
    env.reset(options={"state": [400.0, 40.0, 0.0, 0.0]})


def test_unknown_ids_backends_and_options_list_the_valid_ones():
  with pytest.raises(ValueError, match="valid ids: .*hpg_mj/ShipSteering-v0"):
    envs.make("hpg_mj/ShipSteering-v9")
  with pytest.raises(ValueError, match=r"valid backends: \['mujoco', 'analytic'\]"):
    gymnasium.make("hpg_mj/ShipSteering-v0", backend="bullet")
  env = gymnasium.make("hpg_mj/ShipSteering-v0")
  with pytest.raises(ValueError, match=r"allowed: \['state'\]"):
    env.reset(options={"start": [1, 2, 3, 4]})


@pytest.mark.parametrize("env_id", ["hpg_mj/ShipSteering-v0", "hpg_mj/ShipPatrol-v0",
                                    "hpg_mj/TaxiFuel-v0", "hpg_mj/Taxi-v0"])
def test_a_level_for_a_task_without_levels_names_the_ids_with_levels(env_id):
  # The ladder's argument given to another id: one line, not Gymnasium's TypeError.
  match = (r"has no levels \(level='hard'\); the ids with levels: \['hpg_mj/ShipCurrent-v0', "
           r"'hpg_mj/ShipGoal-v0', 'hpg_mj/ShipRegatta-v0', 'hpg_mj/ShipHarbour-v0'\]$")
  with pytest.raises(ValueError, match=match):
    gymnasium.make(env_id, level="hard")
  with pytest.raises(ValueError, match=match):
    gymnasium.make_vec(env_id, num_envs=2, level="hard")


def test_backends_agree_closely():
  a = gymnasium.make("hpg_mj/ShipSteering-v0", backend="mujoco")
  b = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic")
  state = [300.0, 200.0, 45.0, 5.0]
  oa, _ = a.reset(options={"state": state})
  ob, _ = b.reset(options={"state": state})
  for r in np.linspace(-15, 15, 100):
    oa = a.step(np.array([r]))[0]
    ob = b.step(np.array([r]))[0]
  assert np.hypot(*(oa[:2] - ob[:2])) < 1.0
  assert abs(oa[3] - ob[3]) < 0.2


@pytest.mark.parametrize("backend", ["mujoco", "analytic"])
def test_render_rgb_array(backend):
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend=backend, render_mode="rgb_array",
                       width=160, height=120)
  env.reset(options={"state": [500.0, 500.0, 0.0, 15.0]})
  first = env.render()
  for _ in range(30):
    env.step(np.array([15.0]))
  second = env.render()
  assert first.shape == (120, 160, 3) and first.dtype == np.uint8
  assert first.std() > 5.0                       # not blank
  assert np.abs(first.astype(int) - second).sum() > 0   # the ship moved, the wake grew
  env.close()


@pytest.mark.parametrize("backend", ["mujoco", "analytic"])
def test_patrol_passes_the_gate_again_and_again(backend):
  # SPEC section 8: +100 for each pass, in either direction; the ship sails on.
  env = gymnasium.make("hpg_mj/ShipPatrol-v0", backend=backend)
  env.reset(options={"state": [400.0, 397.0, 0.0, 0.0]})
  env.step(np.array([0.0]))
  obs, reward, terminated, truncated, info = env.step(np.array([0.0]))
  assert (reward, terminated, truncated, info["event"]) == (99.0, False, False, "gate")
  assert obs[1] > 400.0                    # sailed on through, not reset
  env.reset(options={"state": [400.0, 403.0, 180.0, 0.0]})   # southwards this time
  events = [env.step(np.array([0.0]))[4]["event"] for _ in range(2)]
  assert events == [None, "gate"]


def test_patrol_restarts_after_leaving_and_truncates_after_an_hour():
  env = gymnasium.make("hpg_mj/ShipPatrol-v0", backend="analytic")
  assert env.unwrapped.rules.max_steps == 6000          # one hour of 0.6 s steps
  env = gymnasium.make("hpg_mj/ShipPatrol-v0", backend="analytic", max_steps=4,
                       out_of_bounds_reward=-300.0)
  env.reset(seed=5, options={"state": [1.0, 500.0, -90.0, 0.0]})
  obs, reward, terminated, truncated, info = env.step(np.array([0.0]))
  assert (reward, terminated, truncated, info["event"]) == (-301.0, False, False, "out_of_bounds")
  assert info["positions"][-1, 0] < 0.0              # where it left
  assert 0.0 <= obs[0] <= 1000.0 and 0.0 <= obs[1] <= 1000.0   # a fresh start
  assert not np.allclose(obs[:2], info["positions"][-1], atol=5.0)
  results = [env.step(np.array([0.0]))[2:4] for _ in range(3)]
  assert results == [(False, False), (False, False), (False, True)]


def test_patrol_restarts_are_seeded():
  def run(seed):
    env = gymnasium.make("hpg_mj/ShipPatrol-v0", backend="analytic")
    env.reset(seed=seed, options={"state": [1.0, 500.0, -90.0, 0.0]})
    return env.step(np.array([0.0]))[0]
  np.testing.assert_array_equal(run(3), run(3))
  assert not np.array_equal(run(3), run(4))


@pytest.mark.parametrize("state,match", [([1200.0, 5.0, 0.0, 0.0], r"off the field.*\[0.0, 1000.0\]"),
                                         ([5.0, 5.0, 0.0, 16.0], r"\[-15.0, 15.0\]"),
                                         ([5.0, 5.0, np.nan, 0.0], "finite")])
def test_patrol_refuses_impossible_starts(state, match):
  env = gymnasium.make("hpg_mj/ShipPatrol-v0", backend="analytic")
  with pytest.raises(ValueError, match=match):
    env.reset(options={"state": state})


def test_patrol_refuses_bad_actions_and_arguments():
  env = gymnasium.make("hpg_mj/ShipPatrol-v0", backend="analytic", strict=True)
  env.reset(seed=0)
  with pytest.raises(ValueError, match=r"ShipSteering\(patrol, backend=analytic\).*finite"):
    env.step(np.array([np.nan]))
  with pytest.raises(ValueError, match=r"20.0 is outside the allowed range \[-15.0, 15.0\]"):
    env.step(np.array([20.0]))
  with pytest.raises(ValueError, match="max_steps must be a positive number of control steps"):
    gymnasium.make("hpg_mj/ShipPatrol-v0", backend="analytic", max_steps=0)
  with pytest.raises(ValueError, match=r"unknown ship task 'patrl'.*'patrol'"):
    gymnasium.make("hpg_mj/ShipSteering-v0", task="patrl")
