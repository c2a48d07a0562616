"""The harbour as Gymnasium environments (single and native batch) and as dm_control
tasks: every level passes Gymnasium's `check_env` (dm_env's `EnvironmentTestMixin`:
tests/test_suite_environment_mixin.py, every suite task), both backends and both APIs
end alike on an obstacle and see it alike, the batch follows the single environments,
and the pictures show the level's obstacles alike on both paths."""
import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode

import hpg_mj  # noqa: F401  (registers the ids)
from hpg_mj import suite
from hpg_mj.envs import ship_harbour as harbour_env
from hpg_mj.worlds import ship_harbour_core as harbour_core

ID = "hpg_mj/ShipHarbour-v0"
LEVELS = list(harbour_core.LEVELS)
# In the hard level's northern pocket, 10 m south of its wall's face (y = 444) and heading
# north: aground at step 6.
START = [400.0, 434.0, 0.0, 0.0]


@pytest.mark.parametrize("backend", ["mujoco", "analytic"])
@pytest.mark.parametrize("level", LEVELS)
def test_check_env(level, backend):
  env = gymnasium.make(ID, level=level, backend=backend)
  check_env(env.unwrapped, skip_render_check=True)
  assert env.observation_space.shape == (harbour_core.OBSERVATION_SIZE,)
  assert env.observation_space.high[-1] == harbour_core.MAX_RANGE_M


def test_an_obstacle_ends_the_episode_alike_on_both_backends_and_in_dm_control():
  runs = []
  for backend in ("analytic", "mujoco"):
    env = gymnasium.make(ID, level="hard", backend=backend)
    obs, info = env.reset(options={"state": START})
    assert info == {"event": None} and obs[7] == 10.0           # dead ahead, 10 m
    run = [obs]
    for _ in range(20):
      obs, reward, terminated, truncated, info = env.step(np.array([0.0]))
      run.append(obs)
      if terminated or truncated:
        break
    assert terminated and info["event"] == "obstacle" and reward == -101.0 and len(run) == 7
    runs.append(np.array(run))
  # The same ship, the same ranges (the rangefinders against the closed form; the
  # straight track is the same on both ships to rounding).
  np.testing.assert_allclose(runs[0], runs[1], atol=1e-6)
  dm = suite.load("ship_harbour", "hard", {"initial_state": START})
  ts = dm.reset()
  np.testing.assert_allclose(np.concatenate(list(ts.observation.values())), runs[1][0])
  steps = [dm.step(np.array([0.0])) for _ in range(6)]
  assert steps[-1].last() and steps[-1].reward == -101.0 and steps[-1].discount == 0.0
  assert dm.task.last_event == "obstacle"
  np.testing.assert_array_equal(np.concatenate(list(steps[-1].observation.values())),
                                runs[1][-1])


@pytest.mark.parametrize("backend,steps,max_steps", [("analytic", 200, 60), ("mujoco", 25, 10)])
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP],
                         ids=lambda m: m.value)
def test_the_native_batch_follows_the_single_environments(mode, backend, steps, max_steps):
  kwargs = {"level": "hard", "backend": backend, "max_steps": max_steps}
  native = gymnasium.make_vec(ID, 4, vectorization_mode="vector_entry_point",
                              autoreset_mode=mode, **kwargs)
  reference = gymnasium.make_vec(ID, 4, vectorization_mode="sync",
                                 vector_kwargs={"autoreset_mode": mode}, **kwargs)
  assert isinstance(native.unwrapped, harbour_env.ShipHarbourVectorEnv)
  (obs_n, _), (obs_r, _) = native.reset(seed=3), reference.reset(seed=3)
  np.testing.assert_array_equal(obs_n, obs_r)
  rng, ends = np.random.default_rng(3), 0
  for _ in range(steps):
    action = rng.uniform(-20.0, 20.0, (4, 1))
    out_n, out_r = native.step(action), reference.step(action)
    for a, b in zip(out_n[:4], out_r[:4]):
      np.testing.assert_array_equal(a, b)
    mask = out_r[4]["_event"]
    np.testing.assert_array_equal(out_n[4]["event"][mask], out_r[4]["event"][mask])
    ends += int(out_r[2].sum() + out_r[3].sum())
  assert ends >= 4


