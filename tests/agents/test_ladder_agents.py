"""The task ladder's agents (SPEC section 11): the shipped task files load as their task
and level; a user's `ShipLadderHierarchy` of its own rules saves its state by node
name and resumes to the numbers of a run never stopped; the agents are scored from
the benchmark's own fixed starts, against its bounds; and the command line trains,
evaluates and renders one."""
import dataclasses
import json
import math
import pathlib

import numba
import numpy as np
import pytest

from hpg_mj import agents
from hpg_mj import benchmark
from hpg_mj import cli
from hpg_mj import taskfile
from hpg_mj.agents import ShipLadderHierarchy
from hpg_mj.experiments import bounds
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import Child, Primitive, Subtask, TaskGraph
from hpg_mj.hierarchy.kinds.rules import Abstraction, Features, Termination
from hpg_mj.learners.tiles import TileCoder

REPO = pathlib.Path(__file__).resolve().parents[2]
LADDER_FILES = {f"{task}_{agent}": (task, kind) for task in bounds.LADDER
                for agent, kind in (("hybrid", "ship_ladder_hybrid"),
                                    ("flat_pg", "ship_ladder_flat_pg"),
                                    ("option_critic", "ship_ladder_option_critic"))}
LADDER_FILES.update({f"{task}_waypoints": (task, "ship_ladder_waypoints")  # designed ones
                     for task in bounds.LADDER})


@pytest.mark.parametrize("name", sorted(LADDER_FILES))
def test_the_shipped_task_files_name_their_task_and_level(name):
  task = agents.load_task(name)
  world, kind = LADDER_FILES[name]
  assert task.kind == kind and task.path.name == f"{name}.toml"   # (the wheel ships tasks/)
  agent = agents.build(task, seed=0)
  assert (agent.config.environment.world, agent.config.environment.level) == (world, "easy")
  assert bounds.task_name(agent) == f"{world}/easy"
  assert agent.figure == ("finish_rate" if world == "ship_regatta" else "gate_pass_rate")
  assert task.section("protocol")["tuning_seeds"] == list(range(10))


# ---- a user's hierarchy on the goal ----------------------------------------------------

@numba.njit
def side(obs, call):
  """The root's state: whether the ship is before the gate's line (0) or past it (1)."""
  ahead = (obs[0] - obs[8]) * obs[10] + (obs[1] - obs[9]) * obs[11]
  return 0 if ahead < 0.0 else 1


@numba.njit
def aim(obs, call):
  """The heading error towards the point `call.reach` m before the gate, and the turn."""
  x, y = obs[8] - call.reach * obs[10], obs[9] - call.reach * obs[11]
  bearing = math.degrees(math.atan2(x - obs[0], y - obs[1]))
  return ((obs[2] - bearing + 180.0) % 360.0 - 180.0, obs[3])


@numba.njit
def arrived(obs, call):
  x, y = obs[8] - call.reach * obs[10], obs[9] - call.reach * obs[11]
  if math.hypot(x - obs[0], y - obs[1]) < 30.0:
    return 1
  return -1 if call.steps >= 150 else 0


class GoalApproach(ShipLadderHierarchy):
  """A root that picks how far before the gate to aim, by the side of its line."""
  record_fields = ("passed", "steps", "return", "calls", "goto_successes")

  def graph(self):
    coder = TileCoder(low=(-180, -15), high=(180, 15), n_tiles=(12, 6), wrap=(True, False))
    goto = Subtask("goto", children=["turn"], view=Features(aim),
                   termination=Termination(arrived),
                   learner=blocks.GaussianCMAC(coder, alpha=0.02), reward=blocks.STEP)
    root = Subtask("root", children=[Child("goto", reach=r) for r in (-40.0, 60.0, 150.0)],
                   view=Abstraction(side), termination=blocks.Never(),
                   learner=blocks.QTable(2, epsilon=0.2))
    return TaskGraph("root", [root, goto, Primitive("turn")])


def _goal_config(max_steps=600):
  config = GoalApproach.Config()
  return dataclasses.replace(config, environment=dataclasses.replace(
      config.environment, world="ship_goal", level="easy", max_steps=max_steps))


