"""The ladder's time limits (each task's `TIME_LIMITS`, `ship_ladder.episode_steps`):
a level that closes its episodes closes them on every path, whatever a larger
`max_steps` asks, and a smaller one still holds. The regatta's circling ship shows the
truncation itself (tests/envs/test_ship_regatta_env.py); every path reads its limit
from one function, so here each path's limit is asked."""
import gymnasium
import pytest

import hpg_mj  # noqa: F401  (registers the ids)
from hpg_mj import suite
from hpg_mj.agents import _ladder
from hpg_mj.benchmark_tasks import task_of
from hpg_mj.hierarchy import ladder
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_ladder


def test_the_rule_takes_the_shorter_and_passes_anything_else_on():
  assert core.limited_steps(None) == core.STEER_MAX_STEPS
  assert core.limited_steps(1000) == 1000
  assert core.limited_steps(1000, 300) == 300
  assert core.limited_steps(1000, 5000) == 1000
  # What is no number goes on to the check that refuses it by name.
  assert core.limited_steps(1000, "long") == "long" and core.limited_steps(1000, True) is True
  with pytest.raises(ValueError, match=r"^unknown ladder task 'ship'; allowed: "):
    ship_ladder.episode_steps("ship", "hard")
  with pytest.raises(ValueError, match=r"unknown level 'stormy'"):
    ship_ladder.episode_steps("ship_current", "stormy")


@pytest.mark.parametrize("task", ship_ladder.TASKS)
@pytest.mark.parametrize("level", ship_ladder.LEVELS)
def test_every_path_closes_at_the_levels_limit(task, level):
  limit = ship_ladder.episode_steps(task, level, 10_000)
  assert limit <= 10_000 and ship_ladder.episode_steps(task, level, 300) == 300
  env_id = ship_ladder.ENV_IDS[task]
  env = gymnasium.make(env_id, level=level, backend="analytic", max_steps=10_000)
  assert env.unwrapped.rules.max_steps == limit
  vec = gymnasium.make_vec(env_id, 2, level=level, backend="analytic", max_steps=10_000)
  assert vec.unwrapped.rules.max_steps == limit
  dm = suite.load(task, level, {"random": 0, "max_steps": 10_000})
  assert dm.task.rules.max_steps == limit
  assert ladder.world(task, level, max_steps=10_000).params.max_steps == limit
  assert task_of(f"{task}/{level}", max_steps=10_000).max_steps == limit
  assert task_of(f"{task}/{level}").max_steps == ship_ladder.episode_steps(task, level)
  settings = _ladder.LadderEnvironment(world=task, level=level, max_steps=10_000)
  assert settings.episode_steps == limit


def test_the_hard_levels_that_close():
  # SPEC section 11: the regatta's, the current's and the harbour's hard levels close
  # after 1,000 control steps; no other level closes.
  closes = {(task, level): ship_ladder.episode_steps(task, level, 10_000)
            for task in ship_ladder.TASKS for level in ship_ladder.LEVELS}
  assert {key: value for key, value in closes.items() if value < 10_000} == {
      ("ship_current", "hard"): 1000, ("ship_regatta", "hard"): 1000,
      ("ship_harbour", "hard"): 1000}