def test_bad_levels_backends_and_options_are_one_line_errors():
  allowed = r"allowed levels: \['easy', 'medium', 'hard'\]$"
  with pytest.raises(ValueError, match=r"^ShipHarbourEnv: unknown level 'windy'; " + allowed):
    gymnasium.make(ID, level="windy")
  with pytest.raises(ValueError, match=r"^ShipHarbourVectorEnv: unknown level 2; " + allowed):
    gymnasium.make_vec(ID, 2, level=2)
  with pytest.raises(ValueError, match=r"^unknown ship backend 'jax'; valid backends: "):
    gymnasium.make(ID, backend="jax")
  with pytest.raises(ValueError, match=r"^unknown task 'windy' in domain 'ship_harbour'; "
                                       r"valid tasks: \['easy', 'medium', 'hard'\]$"):
    suite.load("ship_harbour", "windy")
  env = gymnasium.make(ID, level="medium", backend="analytic")
  with pytest.raises(ValueError, match=r"^ShipHarbour\(medium, backend=analytic\): unknown "
                                       r"reset options \['course'\]; allowed: \['state'\]$"):
    env.reset(options={"course": None})
  with pytest.raises(ValueError, match=r"^ShipHarbour\(medium, backend=analytic\): start "
                                       r"position \(400.0, 570.0\) lies on an obstacle"):
    env.reset(options={"state": [400.0, 570.0, 0.0, 0.0]})
  vec = gymnasium.make_vec(ID, 2, level="medium", backend="analytic")
  with pytest.raises(ValueError, match=r"^ShipHarbourVectorEnv\(medium, backend=analytic\) "
                                       r"copy 0: start position"):
    vec.reset(options={"state": [400.0, 570.0, 0.0, 0.0]})


def test_the_suite_tags_each_level():
  tasks = suite._DOMAINS["ship_harbour"].SUITE
  for level in LEVELS:
    assert level in tasks.tagged(level) and level in tasks.tagged("benchmarking")


def test_the_analytic_harbour_imports_neither_mujoco_nor_dm_control():
  # SPEC section 9, as for the steering ship: the analytic path, single and batched.
  import subprocess
  import sys
  code = ("import sys, gymnasium, numpy as np, hpg_mj\n"
          "env = gymnasium.make('hpg_mj/ShipHarbour-v0', level='hard', backend='analytic')\n"
          "env.reset(seed=0); env.step(np.array([1.0]))\n"
          "vec = gymnasium.make_vec('hpg_mj/ShipHarbour-v0', 2, level='hard', backend='analytic')\n"
          "vec.reset(seed=0); vec.step(np.zeros((2, 1)))\n"
          "print(sorted(m for m in ('mujoco', 'dm_control') if m in sys.modules))")
  done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                        timeout=120)
  assert done.returncode == 0, done.stderr[-2000:]
  assert done.stdout.strip().splitlines()[-1] == "[]"


def test_frames_show_no_rangefinder_rays():
  # MuJoCo draws a rangefinder's ray (yellow: 255, 255, under 100) to whatever it hits, past the
  # 150 m the observation reads: a pixel agent saw more than the ranges. Off in every
  # frame; at this start six rays hit islands and piers ahead.
  dm = suite.load("ship_harbour", "hard", {"initial_state": [500.0, 300.0, 0.0, 0.0]})
  dm.reset()
  assert (dm.physics.data.sensordata[:7] > 0).sum() == 6
  frame = dm.physics.render(240, 320, camera_id="top")
  assert ((frame[..., 0] == 255) & (frame[..., 1] == 255) & (frame[..., 2] < 100)).sum() == 0
  dm.close()


def test_pixels_show_the_levels_obstacles_alike_on_both_paths():
  # The Gymnasium frame (the render worker's ship scene on assets/ship_harbour.xml) and
  # dm_control's physics.render of the same ship are the same picture, the level's
  # islands green on the blue sea.
  env = gymnasium.make(ID, level="hard", backend="mujoco", render_mode="rgb_array",
                       width=160, height=120)
  env.reset(options={"state": [500.0, 900.0, 0.0, 0.0]})
  frame = env.render()
  assert frame.shape == (120, 160, 3) and frame.std() > 5.0
  assert (frame[..., 1].astype(int) > frame[..., 2].astype(int) + 20).sum() > 20
  dm = suite.load("ship_harbour", "hard", {"initial_state": [500.0, 900.0, 0.0, 0.0]})
  dm.reset()
  np.testing.assert_array_equal(dm.physics.render(120, 160, camera_id="top"), frame)
  env.close()
  dm.close()
