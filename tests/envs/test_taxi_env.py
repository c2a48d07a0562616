"""The taxi environments: Gymnasium's `hpg_mj/TaxiFuel-v0` and `hpg_mj/Taxi-v0`,
and the dm_control tasks of `hpg_mj.worlds.taxi` (SPEC section 5)."""
import warnings

import dm_env
import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import hpg_mj  # noqa: F401  (registers the ids)
from hpg_mj import verify
from hpg_mj.envs.taxi import TaxiEnv
from hpg_mj.worlds import taxi
from hpg_mj.worlds import taxi_core as tc

GOLDEN = verify.golden_dir()      # the trajectories shipped in the package
IDS = ("hpg_mj/TaxiFuel-v0", "hpg_mj/Taxi-v0")


def make(env_id="hpg_mj/TaxiFuel-v0", **kwargs):
  return gymnasium.make(env_id, **kwargs).unwrapped


# --- Gymnasium ---------------------------------------------------------------

@pytest.mark.parametrize("env_id", IDS)
def test_check_env_passes_without_warnings(env_id):
  env = make(env_id)
  with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    check_env(env)
  assert [str(w.message) for w in caught] == []


def test_spaces():
  fuel, classic = make(IDS[0]), make(IDS[1])
  assert fuel.observation_space == gymnasium.spaces.MultiDiscrete([5, 5, 5, 4, 13])
  assert classic.observation_space == gymnasium.spaces.MultiDiscrete([5, 5, 5, 4])
  assert fuel.observation_space.dtype == np.int64
  assert fuel.action_space == gymnasium.spaces.Discrete(7)
  assert classic.action_space == gymnasium.spaces.Discrete(6)
  assert TaxiEnv.metadata == {"render_modes": ["rgb_array"], "render_fps": 4}
  assert gymnasium.spec(IDS[0]).max_episode_steps is None   # the env truncates itself


def test_reset_is_seeded_and_starts_legally():
  env = make()
  starts = set()
  for seed in range(40):
    obs, info = env.reset(seed=seed)
    again, _ = env.reset(seed=seed)
    np.testing.assert_array_equal(obs, again)
    row, col, passenger, destination, fuel = obs
    assert passenger < 4 and destination != passenger and 5 <= fuel <= 12
    assert info["action_mask"].dtype == np.int8 and info["action_mask"].shape == (7,)
    starts.add(tuple(obs))
  assert len(starts) > 30


def test_reset_from_a_given_state_and_step():
  env = make()
  obs, info = env.reset(options={"state": [2, 2, tc.IN_TAXI, 1, 3]})
  np.testing.assert_array_equal(obs, [2, 2, 4, 1, 3])
  np.testing.assert_array_equal(info["action_mask"], [1, 1, 1, 1, 0, 0, 0])
  obs, reward, terminated, truncated, _ = env.step(1)   # North
  np.testing.assert_array_equal(obs, [1, 2, 4, 1, 2])
  assert (reward, terminated, truncated) == (-1.0, False, False)
  obs[0] = 99                                            # the env keeps its own copy
  np.testing.assert_array_equal(env.step(2)[0], [1, 3, 4, 1, 1])

  classic = make(IDS[1])
  obs, _ = classic.reset(options={"state": np.array([4, 3, 4, 3])})
  obs, reward, terminated, truncated, _ = classic.step(5)   # deliver at B
  np.testing.assert_array_equal(obs, [4, 3, 3, 3])
  assert (reward, terminated, truncated) == (20.0, True, False)


def test_delivery_with_fuel_and_running_dry():
  env = make()
  env.reset(options={"state": [0, 3, 4, 1, 2]})
  assert env.step(2)[1:4] == (-1.0, False, False)          # East to G, fuel 1
  obs, reward, terminated, truncated, _ = env.step(5)      # deliver with the last unit
  np.testing.assert_array_equal(obs, [0, 4, 1, 1, 0])
  assert (reward, terminated, truncated) == (20.0, True, False)
  env.reset(options={"state": [0, 3, 4, 1, 0]})
  obs, reward, terminated, truncated, _ = env.step(2)
  np.testing.assert_array_equal(obs, [0, 3, 4, 1, 0])
  assert (reward, terminated, truncated) == (-20.0, True, False)


