"""PPO in JAX on the task ladder (`hpg_mj.agents.jax_ppo_ladder`, `ladder_ppo_jax`):
it trains on the current in rows of ship_ppo_jax's record, a saved run and a stopped
`hpg-mj run` resume bit for bit, the level of the task file (or of `--set`) is the
world's and the scorer's, the goal's dictionary is flattened as the JAX world lays
it out, the greedy measure is the ladder's scorer's, and a bad level or world is
refused in one line. Every training test shares one small configuration of the
current, compiled once (8 copies x 16 steps, 2 epochs of 2 minibatches)."""
import json
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("jax.numpy")   # not `jax`: tests/ is on sys.path and holds tests/jax
import jax  # noqa: E402

from hpg_mj import agents  # noqa: E402
from hpg_mj import benchmark  # noqa: E402
from hpg_mj import cli  # noqa: E402
from hpg_mj.experiments import bounds  # noqa: E402
from hpg_mj.jax import ppo_ladder  # noqa: E402
from jax_task_file import SMALL, task_file  # noqa: E402

@pytest.fixture(scope="module")
def small(tmp_path_factory):
  return task_file(tmp_path_factory.mktemp("ladder_ppo"), "ship_current_ppo_jax")


@pytest.fixture(scope="module")
def current(small):
  """The small current/easy agent, seed 0, trained 2 rows, and its record."""
  agent = agents.build(agents.load_task(small), seed=0)
  return agent, agent.train(2)


def test_it_trains_on_the_current_in_rows_of_ship_ppo_jax_s_record(current):
  agent, record = current
  assert agent.record_fields == ("steps",) + ppo_ladder.LadderRow.fields
  assert record["steps"].tolist() == [1000.0, 1000.0]
  assert agent.control_steps == 2048                 # whole updates of 8 x 16
  # The networks see the current's six numbers, each onto [-1, 1] from the level's
  # Box: the water by the easy level's fastest, 1 m/s.
  assert np.asarray(agent.runner.networks["actor"][0]["kernel"]).shape == (6, 64)
  np.testing.assert_allclose(np.asarray(agent.trainer.io.half)[4:], [1.0, 1.0])
  episodes = record["episodes"].sum()
  assert episodes >= 1 and record["gates"].sum() <= episodes
  assert (record["gates_passed"] == record["gates"]).all()    # one gate a course
  # An episode's return is -1 a step plus its ending's reward; its length is at most
  # the control steps trained.
  assert (record["return_sum"] <= -record["episodes"] + 100 * record["gates"]).all()
  metrics = agent.metrics(record)
  assert metrics["episodes_measured"] == episodes and metrics["control_steps"] == 2000
  assert set(metrics) >= {"gate_pass_rate", "steps_to_gate", "mean_return", "J"}


def test_a_saved_run_resumes_bit_for_bit(small, current, tmp_path):
  agent = agents.build(agents.load_task(small), seed=4)
  record = agent.train(2)
  agents.save(agent, tmp_path / "agent", record)
  ahead = agent.train(2)
  loaded, saved_record, _ = agents.load(tmp_path / "agent")
  np.testing.assert_array_equal(saved_record, record)
  np.testing.assert_array_equal(loaded.train(2), ahead)
  mine, theirs = agent.state(), loaded.state()
  assert sorted(mine) == sorted(theirs) and "runner.env_state.x" in mine
  for name in mine:
    np.testing.assert_array_equal(mine[name], theirs[name], err_msg=name)
  # Cut into other calls, the run is the same: 2 + 2 rows = 1 + 3.
  cut = agents.build(agents.load_task(small), seed=4)
  np.testing.assert_array_equal(np.concatenate([cut.train(1), cut.train(3)]),
                                np.concatenate([record, ahead]))


def test_a_run_stopped_after_a_checkpoint_resumes_to_the_same_result(small, current, tmp_path,
                                                                     monkeypatch):
  """`hpg-mj run`'s runner (a checkpoint every row here), stopped after row 2 and run
  again: the same record and greedy scores (16 fixed starts) as the run never stopped."""
  from hpg_mj.agents import jax_ppo
  from hpg_mj.experiments import runs
  monkeypatch.setattr(jax_ppo._JaxAgent, "checkpoint_rows", 1)
  monkeypatch.setattr(runs, "GREEDY_STARTS", 16)
  whole = runs.run(small, 7, 3, tmp_path / "whole")
  with pytest.raises(runs.RunInterrupted):
    runs.run(small, 7, 3, tmp_path / "cut", stop_after=2)
  resumed = runs.run(small, 7, 3, tmp_path / "cut")
  assert "resumed from checkpoint ep2" in (tmp_path / "cut" / "events.log").read_text()
  for name in ("record", "greedy"):
    np.testing.assert_array_equal(np.load(tmp_path / "whole" / f"{name}.npy"),
                                  np.load(tmp_path / "cut" / f"{name}.npy"))
  assert resumed["greedy"] == whole["greedy"]
  assert "J_normalized" in whole["greedy"]           # the scorer's bounds of current/easy