def test_a_users_ladder_hierarchy_saves_by_node_name_and_resumes_exactly(tmp_path):
  agent = GoalApproach(_goal_config(), seed=3)
  record = agent.train(150)
  assert agent.obs_size == 19 and record["calls"].sum() > 150
  state = agent.state()
  assert {"rng_state", "root.q", "goto.theta", "goto.values"} <= set(state)
  assert np.any(state["root.q"] != 0.0) and np.any(state["goto.theta"] != 0.0)
  agents.save(agent, tmp_path / "a", record)
  loaded, loaded_record, _ = agents.load(tmp_path / "a")
  np.testing.assert_array_equal(loaded_record, record)
  np.testing.assert_array_equal(agent.train(40), loaded.train(40))
  for name, value in agent.state().items():
    np.testing.assert_array_equal(loaded.state()[name], value, err_msg=name)


def test_agents_are_scored_from_the_benchmarks_fixed_starts():
  agent = agents.build(agents.load_task("ship_goal_hybrid"), seed=0)
  options = benchmark.fixed_starts("ship_goal/easy", 4)
  starts = agent.fixed_starts(4)
  np.testing.assert_array_equal(starts[:, :4], options["state"])
  np.testing.assert_array_equal(starts[:, 4:], options["gate"])
  regatta = agents.build(agents.load_task("ship_regatta_flat_pg"), seed=0)
  options = benchmark.fixed_starts("ship_regatta/easy", 2)
  np.testing.assert_array_equal(regatta.fixed_starts(2)[:, 4:],
                                options["course"].reshape(2, -1))
  result = benchmark.evaluate(agent, episodes=3, progress=False)
  assert result.metrics["task"] == "ship_goal" and result.metrics["level"] == "easy"
  assert {"J_normalized", "gate_pass_rate_normalized"} <= set(result.metrics)
  np.testing.assert_array_equal(result.record["steps"], agent.evaluate_fixed(3)["steps"])


def test_an_agent_is_scored_at_another_level_of_its_task_with_what_it_learned(tmp_path,
                                                                             capsys):
  """`benchmark.evaluate(agent, level=...)` and `hpg-mj evaluate RUN --level`: the
  agent's policy at a level it did not learn at (`benchmark.at_level`) is the agent
  built at that level with its learned state put in; the agent itself stays at its own,
  and the metrics name the level it learned at. A level whose bounds differ, for an
  agent that scales by them, and a task with no levels are refused in one line."""
  agent = GoalApproach(_goal_config(), seed=3)          # made in Python: no task file
  agent.train(150)
  got = benchmark.evaluate(agent, level="hard", episodes=6, progress=False)
  hard = GoalApproach(dataclasses.replace(agent.config, environment=dataclasses.replace(
      agent.config.environment, level="hard")), seed=3)
  hard.restore({name: np.array(value) for name, value in agent.state().items()}, "test")
  want = benchmark.evaluate(hard, episodes=6, progress=False)
  np.testing.assert_array_equal(got.record, want.record)
  assert got.metrics == {**want.metrics, "trained_level": "easy"}
  assert benchmark.task_of(agent).level == "easy" and benchmark.at_level(agent, "easy") is agent
  out = tmp_path / "goal"
  assert cli.main(["train", "ship_goal_hybrid", "--episodes", "20", "--out", str(out),
                   "--quiet"]) == 0
  capsys.readouterr()
  assert cli.main(["evaluate", str(out), "--level", "medium", "--episodes", "4", "--json"]) == 0
  printed = json.loads(capsys.readouterr().out)
  there = benchmark.evaluate(agents.load(out)[0], level="medium", episodes=4,
                             progress=False).metrics
  assert (printed["level"], printed["trained_level"]) == ("medium", "easy")
  assert printed["J"] == there["J"] and printed["gate_pass_rate"] == there["gate_pass_rate"]
  # The regatta's levels differ in the count of gates the observation may say (its
  # bounds): a hierarchy reads the numbers as they are and acts there; an agent that
  # scaled them by its level's bounds (PPO and SAC in JAX) would not be the same policy.
  regatta = agents.build(agents.load_task("ship_regatta_flat_pg"), seed=0)
  there = benchmark.evaluate(regatta, level="hard", episodes=2, progress=False).metrics
  assert (there["level"], there["trained_level"], there["max_steps"]) == ("hard", "easy", 1000)

  class Scaling(type(regatta)):
    raw_observation = False

  with pytest.raises(ValueError, match=r"^agent 'ship_ladder_flat_pg' learned at "
                     r"ship_regatta/easy, and at hard its observation's bounds differ at 1 of "
                     r"its numbers \(\[10\] \[0, 3\] there \[0, 8\]\): its policy scales the "
                     r"observation by the bounds it learned with, so it acts only in the spaces "
                     r"it learned in$"):
    benchmark.at_level(Scaling(regatta.config, seed=0), "hard")
  with pytest.raises(ValueError, match=r"^agent 'ship_flat_pg' acts on 'ship', which has no "
                     r"levels; the ladder's tasks have: \['ship_current', "):
    benchmark.at_level(agents.build(agents.load_task("ship_flat_pg")), "hard")


