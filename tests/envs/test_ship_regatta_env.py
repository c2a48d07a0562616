"""The regatta as Gymnasium environments (single and native batch) and as dm_control
tasks: every level passes Gymnasium's `check_env` (dm_env's `EnvironmentTestMixin`:
tests/test_suite_environment_mixin.py, every suite task), both backends and both APIs
count the same gates, the batch follows the single environments, and the pictures show
the course alike on both paths."""
import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode

import hpg_mj  # noqa: F401  (registers the ids)
from hpg_mj import suite
from hpg_mj.envs import ship_regatta as regatta_env
from hpg_mj.worlds import ship_regatta_core as regatta_core

ID = "hpg_mj/ShipRegatta-v0"
LEVELS = list(regatta_core.LEVELS)
# Three gates due north of each other, 200 m apart; the ship 9.85 m short of the first.
NORTH = [[400.0, 400.0, 0.0], [400.0, 600.0, 0.0], [400.0, 800.0, 0.0]]
START = [400.0, 390.15, 0.0, 0.0]


@pytest.mark.parametrize("backend", ["mujoco", "analytic"])
@pytest.mark.parametrize("level", LEVELS)
def test_check_env(level, backend):
  env = gymnasium.make(ID, level=level, backend=backend)
  check_env(env.unwrapped, skip_render_check=True)
  assert env.observation_space.shape == (regatta_core.OBSERVATION_SIZE,)
  assert env.observation_space.high[10] == regatta_core.LEVELS[level][0]


@pytest.mark.parametrize("backend", ["analytic", "mujoco"])
def test_a_given_course_is_sailed_gate_by_gate_on_both_backends_and_in_dm_control(backend):
  env = gymnasium.make(ID, level="easy", backend=backend)
  obs, info = env.reset(options={"state": START, "course": NORTH})
  np.testing.assert_array_equal(info["course"], NORTH)
  assert info == {**info, "event": None, "gates_passed": 0}
  np.testing.assert_allclose(obs[4:], [9.85, 0.0, 0.0, 209.85, 0.0, 0.0, 3.0], atol=1e-9)
  rewards, events = [], []
  for _ in range(300):
    obs, reward, terminated, truncated, info = env.step(np.array([0.0]))
    rewards.append(reward)
    events.append(info["event"])
    if terminated or truncated:
      break
  assert terminated and not truncated and info["gates_passed"] == 3 and obs[10] == 0.0
  assert [(k, e) for k, e in enumerate(events, 1) if e] == [(6, "gate"), (117, "gate"),
                                                            (228, "finish")]
  assert sum(rewards) == -228 + 100 + 100 + 500
  # The dm_control task on the MuJoCo ship: the same gates at the same steps.
  dm = suite.load("ship_regatta", "easy", {"initial_state": START, "course": NORTH})
  dm.reset()
  steps = [dm.step(np.array([0.0])) for _ in range(228)]
  assert [ts.reward for ts in steps] == rewards and steps[-1].last()
  assert steps[-1].discount == 0.0 and dm.task.last_event == "finish"
  assert dm.task.gates_passed == 3


def test_the_dm_control_task_is_the_gymnasium_environment_on_mujoco():
  course = regatta_core.sample_course(np.random.default_rng(8), regatta_core.LEVELS["hard"])
  env = suite.load("ship_regatta", "hard", {"initial_state": [700.0, 200.0, 120.0, -3.0],
                                            "course": course})
  gym = gymnasium.make(ID, level="hard", backend="mujoco")
  gym.reset(options={"state": [700.0, 200.0, 120.0, -3.0], "course": course})
  env.reset()
  for r in np.random.default_rng(6).uniform(-15, 15, 40):
    ts = env.step(np.array([r]))
    obs, reward, *_ = gym.step(np.array([r]))
    np.testing.assert_array_equal(np.concatenate(list(ts.observation.values())), obs)
    assert ts.reward == reward