def test_the_greedy_measure_is_the_ladder_scorer_s(current):
  """The agent's greedy episodes (the JAX world, float32, from the scorer's fixed
  starts) are `benchmark.evaluate`'s of its policy (the native vector environment,
  float64), episode by episode; the policy declares the task's spaces and acts in
  deg/s, and evaluating draws nothing the training would."""
  agent, _ = current
  before = {name: np.array(value) for name, value in agent.state().items()}
  greedy = agent.evaluate_fixed(16)
  policy = agent.policy()
  # The agent's task: ship_current/easy, scored under the task's rewards (-100 for
  # leaving), though its file trains with -300 (D1).
  result = benchmark.evaluate(policy, benchmark.task_of(agent), 16, progress=False)
  assert benchmark.task_of(agent).out_of_bounds_reward == -100.0
  assert greedy["episodes"].tolist() == [1.0] * 16
  np.testing.assert_array_equal(greedy["steps"], result.record["steps"])
  left = (greedy["gates"] == 0) & (greedy["steps"] < agent.config.environment.max_steps)
  np.testing.assert_array_equal(greedy["return_sum"] + 200.0 * left, result.record["return"])
  np.testing.assert_array_equal(greedy["gates"], result.record["passed"])
  mine = agent.metrics(greedy)
  for key in ("gate_pass_rate", "mean_return"):
    assert mine[key] == result.metrics[key], key
  assert mine["J"] == pytest.approx(result.metrics["J"], abs=1e-5)
  # The scorer given the agent itself reads its rows (a row an episode) by their names.
  of_agent = benchmark.evaluate(agent, episodes=16, progress=False).record
  for name in ("passed", "steps", "return"):
    np.testing.assert_array_equal(of_agent[name], result.record[name], err_msg=name)
  assert bounds.task_name(agent) == "ship_current/easy"
  space = policy.action_space
  assert (space.low[0], space.high[0], policy.observation_space.shape) == (-15.0, 15.0, (6,))
  rates, _ = policy.predict(np.array([[500.0, 500.0, 0.0, 0.0, 1.0, 0.0]] * 3))
  assert rates.shape == (3,) and (np.abs(rates) <= 15.0).all()
  for name, value in agent.state().items():
    np.testing.assert_array_equal(value, before[name], err_msg=name)


def test_the_ladder_s_names_are_the_scorer_s():
  from hpg_mj import benchmark_tasks
  from hpg_mj.agents import jax_ppo_ladder
  assert jax_ppo_ladder.ENV_IDS == {name: benchmark_tasks.ENV_IDS[name]
                                    for name in benchmark.LADDER}
  assert jax_ppo_ladder.LEVELS == benchmark.LEVELS
  assert set(jax_ppo_ladder.TASKS) >= {"ship_current", "ship_goal"}


def test_the_level_is_the_world_s_and_the_scorer_s(small):
  """`--set environment.level=hard` (as `hpg-mj train` takes it): the JAX world's
  parameters, the observation's scaling, the fixed starts and the bounds are hard's."""
  from hpg_mj import jax as hpg_jax
  from hpg_mj.worlds import ship_current_core
  task = agents.load_task(small, ["environment.level=hard"])
  assert 'level = "hard"' in task.text           # saved with the agent
  agent = agents.build(task)
  assert agent.trainer.params == hpg_jax.make("ShipCurrent-v0", level="hard",
                                              out_of_bounds_reward=-300.0)[1]
  fastest = ship_current_core.max_speed(ship_current_core.level_field("hard"))   # 2.82 m/s
  np.testing.assert_allclose(np.asarray(agent.trainer.io.half)[4:], [fastest] * 2, rtol=1e-6)
  assert bounds.task_name(agent) == "ship_current/hard"
  # Scored under the task's rewards, whatever its file trains with (-300 for leaving).
  assert benchmark.task_of(agent) == benchmark.task_of("ship_current", level="hard")
  np.testing.assert_array_equal(agent.fixed_starts(5)["state"],
                                benchmark.fixed_starts("ship_current/hard", 5)["state"])
  goal = agents.build(agents.load_task("ship_goal_ppo_jax", ["environment.level=medium"]))
  assert (goal.trainer.params.gate_low, goal.trainer.params.gate_high) == (200.0, 800.0)
  np.testing.assert_array_equal(goal.fixed_starts(3)["gate"],
                                benchmark.fixed_starts("ship_goal/medium", 3)["gate"])


def test_another_level_is_scored_only_where_its_scaling_is_the_same(current):
  """PPO in JAX scales the observation by its level's bounds (`trainer.io`): at the
  current's hard level, where the water's bounds are wider, it would not be the policy
  that learned, so it is refused in one line; at the harbour's medium, whose spaces are
  easy's, it is rebuilt with its learned state and scored there."""
  agent, _ = current
  with pytest.raises(ValueError, match=r"^agent 'ladder_ppo_jax' learned at ship_current/easy, "
                     r"and at hard its observation's bounds differ at 2 of its numbers .*: its "
                     r"policy scales the observation by the bounds it learned with, so it acts "
                     r"only in the spaces it learned in$"):
    benchmark.evaluate(agent, level="hard", episodes=2)
  harbour = agents.build(agents.load_task("ship_harbour_ppo_jax"), seed=1)
  there = benchmark.at_level(harbour, "medium")
  assert bounds.task_name(there) == "ship_harbour/medium"
  for name, value in harbour.state().items():
    np.testing.assert_array_equal(np.asarray(there.state()[name]), np.asarray(value), name)


