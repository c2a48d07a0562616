"""The native vector environments (hpg_mj.envs.vector): `gymnasium.make_vec` for every id
follows exactly the single environments that Gymnasium's SyncVectorEnv batches, in each
autoreset mode, and refuses bad input naming the copy and what is allowed."""
import gymnasium
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import hpg_mj  # noqa: F401  (registers the ids)
from hpg_mj.envs import vector

SHIP_IDS = ["hpg_mj/ShipSteering-v0", "hpg_mj/ShipSteeringDiagonal-v0",
            "hpg_mj/ShipSteeringStraight-v0", "hpg_mj/ShipPatrol-v0"]
TAXI_IDS = ["hpg_mj/TaxiFuel-v0", "hpg_mj/Taxi-v0"]
MODES = [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP]


def _pair(env_id, n, mode, **kwargs):
  native = gymnasium.make_vec(env_id, n, vectorization_mode="vector_entry_point",
                              autoreset_mode=mode, **kwargs)
  reference = gymnasium.make_vec(env_id, n, vectorization_mode="sync",
                                 vector_kwargs={"autoreset_mode": mode}, **kwargs)
  return native, reference


def _actions(env_id, rng, n):
  if env_id in TAXI_IDS:
    return rng.integers(0, 7 if "Fuel" in env_id else 6, n)
  return rng.uniform(-20.0, 20.0, (n, 1))   # beyond +-15: clipped alike


def _assert_same_info(native, reference):
  """Same masks (a key the reference lacks: a mask of False), equal entries where set."""
  for key in set(native) - set(reference):
    if key.startswith("_"):
      assert not native[key].any(), key
  assert set(reference) <= set(native)
  for key, value in reference.items():
    if key.startswith("_"):
      np.testing.assert_array_equal(native[key], value, err_msg=key)
    elif isinstance(value, dict):
      _assert_same_info(native[key], value)
    else:
      for i in np.flatnonzero(reference["_" + key]):
        if value[i] is None:
          assert native[key][i] is None, (key, i)
        else:
          np.testing.assert_array_equal(native[key][i], value[i], err_msg=f"{key}[{i}]")


def _run_both(native, reference, env_id, steps, n, seed):
  obs_n, info_n = native.reset(seed=seed)
  obs_r, info_r = reference.reset(seed=seed)
  np.testing.assert_array_equal(obs_n, obs_r)
  _assert_same_info(info_n, info_r)
  rng = np.random.default_rng(seed)
  ends = 0
  for t in range(steps):
    action = _actions(env_id, rng, n)
    out_n, out_r = native.step(action), reference.step(action)
    for name, a, b in zip(("obs", "reward", "terminated", "truncated"), out_n[:4], out_r[:4]):
      np.testing.assert_array_equal(a, b, err_msg=f"{name} at step {t}")
      assert a.dtype == b.dtype, (name, a.dtype, b.dtype)
    _assert_same_info(out_n[4], out_r[4])
    ends += int(out_n[2].sum() + out_n[3].sum())
  return ends


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.value)
@pytest.mark.parametrize("env_id", SHIP_IDS)
def test_analytic_ship_batch_follows_single_envs(env_id, mode):
  # max_steps=40: episodes end by every rule (gate/goal, bounds, time) within the run.
  native, reference = _pair(env_id, 6, mode, backend="analytic", max_steps=40)
  assert isinstance(native.unwrapped, vector.ShipSteeringVectorEnv)
  # The continuing patrol ends only by its clock (3 ends a copy); its restarts after
  # leaving the field draw from each copy's generator, as the single env's do.
  assert _run_both(native, reference, env_id, 150, 6, seed=11) >= (18 if "Patrol" in env_id
                                                                    else 20)


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.value)
@pytest.mark.parametrize("env_id", TAXI_IDS)
def test_taxi_batch_follows_single_envs(env_id, mode):
  native, reference = _pair(env_id, 5, mode, max_steps=30)
  assert isinstance(native.unwrapped, vector.TaxiVectorEnv)
  assert _run_both(native, reference, env_id, 200, 5, seed=4) >= 20