@pytest.mark.parametrize("backend,steps,max_steps", [("analytic", 200, 60), ("mujoco", 25, 10)])
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP],
                         ids=lambda m: m.value)
def test_the_native_batch_follows_the_single_environments(mode, backend, steps, max_steps):
  kwargs = {"level": "hard", "backend": backend, "max_steps": max_steps}
  native = gymnasium.make_vec(ID, 4, vectorization_mode="vector_entry_point",
                              autoreset_mode=mode, **kwargs)
  reference = gymnasium.make_vec(ID, 4, vectorization_mode="sync",
                                 vector_kwargs={"autoreset_mode": mode}, **kwargs)
  assert isinstance(native.unwrapped, regatta_env.ShipRegattaVectorEnv)
  (obs_n, info_n), (obs_r, info_r) = native.reset(seed=3), reference.reset(seed=3)
  np.testing.assert_array_equal(obs_n, obs_r)
  np.testing.assert_array_equal(info_n["course"], info_r["course"])
  rng, ends = np.random.default_rng(3), 0
  for _ in range(steps):
    action = rng.uniform(-20.0, 20.0, (4, 1))
    out_n, out_r = native.step(action), reference.step(action)
    for a, b in zip(out_n[:4], out_r[:4]):
      np.testing.assert_array_equal(a, b)
    mask = out_r[4]["_gates_passed"]
    np.testing.assert_array_equal(out_n[4]["gates_passed"][mask], out_r[4]["gates_passed"][mask])
    ends += int(out_r[2].sum() + out_r[3].sum())
  assert ends >= 4


def test_the_batch_counts_gates_and_takes_courses():
  # Four copies round the same northward course: each passes its gates, and a course for
  # every copy, or one for each, is taken; a bad shape is a one-line error.
  vec = gymnasium.make_vec(ID, 4, level="easy", backend="analytic")
  vec.reset(options={"state": START, "course": NORTH})
  passed = [vec.step(np.zeros((4, 1)))[4]["gates_passed"] for _ in range(6)]
  assert passed[4].tolist() == [0] * 4 and passed[5].tolist() == [1] * 4
  each = np.array([NORTH] * 4) + [[[10.0 * i, 0.0, 0.0]] for i in range(4)]
  _, info = vec.reset(options={"course": each})
  np.testing.assert_array_equal(info["course"], each)
  np.testing.assert_array_equal(vec.unwrapped.courses, each)
  with pytest.raises(ValueError, match=r"^ShipRegattaVectorEnv\(easy, backend=analytic\): "
                                       r"options\['course'\] must be one course \(3, 3\) or one "
                                       r"per copy \(4, 3, 3\), got shape \(2, 3\)$"):
    vec.reset(options={"course": NORTH[:2]})


def test_the_hard_course_closes_after_its_time_limit_on_every_path():
  # At hard the course closes after 1,000 control steps whatever a larger max_steps asks
  # (a smaller one still holds): Gymnasium's single and batched environments here, the
  # other paths for every ladder task in tests/worlds/test_ship_ladder_limits.py. The ship
  # circles in the field.
  limit = regatta_core.TIME_LIMITS["hard"]
  assert limit == 1000 and regatta_core.TIME_LIMITS["medium"] is None
  circle = [500.0, 500.0, 0.0, 15.0]
  env = gymnasium.make(ID, level="hard", backend="analytic", max_steps=5000)
  env.reset(seed=0, options={"state": circle})
  ends = [env.step(np.array([15.0]))[2:4] for _ in range(limit)]
  assert ends[-2] == (False, False) and ends[-1] == (False, True)
  vec = gymnasium.make_vec(ID, 2, level="hard", backend="analytic", max_steps=5000)
  vec.reset(seed=0, options={"state": circle})
  for _ in range(limit):
    _, _, terminated, truncated, _ = vec.step(np.full((2, 1), 15.0))
  assert truncated.tolist() == [True, True] and not terminated.any()


