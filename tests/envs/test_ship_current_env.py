"""The ship in a current as Gymnasium environments (single and native batch) and as
dm_control tasks: every level passes Gymnasium's `check_env` (dm_env's
`EnvironmentTestMixin`: tests/test_suite_environment_mixin.py, every suite task), the
batch follows the single environments, and a bad level is a one-line error naming what
is allowed."""
import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode

import hpg_mj  # noqa: F401  (registers the ids)
from hpg_mj import suite
from hpg_mj.envs import ship_current as current_env
from hpg_mj.worlds import ship_current_core as current_core

ID = "hpg_mj/ShipCurrent-v0"
LEVELS = list(current_core.LEVELS)


@pytest.mark.parametrize("backend", ["mujoco", "analytic"])
@pytest.mark.parametrize("level", LEVELS)
def test_check_env(level, backend):
  env = gymnasium.make(ID, level=level, backend=backend)
  check_env(env.unwrapped, skip_render_check=True)
  assert env.observation_space.shape == (6,)
  speed = current_core.max_speed(current_core.LEVELS[level])
  np.testing.assert_array_equal(env.observation_space.high[4:], [speed, speed])


@pytest.mark.parametrize("level", LEVELS)
def test_the_observation_ends_with_the_water_at_the_ship(level):
  env = gymnasium.make(ID, level=level, backend="analytic")
  obs, _ = env.reset(seed=0)
  field = current_core.level_field(level)
  for _ in range(20):
    assert obs[4:].tolist() == list(current_core.current_at(field, obs[0], obs[1]))
    obs, *_ = env.step(np.array([7.0]))


def test_the_hard_current_sweeps_a_ship_off_the_course_the_still_water_keeps():
  # The same start and rudder: in still water (ShipSteering) the ship passes the gate;
  # in the hard current it is carried east past the posts.
  start = [440.0, 370.0, 0.0, 0.0]      # 10 m inside the east post, 30 m south of the gate
  still = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic")
  still.reset(options={"state": start})
  hard = gymnasium.make(ID, level="hard", backend="analytic")
  hard.reset(options={"state": start})
  events = [still.step(np.array([0.0]))[4]["event"] for _ in range(20)]
  assert "gate" in events
  for _ in range(20):
    obs, _, terminated, _, info = hard.step(np.array([0.0]))
  assert not terminated and obs[1] > 400.0 and obs[0] > 450.0     # crossed east of the gate


@pytest.mark.parametrize("level", LEVELS)
def test_mujoco_and_analytic_backends_agree_within_the_euler_error(level):
  obs = {}
  for backend in ("mujoco", "analytic"):
    env = gymnasium.make(ID, level=level, backend=backend)
    env.reset(options={"state": [500.0, 100.0, -30.0, 4.0]})
    for r in np.random.default_rng(0).uniform(-15, 15, 150):
      obs[backend], *_ = env.step(np.array([r]))
  # The explicit-Euler analytic ship strays up to ~1.5 m from the continuous one over
  # 600 s (`hpg-mj verify current`); MuJoCo's ship stays within 0.05 m of it.
  np.testing.assert_allclose(obs["mujoco"][:2], obs["analytic"][:2], atol=1.5)
  np.testing.assert_allclose(obs["mujoco"][2:4], obs["analytic"][2:4], atol=0.1)


@pytest.mark.parametrize("backend,steps", [("analytic", 150), ("mujoco", 25)])
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP],
                         ids=lambda m: m.value)
def test_the_native_batch_follows_the_single_environments(mode, backend, steps):
  kwargs = {"level": "hard", "backend": backend, "max_steps": 40}
  native = gymnasium.make_vec(ID, 4, vectorization_mode="vector_entry_point",
                              autoreset_mode=mode, **kwargs)
  reference = gymnasium.make_vec(ID, 4, vectorization_mode="sync",
                                 vector_kwargs={"autoreset_mode": mode}, **kwargs)
  assert isinstance(native.unwrapped, current_env.ShipCurrentVectorEnv)
  np.testing.assert_array_equal(native.reset(seed=3)[0], reference.reset(seed=3)[0])
  rng, ends = np.random.default_rng(3), 0
  for _ in range(steps):
    action = rng.uniform(-20.0, 20.0, (4, 1))
    for a, b in zip(native.step(action)[:4], reference.step(action)[:4]):
      np.testing.assert_array_equal(a, b)
      ends += int(b.sum()) if b.dtype == np.bool_ else 0
  assert ends >= (8 if backend == "analytic" else 1)


