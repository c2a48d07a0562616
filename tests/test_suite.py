"""dm_control suite invariants, for every task (after dm_control/suite/suite_test.py)."""
import dm_env
import numpy as np
import pytest
from dm_control.mujoco import engine
from dm_control.rl import control
from dm_control.suite import base
from dm_env import specs

from hpg_mj import suite

N_STEPS = 60


def _random_action(spec, rng):
  if isinstance(spec, specs.DiscreteArray):
    return np.array(rng.integers(0, spec.num_values), dtype=spec.dtype)
  return rng.uniform(spec.minimum, spec.maximum, spec.shape).astype(spec.dtype)


def _rollout(env, seed, n=N_STEPS):
  rng = np.random.default_rng(seed)
  steps = [env.reset()]
  for _ in range(n):
    ts = env.step(_random_action(env.action_spec(), rng))
    steps.append(ts)
    if ts.last():
      steps.append(env.reset())
  return steps


def test_all_tasks_listed():
  assert set(suite.ALL_TASKS) == {("ship", "steer"), ("ship", "diagonal"), ("ship", "straight"),
                                  ("ship", "patrol"), ("taxi", "fuel"), ("taxi", "classic"),
                                  ("ship_current", "easy"), ("ship_current", "medium"),
                                  ("ship_current", "hard"), ("ship_goal", "easy"),
                                  ("ship_goal", "medium"), ("ship_goal", "hard"),
                                  ("ship_regatta", "easy"), ("ship_regatta", "medium"),
                                  ("ship_regatta", "hard"), ("ship_harbour", "easy"),
                                  ("ship_harbour", "medium"), ("ship_harbour", "hard")}


def test_tasks_are_listed_by_tag_as_in_dm_control():
  # dm_control.suite's BENCHMARKING, EXTRA, EASY and HARD, and the ladder's MEDIUM.
  assert suite.BENCHMARKING == suite.ALL_TASKS and suite.EXTRA == ()
  ladder = ("ship_current", "ship_goal", "ship_regatta", "ship_harbour")
  for level, listed in (("easy", suite.EASY), ("medium", suite.MEDIUM), ("hard", suite.HARD)):
    assert listed == tuple((domain, level) for domain in ladder)
    assert listed == suite.tagged(level)
  assert suite.tagged("subtask") == (("ship", "diagonal"), ("ship", "straight"))
  assert suite.tagged("continuing") == (("ship", "patrol"),)
  assert set(suite.TAGS) == {"benchmarking", "subtask", "continuing", "easy", "medium", "hard"}
  with pytest.raises(ValueError, match=r"^no task is tagged 'hardest'; tags: \['benchmarking', "):
    suite.tagged("hardest")


@pytest.mark.parametrize("domain,task", suite.ALL_TASKS)
def test_components_have_names_and_cameras(domain, task):
  env = suite.load(domain, task, {"random": 0})
  assert isinstance(env, control.Environment)
  assert isinstance(env.physics, engine.Physics)
  assert type(env.physics).__name__ == "Physics" and type(env.physics) is not engine.Physics
  assert isinstance(env.task, base.Task)
  model = env.physics.model
  assert model.ncam >= 2
  names = [model.id2name(i, "camera") for i in range(model.ncam)]
  assert all(names), names
  assert all(model.id2name(i, "body") for i in range(1, model.nbody))


@pytest.mark.parametrize("domain,task", [("ship", "steer"), ("ship_harbour", "hard"),
                                         ("taxi", "fuel")])
def test_dm_control_s_pixels_wrapper_sees_the_field_from_its_default_camera(domain, task):
  # A newcomer's pixels.Wrapper(env), camera -1 as dm_control's default, drew a black
  # frame: MuJoCo's free camera looked between the field and the ship's hidden target,
  # 5 km away. The model's <statistic> now points it at the field (the taxi's board was
  # already in view).
  from dm_control.suite.wrappers import pixels
  env = pixels.Wrapper(suite.load(domain, task, {"random": 0}),
                       render_kwargs={"height": 60, "width": 80})
  frame = env.reset().observation["pixels"]
  assert frame.shape == (60, 80, 3)
  assert (frame.astype(int).sum(-1) > 100).mean() > 0.5
  env.close()


@pytest.mark.parametrize("domain,task", suite.ALL_TASKS)
def test_actions_and_observations_conform_to_specs(domain, task):
  env = suite.load(domain, task, {"random": 1})
  obs_spec = env.observation_spec()
  for ts in _rollout(env, 1):
    assert set(ts.observation) == set(obs_spec)
    for name, spec in obs_spec.items():
      spec.validate(np.asarray(ts.observation[name], dtype=spec.dtype))
      assert np.asarray(ts.observation[name]).shape == spec.shape
    if ts.first():
      assert ts.reward is None
    else:
      assert np.isfinite(ts.reward)
      assert ts.discount in (0.0, 1.0)
  with pytest.raises(ValueError):
    env.reset()
    env.step(np.full((3,), 0.5))