def test_bad_levels_backends_and_options_are_one_line_errors():
  allowed = r"allowed levels: \['easy', 'medium', 'hard'\]$"
  with pytest.raises(ValueError, match=r"^ShipRegattaEnv: unknown level 'windy'; " + allowed):
    gymnasium.make(ID, level="windy")
  with pytest.raises(ValueError, match=r"^ShipRegattaVectorEnv: unknown level 2; " + allowed):
    gymnasium.make_vec(ID, 2, level=2)
  with pytest.raises(ValueError, match=r"^unknown ship backend 'jax'; valid backends: "):
    gymnasium.make(ID, backend="jax")
  with pytest.raises(ValueError, match=r"^unknown task 'windy' in domain 'ship_regatta'; "
                                       r"valid tasks: \['easy', 'medium', 'hard'\]$"):
    suite.load("ship_regatta", "windy")
  env = gymnasium.make(ID, level="medium", backend="analytic")
  with pytest.raises(ValueError, match=r"^ShipRegatta\(medium, backend=analytic\): unknown "
                                       r"reset options \['gates'\]; allowed: \['course', "
                                       r"'state'\]$"):
    env.reset(options={"gates": NORTH})
  with pytest.raises(ValueError, match=r"^ShipRegatta\(medium, backend=analytic\): a course is "
                                       r"5 gates"):
    env.reset(options={"course": NORTH})


def test_the_suite_tags_each_level():
  tasks = suite._DOMAINS["ship_regatta"].SUITE
  for level in LEVELS:
    assert level in tasks.tagged(level) and level in tasks.tagged("benchmarking")


def test_the_analytic_regatta_imports_neither_mujoco_nor_dm_control():
  # SPEC section 9, as for the steering ship: the analytic path, single and batched.
  import subprocess
  import sys
  code = ("import sys, gymnasium, numpy as np, hpg_mj\n"
          "env = gymnasium.make('hpg_mj/ShipRegatta-v0', level='hard', backend='analytic')\n"
          "env.reset(seed=0); env.step(np.array([1.0]))\n"
          "vec = gymnasium.make_vec('hpg_mj/ShipRegatta-v0', 2, level='hard', backend='analytic')\n"
          "vec.reset(seed=0); vec.step(np.zeros((2, 1)))\n"
          "print(sorted(m for m in ('mujoco', 'dm_control') if m in sys.modules))")
  done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                        timeout=120)
  assert done.returncode == 0, done.stderr[-2000:]
  assert done.stdout.strip().splitlines()[-1] == "[]"


def test_pixels_show_the_course_alike_on_both_paths():
  # The Gymnasium frame (the render worker's ship scene on assets/ship_regatta.xml) and
  # dm_control's physics.render of the same ship and course are the same picture; once
  # the first gate is passed, its colour and the next one's change.
  course = regatta_core.sample_course(np.random.default_rng(5), regatta_core.LEVELS["hard"])
  x, y, heading = course[0]
  rad = np.radians(heading)
  state = [x - 9.85 * np.sin(rad), y - 9.85 * np.cos(rad), heading, 0.0]
  env = gymnasium.make(ID, level="hard", backend="mujoco", render_mode="rgb_array",
                       width=160, height=120)
  env.reset(options={"state": state, "course": course})
  frame = env.render()
  assert frame.shape == (120, 160, 3) and frame.std() > 5.0
  dm = suite.load("ship_regatta", "hard", {"initial_state": state, "course": course})
  dm.reset()
  np.testing.assert_array_equal(dm.physics.render(120, 160, camera_id="top"), frame)
  for _ in range(6):
    info = env.step(np.array([0.0]))[4]
    dm.step(np.array([0.0]))
  assert info["event"] == "gate"
  after = env.render()
  np.testing.assert_array_equal(dm.physics.render(120, 160, camera_id="top"), after)
  assert np.abs(after.astype(int) - frame).sum() > 0
  env.close()
  dm.close()
