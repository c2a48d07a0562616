"""The goal-conditioned ship as Gymnasium environments (single and native batch) and as
dm_control tasks: `check_env` on every level (dm_env's `EnvironmentTestMixin`:
tests/test_suite_environment_mixin.py), the step's reward is `compute_reward`'s, and
Stable-Baselines3's `HerReplayBuffer` trains on it unmodified."""
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode

import hpg_mj  # noqa: F401  (registers the ids)
from hpg_mj import suite
from hpg_mj.envs import ship_goal as goal_env
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_goal_core as goal_core

ID = "hpg_mj/ShipGoal-v0"
LEVELS = list(goal_core.LEVELS)


@pytest.mark.parametrize("backend", ["mujoco", "analytic"])
@pytest.mark.parametrize("level", LEVELS)
def test_check_env(level, backend):
  env = gymnasium.make(ID, level=level, backend=backend)
  check_env(env.unwrapped, skip_render_check=True)
  assert set(env.observation_space.spaces) == {"observation", "achieved_goal", "desired_goal",
                                               "ranges"}


@pytest.mark.parametrize("backend", ["analytic", "mujoco"])
def test_the_steps_reward_is_compute_rewards_and_a_pass_ends_the_episode(backend):
  env = gymnasium.make(ID, backend=backend, max_steps=1500)
  unwrapped = env.unwrapped
  rng = np.random.default_rng(0)
  for seed in range(3):
    obs, _ = env.reset(seed=seed)
    phase = 0
    for _ in range(1500):
      tx, ty, phase = goal_core.pilot_target(obs["observation"], phase, obs["desired_goal"])
      r = core.pilot_turn_rate(obs["observation"], tx, ty) + rng.uniform(-1, 1)
      obs, reward, terminated, truncated, info = env.step(np.array([r]))
      assert reward == unwrapped.compute_reward(obs["achieved_goal"], obs["desired_goal"], info)
      assert info["is_success"] == (reward == 99.0)
      if terminated or truncated:
        break
    assert terminated and info["event"] == "gate" and info["is_success"]


def test_a_gate_and_a_start_can_be_given():
  env = gymnasium.make(ID, level="hard", backend="analytic")
  obs, _ = env.reset(options={"state": [560.0, 590.15, 0.0, 0.0], "gate": [560.0, 600.0, 0.0]})
  np.testing.assert_allclose(obs["desired_goal"], [560.0, 600.0, 0.0, 1.0])
  rewards = [env.step(np.array([0.0]))[1] for _ in range(6)]
  assert rewards == [-1.0] * 5 + [99.0]
  with pytest.raises(ValueError, match=r"^ShipGoal\(hard, backend=analytic\): unknown reset "
                                       r"options \['goal'\]; allowed: \['gate', 'state'\]$"):
    env.reset(options={"goal": [1, 2, 3]})


@pytest.mark.parametrize("backend", ["analytic", "mujoco"])
def test_the_hard_level_runs_aground_sees_its_obstacles_and_refuses_gates_on_them(backend):
  # goal/hard's water holds the harbour's medium obstacles: a ship sailing north at the
  # island of centre (400, 220), radius 60, sees it ahead and runs aground on it, and
  # `compute_reward` gives the same reward from the step's info, whatever the goals.
  env = gymnasium.make(ID, level="hard", backend=backend)
  obs, _ = env.reset(options={"state": [400.0, 100.0, 0.0, 0.0], "gate": [560.0, 600.0, 0.0]})
  assert obs["ranges"][3] == pytest.approx(60.0, abs=1e-6)      # ahead: 160 - 100 m
  assert obs["ranges"][0] == 150.0 and obs["ranges"][6] == 150.0
  for step in range(40):
    obs, reward, terminated, _, info = env.step(np.zeros(1))
    if terminated:
      break
  assert info["event"] == "obstacle" and reward == -101.0 and step == 33   # 60 m at 1.8 a step
  unwrapped = env.unwrapped
  assert unwrapped.compute_reward(obs["achieved_goal"], obs["desired_goal"], info) == reward
  assert unwrapped.compute_reward(obs["achieved_goal"], obs["desired_goal"], None) == -1.0
  batch = np.stack([obs["achieved_goal"]] * 3)
  np.testing.assert_array_equal(unwrapped.compute_reward(
      batch, batch, np.array([info, {"event": None}, {}])), [-101.0, 99.0, 99.0])
  with pytest.raises(ValueError, match=r"^ShipGoal\(hard, backend=.*\): gate \[400.0, 400.0, 0.0\] "
                                       r"comes within 10 m of an obstacle of level 'hard'"):
    env.reset(options={"gate": [400.0, 400.0, 0.0]})
  with pytest.raises(ValueError, match=r"lies on an obstacle"):
    env.reset(options={"state": [400.0, 220.0, 0.0, 0.0]})
  env.close()
  # At easy and medium the water is open: every range reads 150 m, that gate is allowed.
  open_water = gymnasium.make(ID, level="medium", backend=backend)
  obs, _ = open_water.reset(options={"state": [400.0, 100.0, 0.0, 0.0],
                                     "gate": [400.0, 400.0, 0.0]})
  np.testing.assert_array_equal(obs["ranges"], np.full(7, 150.0))
  open_water.close()


