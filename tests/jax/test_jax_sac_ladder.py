"""SAC in JAX on the task ladder (`ladder_sac_jax`, `hpg_mj.agents.jax_ppo_ladder`): the
shipped task files load with ship_sac_jax's learner and values on each ladder task, a
small run on the goal (its 19 numbers flattened) trains in the ladder's record, a saved
run resumes bit for bit, and its greedy measure is the ladder scorer's, episode by
episode. One small configuration (2 copies, networks of 16, learning from the 200th
control step), as tests/jax/test_jax_sac.py's."""
import numpy as np
import pytest

pytest.importorskip("jax.numpy")   # not `jax`: tests/ is on sys.path and holds tests/jax

from hpg_mj import agents  # noqa: E402
from hpg_mj import benchmark  # noqa: E402
from hpg_mj.experiments import ladder  # noqa: E402
from hpg_mj.jax import ppo_ladder  # noqa: E402
from jax_task_file import task_file  # noqa: E402

SMALL = {"n_envs = 4": "n_envs = 2", "n_steps = 250": "n_steps = 100",
         "buffer_size = 1000000": "buffer_size = 1500", "learning_starts = 10000":
         "learning_starts = 200", "batch_size = 256": "batch_size = 32",
         "gradient_steps = 4": "gradient_steps = 2", "net_arch = [64, 64] ": "net_arch = [16, 16] "}
TASKS = ("current", "goal", "regatta", "harbour")


@pytest.fixture(scope="module")
def goal(tmp_path_factory):
  """The small goal/easy agent, seed 0, trained 2 rows, and its record."""
  path = task_file(tmp_path_factory.mktemp("ladder_sac"), "ship_goal_sac_jax", SMALL)
  agent = agents.build(agents.load_task(path), seed=0)
  return path, agent, agent.train(2)


@pytest.mark.parametrize("task", TASKS)
def test_the_shipped_files_are_ship_sac_jax_s_learner_on_each_ladder_task(task):
  ship = agents.load_task("ship_sac_jax")
  mine = agents.load_task(f"ship_{task}_sac_jax")
  agent = agents.build(mine, seed=0)
  assert type(agent).__name__ == "LadderSACJax" and agent.algorithm == "sac"
  assert isinstance(agent.trainer, ppo_ladder.LadderSACTrainer)
  assert mine.config.sac == ship.config.sac                  # its values, as tuned there
  assert mine.config.environment.world == f"ship_{task}"
  assert mine.control_steps == ship.control_steps == 1_000_000
  assert mine.tuning["grid"] == ship.tuning["grid"] and mine.tuning["budget"] == 4
  assert mine.tuning["score"] == ("mean_return" if task == "regatta" else "J")
  assert f"ladder_{task}_sac_jax" in ladder.TASKS[f"ship_{task}"]
  # `hpg-mj run` saves a run every 0.1 M steps: a 1 M-step run is 15-25 minutes here.
  assert agent.checkpoint_rows == 100 < mine.protocol.episodes


def test_it_trains_on_the_goal_in_the_ladder_s_record(goal):
  _, agent, record = goal
  assert agent.record_fields == ("steps",) + ppo_ladder.LadderRow.fields
  assert record["steps"].tolist() == [1000.0, 1000.0] and agent.control_steps == 2000
  # The actor reads the goal's 19 numbers; it learned from the 200th step on.
  assert np.asarray(agent.runner.nets.actor[0]["kernel"]).shape == (19, 16)
  assert int(agent.runner.nets.critic_opt["count"]) == 2 * (2000 - 200) // 2
  assert record["gates"].sum() <= record["episodes"].sum()
  assert set(agent.metrics(record)) >= {"gate_pass_rate", "steps_to_gate", "mean_return", "J"}


def test_a_saved_run_resumes_bit_for_bit_and_scores_as_the_scorer(goal, tmp_path):
  path, agent, record = goal
  again = agents.build(agents.load_task(path), seed=0)
  np.testing.assert_array_equal(again.train(2), record)     # a seed is its run
  agents.save(again, tmp_path / "agent", record)
  ahead = again.train(1)
  loaded, saved, _ = agents.load(tmp_path / "agent")
  np.testing.assert_array_equal(saved, record)
  np.testing.assert_array_equal(loaded.train(1), ahead)
  # The greedy measure (the JAX world, float32) is the scorer's of its policy (the
  # native vector environment, float64), episode by episode.
  greedy = loaded.evaluate_fixed(8)
  result = benchmark.evaluate(loaded.policy(), benchmark.task_of(loaded), 8, progress=False)
  assert greedy["episodes"].tolist() == [1.0] * 8
  np.testing.assert_array_equal(greedy["steps"], result.record["steps"])
  np.testing.assert_array_equal(greedy["gates"], result.record["passed"])
  rates, _ = loaded.policy().predict(
      {k: np.zeros((3,) + space.shape) for k, space in
       loaded.policy().observation_space.spaces.items()})
  assert rates.shape == (3,) and (np.abs(rates) <= 15.0).all()