def test_truncation_at_200_steps():
  # Fillup at F costs no fuel, so the taxi can wait there for ever: truncated at 200.
  env = make()
  env.reset(options={"state": [2, 1, 0, 3, 12]})
  for t in range(1, 201):
    _, reward, terminated, truncated, _ = env.step(6)
    assert reward == -1.0 and not terminated
    assert truncated == (t == 200)
  with pytest.raises(RuntimeError, match="episode has ended; call reset"):
    env.step(6)
  classic = make(IDS[1])
  classic.reset(options={"state": [0, 2, 0, 3]})
  results = [classic.step(1)[2:4] for _ in range(200)]   # North into the border
  assert results[-1] == (False, True) and all(r == (False, False) for r in results[:-1])


def test_not_strict_steps_on_and_accepts_gymnasium_states():
  env = make(strict=False)
  obs, _ = env.reset(options={"state": [0, 0, 1, 1, 5]})   # passenger at its destination
  np.testing.assert_array_equal(obs, [0, 0, 1, 1, 5])
  env.reset(options={"state": [4, 3, 4, 3, 5]})
  assert env.step(5)[2] is True
  obs, reward, terminated, _, _ = env.step(1)               # after the end: allowed
  np.testing.assert_array_equal(obs, [3, 3, 3, 3, 3])


@pytest.mark.parametrize("env_id,action,message", [
    (IDS[0], np.nan, "hpg_mj/TaxiFuel-v0: action must be finite, got nan"),
    (IDS[0], 2.5, r"hpg_mj/TaxiFuel-v0: action must be an integer in 0..6, got 2.5"),
    (IDS[0], 7, r"hpg_mj/TaxiFuel-v0: action 7 is not one of 0 South, .*, 6 Fillup"),
    (IDS[1], 6, r"hpg_mj/Taxi-v0: action 6 is not one of 0 South, .*, 5 Dropoff$"),
    (IDS[1], -1, r"hpg_mj/Taxi-v0: action -1 is not one of"),
    (IDS[0], np.array([1, 2]), r"action must be a single integer, got shape \(2,\)"),
    (IDS[0], "north", "action must be an integer, got 'north'"),
])
def test_bad_actions_raise(env_id, action, message):
  env = make(env_id)
  env.reset(seed=0)
  with pytest.raises(ValueError, match=message):
    env.step(action)


def test_integral_actions_of_other_types_are_accepted():
  env = make()
  env.reset(options={"state": [2, 2, 0, 1, 5]})
  for action in (np.int32(1), np.array([1]), 1.0):
    env.step(action)
  np.testing.assert_array_equal(env.state, (0, 2, 0, 1, 2))


@pytest.mark.parametrize("env_id,state,message", [
    (IDS[0], [0, 5, 0, 1, 5], "hpg_mj/TaxiFuel-v0: state col=5 is off the grid; allowed 0..4"),
    (IDS[0], [0, 0, 2, 2, 5], r"passenger=2 waits at its own destination 2 \(Y\)"),
    (IDS[0], [0, 0, 0, 1, 13], "fuel=13 is outside the tank; allowed 0..12"),
    (IDS[0], [0, 0, 0, 1], r"a state is \[row, col, passenger, destination, fuel\]"),
    (IDS[1], [0, 0, 0, 1, 5], r"hpg_mj/Taxi-v0: a state is \[row, col, passenger, destination\]"),
    (IDS[1], [0, 0, 6, 1], "passenger=6 is not allowed; allowed 0..4"),
])
def test_impossible_states_raise(env_id, state, message):
  with pytest.raises(ValueError, match=message):
    make(env_id).reset(options={"state": state})


def test_bad_construction_and_options_raise():
  with pytest.raises(ValueError, match="render_mode 'human' is not supported"):
    TaxiEnv(render_mode="human")
  with pytest.raises(ValueError, match="width must be an integer in 1..1280"):
    TaxiEnv(width=0)
  with pytest.raises(ValueError, match="unknown reset option.*'start'.*allowed: 'state'"):
    make().reset(options={"start": [0, 0, 0, 1, 5]})
  with pytest.raises(RuntimeError, match="call reset"):
    make().step(0)


def test_render_shows_the_board_and_follows_the_taxi():
  env = make(render_mode="rgb_array", width=160, height=160)
  env.reset(options={"state": [2, 2, 0, 1, 7]})
  first = env.render()
  assert first.shape == (160, 160, 3) and first.dtype == np.uint8
  assert first.std() > 20 and len(np.unique(first.reshape(-1, 3), axis=0)) > 20
  env.step(1)
  second = env.render()
  assert np.abs(first.astype(int) - second.astype(int)).sum(axis=-1).astype(bool).sum() > 100
  env.close()
  with pytest.raises(ValueError, match="render_mode='rgb_array'"):
    make().render()


# --- dm_control --------------------------------------------------------------