@pytest.mark.parametrize("level,backend,steps,max_steps", [
    ("easy", "analytic", 200, 30), ("easy", "mujoco", 25, 10),
    ("hard", "analytic", 300, 100), ("hard", "mujoco", 25, 10)])   # hard: its obstacles
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP],
                         ids=lambda m: m.value)
def test_the_native_batch_follows_the_single_environments(mode, level, backend, steps,
                                                          max_steps):
  kwargs = {"level": level, "backend": backend, "max_steps": max_steps}
  native = gymnasium.make_vec(ID, 4, vectorization_mode="vector_entry_point",
                              autoreset_mode=mode, **kwargs)
  reference = gymnasium.make_vec(ID, 4, vectorization_mode="sync",
                                 vector_kwargs={"autoreset_mode": mode}, **kwargs)
  assert isinstance(native.unwrapped, goal_env.ShipGoalVectorEnv)

  def same_obs(a, b):
    assert set(a) == set(b)
    for key in a:
      np.testing.assert_array_equal(a[key], b[key], err_msg=key)
  same_obs(native.reset(seed=5)[0], reference.reset(seed=5)[0])
  rng, ends = np.random.default_rng(5), 0
  for _ in range(steps):
    action = rng.uniform(-20.0, 20.0, (4, 1))
    out_n, out_r = native.step(action), reference.step(action)
    same_obs(out_n[0], out_r[0])
    for a, b in zip(out_n[1:4], out_r[1:4]):
      np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(out_n[4]["is_success"][out_r[4]["_is_success"]],
                                  out_r[4]["is_success"][out_r[4]["_is_success"]])
    if mode == AutoresetMode.SAME_STEP and "final_obs" in out_r[4]:
      for i in np.flatnonzero(out_r[4]["_final_obs"]):
        same_obs(out_n[4]["final_obs"][i], out_r[4]["final_obs"][i])
    ends += int(out_r[2].sum() + out_r[3].sum())
  assert ends >= 8


def test_the_hard_gate_takes_no_pass_30_m_off_its_centre_on_any_path():
  # A ship sailing north 30 m east of the gate's centre passes the medium gate (50 m
  # either side) and not the hard one (25 m): Gymnasium's single and batched
  # environments, dm_control's task and the fused loop's world judge alike.
  from hpg_mj.hierarchy import ladder
  from hpg_mj.worlds import ship_goal_core as goal_core
  state, gate = [590.0, 590.0, 0.0, 0.0], [560.0, 600.0, 0.0]
  for level, passes in (("medium", True), ("hard", False)):
    env = gymnasium.make(ID, level=level, backend="analytic")
    env.reset(options={"state": state, "gate": gate})
    events = [env.step(np.zeros(1))[4]["event"] for _ in range(8)]
    assert ("gate" in events) == passes, level
    vec = gymnasium.make_vec(ID, 2, level=level, backend="analytic")
    vec.reset(options={"state": state, "gate": gate})
    success = [vec.step(np.zeros((2, 1)))[4]["is_success"].all() for _ in range(8)]
    assert any(success) == passes, level
    dm = suite.load("ship_goal", level, {"initial_state": state, "gate": gate})
    dm.reset()
    rewards = [dm.step(np.zeros(1)).reward for _ in range(8)]
    assert (99.0 in rewards) == passes, level
    world = ladder.world("ship_goal", level)
    np.testing.assert_array_equal(world.params.tolerance, goal_core.level_tolerance(level))