def test_mujoco_ship_batch_follows_single_envs():
  native, reference = _pair("hpg_mj/ShipSteering-v0", 3, AutoresetMode.NEXT_STEP,
                            backend="mujoco", max_steps=12)
  assert _run_both(native, reference, "hpg_mj/ShipSteering-v0", 30, 3, seed=2) >= 6


def test_copy_i_is_the_single_env_seeded_s_plus_i():
  batch = gymnasium.make_vec("hpg_mj/ShipSteering-v0", 4, backend="analytic")
  obs, _ = batch.reset(seed=100)
  singles = [gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic") for _ in range(4)]
  for i, env in enumerate(singles):
    np.testing.assert_array_equal(obs[i], env.reset(seed=100 + i)[0])
  obs, _ = batch.reset(seed=[7, None, 9, None])
  np.testing.assert_array_equal(obs[0], singles[0].reset(seed=7)[0])
  np.testing.assert_array_equal(obs[2], singles[2].reset(seed=9)[0])
  r = np.full((4, 1), 3.0)
  for _ in range(5):
    obs, reward, *_ = batch.step(r)
    expected = singles[2].step(r[2])
  np.testing.assert_array_equal(obs[2], expected[0])
  assert reward[2] == expected[1]


@pytest.mark.parametrize("env_id", SHIP_IDS + TAXI_IDS)
def test_make_vec_gives_the_native_batch_with_its_mode_declared(env_id):
  kwargs = {"backend": "analytic"} if env_id in SHIP_IDS else {}
  env = gymnasium.make_vec(env_id, 3, **kwargs)
  assert isinstance(env, vector._BatchedEnv)
  assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
  assert env.single_observation_space == gymnasium.make(env_id, **kwargs).observation_space
  assert env.action_space.shape[0] == 3 and env.observation_space.shape[0] == 3
  obs, _ = env.reset(seed=0)
  assert env.observation_space.contains(obs)
  env = gymnasium.make_vec(env_id, 3, autoreset_mode="SameStep", **kwargs)
  assert env.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP


def test_next_step_reset_ignores_the_action_and_gives_reward_zero():
  env = gymnasium.make_vec("hpg_mj/ShipSteering-v0", 2, backend="analytic")
  env.reset(seed=0, options={"state": [[1.0, 500.0, -90.0, 0.0], [500.0, 500.0, 0.0, 0.0]]})
  obs, reward, terminated, truncated, info = env.step(np.zeros((2, 1)))
  np.testing.assert_array_equal(reward, [-101.0, -1.0])
  np.testing.assert_array_equal(terminated, [True, False])
  assert list(info["event"]) == ["out_of_bounds", None]
  start = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic").reset(seed=0)[0]
  obs, reward, terminated, truncated, info = env.step(np.full((2, 1), 15.0))
  np.testing.assert_array_equal(obs[0], start)          # copy 0 restarted, seed 0's stream
  np.testing.assert_array_equal(reward, [0.0, -1.0])
  np.testing.assert_array_equal(info["_positions"], [False, True])


def test_same_step_reports_the_final_observation():
  env = gymnasium.make_vec("hpg_mj/ShipSteering-v0", 2, backend="analytic",
                           autoreset_mode="SameStep")
  env.reset(seed=0, options={"state": [1.0, 500.0, -90.0, 0.0]})
  obs, reward, terminated, _, info = env.step(np.zeros((2, 1)))
  np.testing.assert_array_equal(terminated, [True, True])
  np.testing.assert_allclose(info["final_obs"][0], [-0.8, 500.0, -90.0, 0.0], atol=1e-12)
  assert list(info["final_info"]["event"]) == ["out_of_bounds", "out_of_bounds"]
  assert np.all((0.0 <= obs[:, :2]) & (obs[:, :2] <= 1000.0))   # new starts


def test_disabled_mode_resets_with_a_mask_only():
  native, reference = _pair("hpg_mj/TaxiFuel-v0", 3, AutoresetMode.DISABLED, max_steps=2)
  for env in (native, reference):
    env.reset(seed=5)
    env.step(np.array([0, 1, 2]))
    out = env.step(np.array([3, 3, 3]))
    assert out[3].all()
  with pytest.raises(RuntimeError, match=r"copies \[0, 1, 2\] have ended.*reset_mask"):
    native.step(np.array([0, 0, 0]))
  mask = np.array([True, False, True])
  obs_n, info_n = native.reset(options={"reset_mask": mask})
  obs_r, info_r = reference.reset(options={"reset_mask": mask})
  np.testing.assert_array_equal(obs_n, obs_r)
  _assert_same_info(info_n, info_r)


def test_ship_batch_refuses_bad_actions_naming_the_copy():
  env = gymnasium.make_vec("hpg_mj/ShipSteering-v0", 3, backend="analytic")
  with pytest.raises(RuntimeError, match="reset"):
    env.step(np.zeros((3, 1)))
  env.reset(seed=0)
  with pytest.raises(ValueError, match=r"shape \(3, 1\) or \(3,\), got shape \(2, 1\)"):
    env.step(np.zeros((2, 1)))
  with pytest.raises(ValueError, match="copy 1 must be finite, got nan"):
    env.step(np.array([[0.0], [np.nan], [0.0]]))
  with pytest.raises(ValueError, match="must be numbers"):
    env.step(np.array([["a"], ["b"], ["c"]]))
  strict = gymnasium.make_vec("hpg_mj/ShipSteering-v0", 3, backend="analytic", strict=True)
  strict.reset(seed=0)
  with pytest.raises(ValueError, match=r"16.0 of copy 2 is outside the allowed range"):
    strict.step(np.array([0.0, 1.0, 16.0]))
  with pytest.raises(ValueError, match="off the field"):
    env.reset(options={"state": [[5.0, 5.0, 0.0, 0.0]] * 2 + [[5.0, 1005.0, 0.0, 0.0]]})


def test_taxi_batch_refuses_bad_actions_naming_the_copy():
  env = gymnasium.make_vec("hpg_mj/Taxi-v0", 2)
  env.reset(seed=0)
  with pytest.raises(ValueError, match=r"action 6 of copy 1 is not one of 0 South.*5 Dropoff"):
    env.step(np.array([0, 6]))
  with pytest.raises(ValueError, match=r"copy 0 must be an integer in 0..5, got 1.5"):
    env.step(np.array([1.5, 0.0]))
  with pytest.raises(ValueError, match=r"shape \(2,\), got shape \(3,\)"):
    env.step(np.array([0, 0, 0]))
  with pytest.raises(ValueError, match="own destination"):
    env.reset(options={"state": [0, 0, 0, 0]})


@pytest.mark.parametrize("kwargs, message", [
    ({"num_envs": 0}, "num_envs must be a positive integer, got 0"),
    ({"autoreset_mode": "sometimes"}, r"unknown autoreset_mode 'sometimes'; allowed: "
                                      r"\['Disabled', 'NextStep', 'SameStep'\]"),
    ({"backend": "bullet"}, r"unknown ship backend 'bullet'"),
    ({"render_mode": "rgb_array"}, "render_mode 'rgb_array' is not supported by the batch"),
])
def test_ship_batch_refuses_bad_arguments(kwargs, message):
  kwargs = {"num_envs": 2, "backend": "analytic", **kwargs}
  with pytest.raises(ValueError, match=message):
    vector.ShipSteeringVectorEnv(**kwargs)


def test_batch_refuses_bad_seeds_and_options():
  env = gymnasium.make_vec("hpg_mj/TaxiFuel-v0", 3)
  with pytest.raises(ValueError, match=r"one per copy \(3\), got 2"):
    env.reset(seed=[1, 2])
  with pytest.raises(ValueError, match="seed must be None, an int or a list"):
    env.reset(seed=1.5)
  with pytest.raises(ValueError, match=r"unknown reset options \['start'\]; allowed"):
    env.reset(options={"start": 1})
  with pytest.raises(RuntimeError, match="first reset"):
    env.reset(options={"reset_mask": np.array([True, False, False])})
  env.reset(seed=0)
  with pytest.raises(ValueError, match=r"reset_mask'\] must be a bool array of shape \(3,\)"):
    env.reset(options={"reset_mask": np.array([1, 0, 0])})