@pytest.mark.parametrize("domain,task", suite.ALL_TASKS)
def test_deterministic_under_a_seed(domain, task):
  a = _rollout(suite.load(domain, task, {"random": 42}), 5)
  b = _rollout(suite.load(domain, task, {"random": 42}), 5)
  assert len(a) == len(b)
  for x, y in zip(a, b):
    assert x.step_type == y.step_type and x.reward == y.reward
    for name in x.observation:
      np.testing.assert_array_equal(x.observation[name], y.observation[name])


@pytest.mark.parametrize("domain,task", suite.ALL_TASKS)
def test_observations_share_no_memory(domain, task):
  env = suite.load(domain, task, {"random": 3})
  first = env.reset().observation
  second = env.step(_random_action(env.action_spec(), np.random.default_rng(0))).observation
  arrays = list(first.values()) + list(second.values())
  physics_arrays = [env.physics.data.qpos, env.physics.data.qvel, env.physics.data.act,
                    env.physics.data.mocap_pos]
  for i, a in enumerate(arrays):
    for b in arrays[i + 1:] + physics_arrays:
      assert not np.shares_memory(a, b)


@pytest.mark.parametrize("domain,task", suite.ALL_TASKS)
def test_initial_states_are_random(domain, task):
  env = suite.load(domain, task, {"random": 0})
  starts = {tuple(np.concatenate([np.ravel(v) for v in env.reset().observation.values()]))
            for _ in range(10)}
  assert len(starts) >= 5


def test_unknown_domain_and_task_list_the_valid_ones():
  with pytest.raises(ValueError, match=r"unknown domain 'boat'.*'ship', 'ship_current', "
                                       r"'ship_goal', 'ship_harbour', 'ship_regatta', 'taxi'"):
    suite.load("boat", "steer")
  with pytest.raises(ValueError, match=r"unknown task 'sail'.*'steer', 'diagonal', 'straight', 'patrol'"):
    suite.load("ship", "sail")
  with pytest.raises(ValueError, match=r"^task_kwargs: a ladder domain's level is its task "
                                       r"name, load\('ship_goal', 'hard'\), not a 'level' "):
    suite.load("ship_goal", "easy", task_kwargs={"level": "hard"})
  env = suite.load("ship_goal", "easy")
  with pytest.raises(ValueError, match=r"depth is not supported \(allowed: height, width, "):
    env.physics.render(84, 84, depth=True)


def test_time_step_types():
  env = suite.load("ship", "steer", {"random": 0, "initial_state": [400.0, 395.0, 0.0, 0.0]})
  ts = env.reset()
  assert ts.step_type == dm_env.StepType.FIRST
  ts = env.step(np.array([0.0]))       # 1.8 m north: still short of the gate line
  assert ts.step_type == dm_env.StepType.MID and ts.reward == -1.0
  ts = env.step(np.array([0.0]))
  ts = env.step(np.array([0.0]))       # crosses y = 400 between the posts
  assert ts.step_type == dm_env.StepType.LAST and ts.reward == 99.0 and ts.discount == 0.0
  assert env.task.last_event == "gate"


@pytest.mark.parametrize("task", ["steer", "diagonal", "straight", "patrol"])
def test_an_episode_ends_after_max_steps_control_steps(task):
  # The reset is no control step: LAST comes at the max_steps-th step, as in Gymnasium.
  env = suite.load("ship", task, {"random": 0, "max_steps": 5})
  ts, steps = env.reset(), 0
  while not ts.last():
    ts, steps = env.step(np.array([0.0])), steps + 1
  assert steps == 5 and env.task.last_event in (None, "timeout")


def test_patrol_sails_on_after_the_gate_and_restarts_after_leaving():
  # SPEC section 8: each pass +100 (either way), no LAST step until the clock runs out.
  env = suite.load("ship", "patrol", {"random": 0, "initial_state": [400.0, 395.0, 0.0, 0.0],
                                      "max_steps": 8})
  env.reset()
  rewards = [env.step(np.array([0.0])).reward for _ in range(3)]
  assert rewards == [-1.0, -1.0, 99.0] and env.task.last_event == "gate"
  ts = env.step(np.array([0.0]))
  assert ts.step_type == dm_env.StepType.MID and ts.observation["position"][1] > 400.0
  # Off the field: the penalty, then a fresh start inside it; the process goes on.
  env.task.initial_state = [500.0, 999.0, 0.0, 0.0]
  env.reset()
  ts = env.step(np.array([0.0]))
  assert ts.reward == -101.0 and env.task.last_event == "out_of_bounds"
  assert ts.step_type == dm_env.StepType.MID
  assert np.all((0.0 <= ts.observation["position"]) & (ts.observation["position"] <= 1000.0))
  for _ in range(6):
    ts = env.step(np.array([0.0]))
  assert ts.step_type == dm_env.StepType.MID                         # 7 steps
  ts = env.step(np.array([0.0]))
  assert ts.step_type == dm_env.StepType.LAST and ts.discount == 1.0   # truncated at 8