def test_the_goal_s_dictionary_is_flattened_as_the_jax_world_lays_it_out():
  """The scorer's observation (Gymnasium's dictionary) flattened in `GOAL_KEYS` order is
  the JAX world's from the same start: what the policy trained on. And an episode's
  success is the row's gate."""
  agent = agents.build(agents.load_task("ship_goal_ppo_jax", ["environment.level=medium"]))
  gym_env = agent.make_env("gymnasium")
  starts = agent.fixed_starts(3)
  for state, gate in zip(starts["state"], starts["gate"]):
    obs, _ = gym_env.reset(options={"state": state, "gate": gate})
    flat = ppo_ladder.flat({k: v[None] for k, v in obs.items()})[0]
    seen, _ = agent.trainer.start({"state": state, "gate": gate})   # the greedy measure's
    np.testing.assert_allclose(flat, np.asarray(seen), atol=1e-3)
  # Reached, then truncated: the row counts the gate, J, and nothing for the clock.
  row = ppo_ladder.LadderRow(0.99, -1.0, 0.0, -100.0)
  info = {"event": np.array([1, 0, -1]), "terminated": np.array([True, False, True])}
  out = np.asarray(row(np.array([True, True, True]), info, np.array([95.0, -5000.0, -103.0]),
                       np.array([6, 5000, 4])))
  np.testing.assert_allclose(out[:, :4], [[1, 1, 6, 95], [1, 0, 0, -5000], [1, 0, 0, -103]])
  j_left = -(1 - 0.99 ** 3) / 0.01 - 100 * 0.99 ** 3
  np.testing.assert_allclose(out[2, 4], j_left, rtol=1e-5)
  assert out[:, 5].tolist() == [1.0, 0.0, 0.0]


def test_a_bad_level_or_world_is_refused_in_one_line(small):
  for key, value, allowed in (("level", "extreme", r"\['easy', 'medium', 'hard'\]"),
                              ("world", "ship", r"\['ship_current', 'ship_goal'"),
                              ("world", "taxi", r"\['ship_current', 'ship_goal'")):
    with pytest.raises(ValueError, match=rf"ship_current_ppo_jax.toml, with --set "
                                         rf"'environment.{key}={value}': \[environment\] "
                                         rf"{key} = '{value}' is not allowed; allowed: {allowed}"):
      agents.load_task(small, [f"environment.{key}={value}"])
  with pytest.raises(ValueError, match=r"--set 'environment.levl=hard': \[environment\] has no "
                                       r"key 'levl'; its keys: \['backend', "):
    agents.load_task(small, ["environment.levl=hard"])
  with pytest.raises(ValueError, match=r"\[environment\] backend = 'mujoco' is not allowed; "
                                       r"allowed: \['analytic'\]"):
    agents.load_task(small, ["environment.backend=mujoco"])


def test_cli_trains_with_a_level_set_and_prints_the_scorer_s_normalised_score(small, current,
                                                                             tmp_path, capsys):
  """The file says medium, `--set` easy (the small run compiled already): `hpg-mj train`
  prints the greedy measure on easy's 1,000 fixed starts normalized against easy's
  bounds, `hpg-mj evaluate` the same on the first 8."""
  path = task_file(tmp_path, "ship_current_ppo_jax",
                   {**SMALL, 'level = "easy"': 'level = "medium"'})
  out = tmp_path / "agent"
  assert cli.main(["train", str(path), "--set", "environment.level=easy", "--episodes", "1",
                   "--out", str(out), "--quiet", "--json"]) == 0
  trained = json.loads(capsys.readouterr().out)
  greedy = trained["greedy"]
  assert greedy["episodes_measured"] == greedy["starts"] == 1000
  assert "J_normalized" in greedy and "gate_pass_rate_normalized" in greedy
  # the record's one row; the learner trained whole updates of 8 x 16 control steps
  assert trained["control_steps"] == 1000 and trained["control_steps_trained"] == 1024
  assert cli.main(["evaluate", str(out), "--episodes", "8", "--json", "--quiet"]) == 0
  scored = json.loads(capsys.readouterr().out)
  assert scored["episodes_measured"] == 8 and "J_normalized" in scored
  saved = agents.load(out)[0]
  assert saved.config.environment.level == "easy"           # the --set text was saved


def test_the_task_files_load_and_build_without_importing_jax():
  code = ("import sys; from hpg_mj import agents\n"
          "for n in ('ship_current_ppo_jax', 'ship_goal_ppo_jax'):\n"
          "  agents.build(agents.load_task(n, ['environment.level=hard']))\n"
          "print(sorted(m for m in ('jax', 'jaxlib') if m in sys.modules))")
  out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
  assert out.stdout.strip() == "[]"