def test_dm_control_specs_and_observations():
  env = taxi.fuel(random=0)
  assert env.action_spec().num_values == 7
  assert taxi.classic(random=0).action_spec().num_values == 6
  spec = env.observation_spec()
  assert list(spec) == ["taxi", "passenger", "destination", "fuel"]
  first = env.reset()
  for name, value in first.observation.items():
    spec[name].validate(value)
    assert value.dtype == np.int64
  first.observation["taxi"][0] = 99                  # copies, never the board's memory
  assert env.physics.taxi_square()[0] != 99
  assert list(taxi.classic(random=0).reset().observation) == ["taxi", "passenger",
                                                             "destination"]


def test_dm_control_seeds_and_fixed_start():
  a, b = taxi.fuel(random=5), taxi.fuel(random=np.random.RandomState(5))
  for _ in range(3):
    oa, ob = a.reset().observation, b.reset().observation
    assert all(np.array_equal(oa[k], ob[k]) for k in oa)
  env = taxi.fuel(initial_state=[4, 3, 4, 3, 1])
  first = env.reset()
  np.testing.assert_array_equal(first.observation["taxi"], [4, 3])
  np.testing.assert_array_equal(env.physics.taxi_position(), [3.5, 0.5])   # the cab on B
  last = env.step(5)
  assert last.step_type == dm_env.StepType.LAST
  assert (last.reward, last.discount) == (20.0, 0.0)
  assert env.physics.board_state() == (4, 3, 3, 3, 0)
  with pytest.raises(ValueError, match="taxi-fuel: state fuel=30 is outside the tank"):
    taxi.fuel(initial_state=[4, 3, 4, 3, 30])


def test_dm_control_truncates_at_200_with_discount_1():
  env = taxi.fuel(initial_state=[2, 1, 0, 3, 12])
  env.reset()
  for t in range(1, 201):
    time_step = env.step(6)   # Fillup at F
    assert time_step.last() == (t == 200)
  assert time_step.discount == 1.0 and time_step.reward == -1.0
  assert env.step(6).first()   # dm_control starts the next episode


def test_dm_control_bad_action_names_task_and_value():
  env = taxi.classic(random=0)
  env.reset()
  with pytest.raises(ValueError, match="taxi-classic: action 6 is not one of 0 South"):
    env.step(6)
  with pytest.raises(ValueError, match="taxi-classic: action must be finite, got nan"):
    env.step(np.nan)


def replay(task_name, golden):
  """Runs the stored actions through the dm_control task, as the generator did."""
  env = getattr(taxi, task_name)(random=int(golden["seed"]))
  time_steps = [env.reset()] + [env.step(a) for a in golden["actions"]]
  for name in [k for k in golden.files if k.startswith("obs_")]:
    got = np.stack([ts.observation[name[4:]] for ts in time_steps])
    np.testing.assert_array_equal(got, golden[name], err_msg=name)
  rewards = [np.nan if ts.reward is None else ts.reward for ts in time_steps]
  discounts = [np.nan if ts.discount is None else ts.discount for ts in time_steps]
  np.testing.assert_array_equal(rewards, golden["reward"])
  np.testing.assert_array_equal(discounts, golden["discount"])
  np.testing.assert_array_equal([int(ts.step_type) for ts in time_steps], golden["step_type"])


@pytest.mark.parametrize("task_name", ["fuel", "classic"])
def test_golden_trajectory(task_name):
  """Regenerate with tests/golden/make_golden_taxi.py, only when a rule changes."""
  with np.load(GOLDEN / f"taxi_{task_name}.npz") as golden:
    replay(task_name, golden)


def test_gymnasium_and_dm_control_share_the_rules():
  """The golden fuel trajectory through the Gymnasium env, started from each
  episode's first state, gives the same rewards and observations."""
  with np.load(GOLDEN / "taxi_fuel.npz") as golden:
    env = make()
    keys = ("taxi", "passenger", "destination", "fuel")
    obs_at = lambda t: np.concatenate([golden[f"obs_{k}"][t] for k in keys])
    for t, step_type in enumerate(golden["step_type"]):
      if step_type == 0:
        env.reset(options={"state": obs_at(t)})
      else:
        obs, reward, terminated, _, _ = env.step(golden["actions"][t - 1])
        np.testing.assert_array_equal(obs, obs_at(t))
        assert reward == golden["reward"][t]
        assert terminated == (golden["discount"][t] == 0.0)


def test_suite_lists_the_taxi_tasks():
  suite = pytest.importorskip("hpg_mj.suite")
  assert suite.TASKS_BY_DOMAIN["taxi"] == ("fuel", "classic")
  env = suite.load("taxi", "fuel", task_kwargs={"random": 3})
  assert env.reset().first()