def test_bad_levels_and_backends_are_one_line_errors():
  allowed = r"allowed levels: \['easy', 'medium', 'hard'\]$"
  with pytest.raises(ValueError, match=r"^ShipCurrentEnv: unknown level 'stormy'; " + allowed):
    gymnasium.make(ID, level="stormy")
  with pytest.raises(ValueError, match=r"^ShipCurrentVectorEnv: unknown level 3; " + allowed):
    gymnasium.make_vec(ID, 2, level=3)
  with pytest.raises(ValueError, match=r"^unknown ship backend 'jax'; valid backends: "):
    gymnasium.make(ID, backend="jax")
  with pytest.raises(ValueError, match=r"^unknown task 'stormy' in domain 'ship_current'; "
                                       r"valid tasks: \['easy', 'medium', 'hard'\]$"):
    suite.load("ship_current", "stormy")


def test_the_suite_tags_each_level():
  tasks = suite._DOMAINS["ship_current"].SUITE
  for level in LEVELS:
    assert level in tasks.tagged(level) and level in tasks.tagged("benchmarking")


def test_the_dm_control_task_is_the_gymnasium_environment_on_mujoco():
  env = suite.load("ship_current", "medium", {"initial_state": [700.0, 200.0, 120.0, -3.0]})
  gym = gymnasium.make(ID, level="medium", backend="mujoco")
  gym.reset(options={"state": [700.0, 200.0, 120.0, -3.0]})
  env.reset()
  for r in np.random.default_rng(6).uniform(-15, 15, 40):
    ts = env.step(np.array([r]))
    obs, reward, *_ = gym.step(np.array([r]))
    np.testing.assert_array_equal(np.concatenate(list(ts.observation.values())), obs)
    assert ts.reward == reward


def test_the_analytic_current_imports_neither_mujoco_nor_dm_control():
  # SPEC section 9, as for the steering ship: the analytic path, single and batched.
  import subprocess
  import sys
  code = ("import sys, gymnasium, numpy as np, hpg_mj\n"
          "env = gymnasium.make('hpg_mj/ShipCurrent-v0', level='hard', backend='analytic')\n"
          "env.reset(seed=0); env.step(np.array([1.0]))\n"
          "vec = gymnasium.make_vec('hpg_mj/ShipCurrent-v0', 2, level='hard', backend='analytic')\n"
          "vec.reset(seed=0); vec.step(np.zeros((2, 1)))\n"
          "print(sorted(m for m in ('mujoco', 'dm_control') if m in sys.modules))")
  done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                        timeout=120)
  assert done.returncode == 0, done.stderr[-2000:]
  assert done.stdout.strip().splitlines()[-1] == "[]"


def test_pixels_of_both_paths_are_the_same_picture():
  # Pixel observations as the steering ship's: the Gymnasium frame and dm_control's
  # physics.render of the same ship at its start.
  state = [300.0, 500.0, 80.0, 0.0]
  env = gymnasium.make(ID, level="hard", backend="mujoco", render_mode="rgb_array",
                       width=160, height=120)
  env.reset(options={"state": state})
  frame = env.render()
  assert frame.shape == (120, 160, 3) and frame.std() > 5.0
  dm = suite.load("ship_current", "hard", {"initial_state": state})
  dm.reset()
  np.testing.assert_array_equal(dm.physics.render(120, 160, camera_id="top"), frame)
  env.close()
  dm.close()


def test_a_step_before_reset_is_refused_and_one_after_the_end_warned_or_refused():
  # A newcomer sailed on after leaving the field, reward -101 a step and no word; and
  # the environment itself (unwrapped, without Gymnasium's order check) stepped from
  # (0, 0, 0, 0) before any reset. As Gymnasium's CartPole: warned once an episode;
  # with strict=True refused, as the taxi's.
  with pytest.raises(RuntimeError, match=r"^ShipCurrent\(hard, backend=analytic\): call "
                     r"reset\(\) before step\(\)$"):
    gymnasium.make(ID, level="hard", backend="analytic").unwrapped.step([0.0])
  for strict in (False, True):
    env = gymnasium.make(ID, level="hard", backend="analytic", strict=strict)
    env.reset(seed=0, options={"state": [5.0, 500.0, -90.0, 0.0]})
    terminated = False
    while not terminated:
      terminated = env.step([0.0])[2]
    if strict:
      with pytest.raises(RuntimeError, match="the episode has ended; call reset"):
        env.step([0.0])
      continue
    with pytest.warns(UserWarning, match="step\\(\\) called after the episode ended") as caught:
      env.step([0.0])
      env.step([0.0])
    assert len(caught) == 1
    env.reset()
    assert env.step([0.0])[2] is False     # a new episode sails as before