def test_her_trains_on_it_unmodified():
  # Stable-Baselines3's SAC with its HerReplayBuffer, a few hundred steps: the buffer
  # relabels with `compute_reward`, and hindsight finds the successes random sailing
  # never does.
  import torch
  from stable_baselines3 import SAC, HerReplayBuffer
  threads = torch.get_num_threads()
  torch.set_num_threads(1)      # a 16-unit network gains nothing from more
  env = gymnasium.make(ID, level="hard", backend="analytic", max_steps=50)
  model = SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer,
              replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
              learning_starts=100, batch_size=64, policy_kwargs={"net_arch": [16]}, seed=0,
              device="cpu")
  try:
    model.learn(300)
  finally:
    torch.set_num_threads(threads)
  assert model.num_timesteps == 300 and model.replay_buffer.size() == 300
  batch = model.replay_buffer.sample(512)
  rewards = batch.rewards.numpy().ravel()
  again = env.unwrapped.compute_reward(batch.next_observations["achieved_goal"].numpy(),
                                       batch.observations["desired_goal"].numpy(), None)
  np.testing.assert_array_equal(rewards, again.astype(np.float32))
  assert (rewards == 99.0).sum() >= 10                     # relabelled successes


@pytest.mark.parametrize("level", ["easy", "hard"])
def test_sb3_s_check_env_passes_on_the_environment_itself(level):
  # docs/getting_started.md: SB3's checker calls compute_reward on what it is given, so
  # it is handed `unwrapped` (Gymnasium 1's wrappers do not pass the method on).
  from stable_baselines3.common.env_checker import check_env
  env = gymnasium.make(ID, level=level, backend="analytic")
  with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    check_env(env.unwrapped)
  assert all("recommend" in str(w.message) for w in caught), [str(w.message) for w in caught]


def test_bad_levels_are_one_line_errors():
  allowed = r"allowed levels: \['easy', 'medium', 'hard'\]$"
  with pytest.raises(ValueError, match=r"^ShipGoalEnv: unknown level 'far'; " + allowed):
    gymnasium.make(ID, level="far")
  with pytest.raises(ValueError, match=r"^ShipGoalVectorEnv: unknown level None; " + allowed):
    gymnasium.make_vec(ID, 2, level=None)
  with pytest.raises(ValueError, match=r"^unknown task 'far' in domain 'ship_goal'; "
                                       r"valid tasks: \['easy', 'medium', 'hard'\]$"):
    suite.load("ship_goal", "far")


def test_the_suite_tags_each_level_and_observes_the_gate():
  tasks = suite._DOMAINS["ship_goal"].SUITE
  for level in LEVELS:
    assert level in tasks.tagged(level) and level in tasks.tagged("benchmarking")
  env = suite.load("ship_goal", "medium", {"initial_state": [400.0, 390.15, 0.0, 0.0],
                                           "gate": [400.0, 400.0, 0.0]})
  ts = env.reset()
  np.testing.assert_array_equal(ts.observation["gate_position"], [400.0, 400.0])
  assert ts.observation["gate_heading_deg"] == [0.0]
  for _ in range(5):
    assert env.step(np.array([0.0])).reward == -1.0
  ts = env.step(np.array([0.0]))
  assert ts.last() and ts.reward == 99.0 and ts.discount == 0.0
  assert env.task.last_event == "gate"
  posts = np.array([env.physics.named.model.geom_pos[name][:2]
                    for name in ("gate_post_west", "gate_post_east")])
  np.testing.assert_array_equal(posts, [[350.0, 400.0], [450.0, 400.0]])


def test_pixels_show_the_episodes_gate_alike_on_both_paths():
  # The Gymnasium frame (render worker's ship scene) and dm_control's physics.render
  # (the render worker's copy of the MuJoCo ship) of the same ship and gate are the same
  # picture; another gate makes another.
  state, gate = [700.0, 200.0, 30.0, 0.0], [300.0, 600.0, 60.0]
  env = gymnasium.make(ID, level="hard", backend="mujoco", render_mode="rgb_array",
                       width=160, height=120)
  env.reset(options={"state": state, "gate": gate})
  frame = env.render()
  dm = suite.load("ship_goal", "hard", {"initial_state": state, "gate": gate})
  dm.reset()
  np.testing.assert_array_equal(dm.physics.render(120, 160, camera_id="top"), frame)
  env.reset(options={"state": state, "gate": [560.0, 600.0, -60.0]})
  assert np.abs(env.render().astype(int) - frame).sum() > 0
  env.close()
  dm.close()