def test_the_command_line_trains_evaluates_and_renders_a_ladder_agent(tmp_path, capsys):
  text = (REPO / "tasks" / "ship_regatta_hybrid.toml").read_text()
  path = tmp_path / "regatta.toml"
  path.write_text(text.replace("max_steps = 5000", "max_steps = 40"))
  out = tmp_path / "agent"
  assert cli.main(["train", str(path), "--episodes", "30", "--out", str(out), "--json",
                   "--quiet"]) == 0
  metrics = json.loads(capsys.readouterr().out)
  assert metrics["episodes_measured"] == 30 and metrics["max_steps"] == 40
  assert {"finish_rate", "gates_passed", "mean_return_normalized",
          "finish_rate_normalized"} <= set(metrics)
  # The step limit in force: at hard the level's time limit, under the file's 5,000.
  assert cli.main(["train", "ship_regatta_hybrid", "--set", "environment.level=hard",
                   "--episodes", "2", "--out", str(tmp_path / "hard"), "--json",
                   "--quiet"]) == 0
  trained = json.loads(capsys.readouterr().out)
  assert (trained["max_steps"], trained["level"]) == (1000, "hard")     # the level it learned at
  for backend in ("analytic", "mujoco"):
    assert cli.main(["evaluate", str(out), "--episodes", "2", "--backend", backend,
                     "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["episodes_measured"] == 2
    # What it acts on, and whether the score is the benchmark's (all 1,000 fixed starts,
    # greedily), as `evaluate --policy` says it.
    assert (got["task"], got["level"], got["official"]) == ("ship_regatta", "easy", False)
  gif = tmp_path / "regatta.gif"
  assert cli.main(["render", "--agent", str(out), "--out", str(gif), "--width", "160",
                   "--height", "128"]) == 0
  assert "a greedy episode" in capsys.readouterr().out
  assert gif.stat().st_size > 1000


def test_the_regattas_score_is_its_return_under_its_own_rewards():
  """A regatta agent trained with other rewards (D1's -300) is scored by its return
  under SPEC section 11's, as every policy is: the same greedy episodes of an agent on
  the task's own rewards return exactly that."""
  from hpg_mj.agents import _ladder
  from hpg_mj.agents.ship_ladder_hybrid import ShipLadderHybrid
  records = {}
  for out_of_bounds in (-100.0, -300.0):
    config = ShipLadderHybrid.Config()
    config = dataclasses.replace(config, environment=dataclasses.replace(
        config.environment, world="ship_regatta", level="hard", max_steps=150,
        out_of_bounds_reward=out_of_bounds))
    agent = ShipLadderHybrid(config, seed=1)
    records[out_of_bounds] = (agent, agent.evaluate_fixed(40))
  own, other = records[-100.0][1], records[-300.0][1]
  np.testing.assert_array_equal(own["steps"], other["steps"])
  assert (own["steps"] == 150).any() and (own["steps"] < 150).any()    # truncated and left
  assert (own["return"] != other["return"]).any()
  agent = records[-300.0][0]
  np.testing.assert_array_equal(_ladder.regatta_returns(other, agent.config.environment),
                                own["return"])
  assert agent.metrics(other)["mean_return"] == pytest.approx(own["return"].mean())
  np.testing.assert_array_equal(agent.scored(other)["finished"], other["passed"])


@pytest.mark.parametrize("changes,message", [
    ({"world": "ship_ocean"}, r"world = 'ship_ocean' is not allowed; allowed: \['ship_current', "
                              r"'ship_goal', 'ship_regatta', 'ship_harbour'\]"),
    ({"level": "insane"}, r"level = 'insane' is not allowed; allowed: \['easy', 'medium', 'hard'\]"),
])
def test_a_section_made_in_python_refuses_what_its_choices_do_not_allow(changes, message):
  """As a task file's loading refuses it: a user's LadderEnvironment(world=..., level=...)
  in Python is one line naming the key and what is allowed, not a run of another task."""
  from hpg_mj.agents import LadderEnvironment
  with pytest.raises(taskfile.TaskFileError, match=message) as err:
    LadderEnvironment(**changes)
  assert "\n" not in str(err.value)
