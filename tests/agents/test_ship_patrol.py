"""The continuing ship task's agent (SPEC section 8): its task file's protocol in
hours or control steps, the compiled loop against the Gymnasium environment, the
comparison `hpg-mj train --json` prints, and the refusals."""
import json

import gymnasium
import numpy as np
import pytest

from hpg_mj import agents, cli
from hpg_mj.hierarchy import patrol
from hpg_mj.hierarchy import ship_rules
from hpg_mj.taskfile import TaskFileError
from hpg_mj.render import video
from hpg_mj.worlds import ship_core as core

TASK = agents.shipped_tasks()["ship_patrol_average_reward"]


def small_task(tmp_path, protocol="hours = 2", episodic_episodes=30, name="patrol.toml"):
  text = TASK.read_text()
  text = text.replace("hours = 2500", protocol)
  text = text.replace("episodic_episodes = 0 ", f"episodic_episodes = {episodic_episodes} ")
  text = text.replace("evaluation_hours = 100", "evaluation_hours = 1")
  path = tmp_path / name
  path.write_text(text)
  return path


def test_the_shipped_protocol_is_in_hours():
  task = agents.load_task("ship_patrol_average_reward")
  assert task.protocol.episodes == 2500                 # record rows of one hour each
  assert task.control_steps == 2500 * core.HOUR_STEPS
  assert agents.lookup("ship_patrol").record_steps == 6000


@pytest.mark.parametrize("protocol,match", [
    ("hours = 2\nepisodes = 2", r"exactly one of \['episodes', 'control_steps', 'hours'\]"),
    ("control_steps = 9000", r"control_steps = 9000 must be a positive whole number of "
                             r"record rows of 6000 control steps"),
    ("hours = -1", "must be a positive whole number"),
    ("hours = \"two\"", "hours must be a number"),
    ("control_steps = 1.5", "control_steps must be an integer"),
    ("", r"exactly one of .* got none"),
])
def test_bad_protocols_are_refused(tmp_path, protocol, match):
  path = small_task(tmp_path, protocol)
  with pytest.raises(TaskFileError, match=match):
    agents.load_task(path)


def test_an_episodic_agent_refuses_a_length_in_hours(tmp_path):
  text = agents.shipped_tasks()["ship_hybrid"].read_text().replace("episodes = 50000",
                                                                   "hours = 10")
  (tmp_path / "h.toml").write_text(text)
  with pytest.raises(TaskFileError, match="hours is for continuing agents; 'ship_hybrid' is "
                                          "episodic: give \\[protocol\\] episodes"):
    agents.load_task(tmp_path / "h.toml")


def test_control_steps_give_the_same_rows_as_hours(tmp_path):
  a = agents.load_task(small_task(tmp_path, "control_steps = 12000", name="a.toml"))
  b = agents.load_task(small_task(tmp_path, "hours = 2", name="b.toml"))
  assert a.protocol.episodes == b.protocol.episodes == 2
  assert a.control_steps == b.control_steps == 12000


def test_the_process_goes_on_between_training_calls(tmp_path):
  agent = agents.build(agents.load_task(small_task(tmp_path)), seed=3)
  first = agent.train(1)
  assert first["steps"][0] >= 6000 and first["steps"][0] < 6000 + 300   # a call is not cut
  where = agent.ship.copy()
  again = agents.build(agents.load_task(small_task(tmp_path)), seed=3)
  again.train(1)
  np.testing.assert_array_equal(again.ship, where)     # seeded
  second = agent.train(1)
  assert not np.array_equal(agent.ship, where) and second["calls"][0] > 0
  assert agent.metrics(np.concatenate([first, second]))["hours"] == pytest.approx(
      (first["steps"][0] + second["steps"][0]) / 6000)


def test_the_mujoco_ship_sails_the_patrol_step_by_step(tmp_path):
  agent = agents.build(agents.load_task(small_task(tmp_path)), seed=0)
  record = agent.evaluate(1, "mujoco")          # the step-by-step path, greedy
  assert record["steps"][0] >= 6000 and record["calls"][0] >= 20
  assert agent.episodes == 0 and agent.started[0] == 0.0   # no learning, no process


def test_the_compiled_helmsman_sails_as_the_gymnasium_patrol_does():
  # One rule for both paths: the scripted figure-eight helmsman through
  # hpg_mj/ShipPatrol-v0 (analytic) and in the compiled loop, from the same start.
  start = np.array([620.0, 150.0, -30.0, 4.0])
  env = gymnasium.make("hpg_mj/ShipPatrol-v0", backend="analytic", max_steps=3000).unwrapped
  obs, _ = env.reset(options={"state": start})
  pilot = video.ShipPilot("patrol")
  gates = 0
  for _ in range(3000):
    obs, _, _, _, info = env.step(pilot(obs))
    gates += info["event"] == "gate"
  rows = np.zeros((1, patrol.N_RECORD))
  ship = start.copy()
  patrol.scripted(1, 3000, np.zeros(4, dtype=np.uint64), ship, 100.0, -100.0, rows)
  assert rows[0, patrol.GATES] == gates and gates >= 50        # half an hour
  np.testing.assert_allclose(ship, obs, atol=1e-9)


def test_train_needs_no_episodes_and_prints_the_comparison(tmp_path, capsys):
  path = small_task(tmp_path)
  assert cli.main(["train", str(path), "--seed", "5", "--json", "--quiet",
                   "--out", str(tmp_path / "agent")]) == 0
  metrics = json.loads(capsys.readouterr().out)
  assert metrics["episodes"] == 2 and metrics["hours"] >= 2.0
  for key in ("gates_per_hour", "greedy_gates_per_hour", "episodic_gates_per_hour",
              "scripted_gates_per_hour"):
    assert isinstance(metrics[key], float) and metrics[key] >= 0.0, key
  assert metrics["scripted_gates_per_hour"] > 100.0
  assert metrics["episodic_episodes"] == 30 and metrics["evaluation_hours"] == 1
  agent, record, _ = agents.load(tmp_path / "agent")
  assert len(record) == 2 and agent.started[0] == 1.0


def _arrays(agent):
  return {**agent.state(), "ship": agent.ship}


@pytest.mark.parametrize("learn", [True, False])
def test_stepwise_and_compiled_paths_give_identical_results(tmp_path, learn):
  # One algorithm on two paths: the patrol task graph through hpg_mj/ShipPatrol-v0
  # (analytic), the agent's generator drawing the restarts, and the compiled loop.
  task = agents.load_task(small_task(tmp_path))
  stepwise, compiled = agents.build(task, seed=5), agents.build(task, seed=5)
  if not learn:                 # a greedy policy worth sailing: the learned one
    for agent in (stepwise, compiled):
      agent.train(2)
  env = stepwise.stepwise_env("analytic")
  a = stepwise.run_stepwise(env, 2, learn=learn)
  b = compiled.run(2, "analytic", learn=learn)
  np.testing.assert_array_equal(a, b)
  assert a["steps"].min() >= 6000 and a["calls"].sum() > 50
  assert a["departures"].sum() >= 1            # the restart is drawn on both paths alike
  if learn:
    assert a["gates"].sum() >= 1                # a call cut by a gate pass, on both
  for name, value in _arrays(stepwise).items():
    np.testing.assert_array_equal(value, _arrays(compiled)[name], err_msg=name)
  assert stepwise.episodes == compiled.episodes == 2       # learning rows only
  if learn:                     # the shipped planning swept on both paths alike
    assert compiled.model[3][0] == a["calls"].sum() >= 2 * compiled.config.root.planning_every


def test_without_planning_no_model_is_kept_and_the_values_differ(tmp_path):
  planned = agents.build(agents.load_task(small_task(tmp_path)), seed=4)
  path = small_task(tmp_path, name="off.toml")
  path.write_text(path.read_text().replace("planning_every = 100", "planning_every = 0"))
  plain = agents.build(agents.load_task(path), seed=4)
  plain.train(1)
  planned.train(1)
  assert plain.model[0].size == 0 and plain.model[3][0] == 0
  assert planned.model[3][0] >= 100 and (planned.model[0] >= 0).sum() > 10
  assert not np.array_equal(plain.q, planned.q)


def test_stepwise_rows_continue_the_process(tmp_path):
  task = agents.load_task(small_task(tmp_path))
  agent = agents.build(task, seed=2)
  env = agent.stepwise_env("analytic")
  agent.train_stepwise(env, 1)
  where = agent.ship.copy()
  assert agent.started[0] == 1.0 and agent.episodes == 1
  again = agents.build(task, seed=2)
  again.train(1)                                # the compiled path ends at the same state
  np.testing.assert_array_equal(again.ship, where)


def test_a_truncating_environment_is_refused(tmp_path):
  agent = agents.build(agents.load_task(small_task(tmp_path)), seed=0)
  env = gymnasium.make("hpg_mj/ShipPatrol-v0", backend="analytic", max_steps=10)
  with pytest.raises(ValueError, match="rows end between calls; make the patrol environment "
                                       "with max_steps="):
    agent.run_stepwise(env, 1)


@pytest.mark.parametrize("theta,sector", [(-180.0, 0), (179.9, 0), (-157.6, 0), (-157.5, 1),
                                          (0.0, 4), (22.4, 4), (22.5, 5), (-22.5, 4),
                                          (-22.6, 3), (90.0, 6)])
def test_the_root_state_is_the_cell_and_the_heading_sector(theta, sector):
  state = np.array([425.0, 375.0, theta, 0.0])              # cell (8, 7): 8 * 20 + 7
  assert ship_rules.root_state(state, 1) == 167
  assert ship_rules.root_state(state, 8) == 167 * 8 + sector


def test_the_shipped_root_sees_the_heading():
  agent = agents.build(agents.load_task("ship_patrol_average_reward"), seed=0)
  root = agent.config.root
  assert root.heading_sectors == 8 and (root.near_gate_m, root.near_gate_cell_m) == (50.0, 25.0)
  assert agent.q.shape == ((400 + 16) * 8 * 8,) and root.planning_every == 100


def test_finer_cells_about_the_gate_are_numbered_after_the_grid():
  # The square of half-width 100 m about the gate's centre (400, 400), 25 m cells:
  # x0 = y0 = 300, (425, 375) is its cell (5, 3): 400 + 5 * 8 + 3; (250, 375) is
  # outside it, in the 50 m cell (5, 7).
  inside, outside = np.array([425.0, 375.0, 0.0, 0.0]), np.array([250.0, 375.0, 0.0, 0.0])
  assert ship_rules.n_root_cells(100.0, 25.0) == 400 + 64
  assert ship_rules.n_root_cells(0.0, 25.0) == 400
  assert ship_rules.root_state(inside, 1, 100.0, 25.0) == 443
  assert ship_rules.root_state(inside, 8, 100.0, 25.0) == 443 * 8 + 4
  assert ship_rules.root_state(outside, 1, 100.0, 25.0) == 107
  assert ship_rules.root_state(inside, 1, 0.0, 25.0) == 167     # off: the 50 m grid


@pytest.mark.parametrize("line,match", [
    ("near_gate_m = -1.0", r"\[root\] near_gate_m = -1.0 is out of range; allowed: >= 0 and "
                           r"<= 400"),
    ("near_gate_cell_m = 0.5", r"\[root\] near_gate_cell_m = 0.5 is out of range; allowed: "
                               r">= 1 and <= 50"),
])
def test_bad_near_gate_cells_are_refused(tmp_path, line, match):
  path = small_task(tmp_path)
  key = line.split(" =")[0]
  text = "\n".join(line if row.startswith(key + " ") else row
                   for row in path.read_text().splitlines())
  path.write_text(text)
  with pytest.raises(TaskFileError, match=match):
    agents.load_task(path)


def test_near_gate_cells_must_tile_the_square(tmp_path):
  path = small_task(tmp_path)
  path.write_text(path.read_text().replace("near_gate_m = 50.0 ", "near_gate_m = 60.0 "))
  with pytest.raises(ValueError, match=r"near_gate_cell_m = 25.0 must divide twice "
                                       r"near_gate_m = 60.0"):
    agents.build(agents.load_task(path), seed=0)


def test_near_gate_cells_give_identical_results_on_both_paths(tmp_path):
  path = small_task(tmp_path)
  path.write_text(path.read_text().replace("near_gate_m = 50.0 ", "near_gate_m = 100.0 "))
  task = agents.load_task(path)
  stepwise, compiled = agents.build(task, seed=5), agents.build(task, seed=5)
  assert compiled.q.shape == ((400 + 64) * 8 * 8,)
  a = stepwise.run_stepwise(stepwise.stepwise_env("analytic"), 2, learn=True)
  b = compiled.run(2, "analytic", learn=True)
  np.testing.assert_array_equal(a, b)
  assert (compiled.q.reshape(-1, 8)[400 * 8:] != 0).any()      # the fine cells are visited
  for name, value in _arrays(stepwise).items():
    np.testing.assert_array_equal(value, _arrays(compiled)[name], err_msg=name)


def _script(name):
  import importlib.util
  import pathlib
  path = pathlib.Path(__file__).resolve().parents[2] / "scripts" / f"{name}.py"
  spec = importlib.util.spec_from_file_location(name, path)
  script = importlib.util.module_from_spec(spec)
  spec.loader.exec_module(script)
  return script


def test_the_loop_script_sails_what_the_evaluation_sails(tmp_path, capsys):
  # scripts/patrol_loop.py (issue 24) calls the agent's rules directly: its greedy
  # hours are the evaluation's, call for call, so its gates an hour are the same.
  import argparse
  import re
  script = _script("patrol_loop")
  agent = agents.build(agents.load_task(small_task(tmp_path)), seed=1)
  agent.train(2)
  root = agent.config.root
  view = (root.heading_sectors, root.near_gate_m, root.near_gate_cell_m)
  moved = np.full(agent.q.size, 2)
  args = argparse.Namespace(rollouts=1, horizon=200)
  script.report(agent, agent.q, script.low_arrays(agent), view, agent.gain[0], moved, args)
  out = capsys.readouterr().out
  gates = float(re.search(r"greedy: ([\d.]+) gates/h", out).group(1))
  assert gates == pytest.approx(agent.metrics(agent.evaluation(100))["gates_per_hour"], abs=0.05)
  assert "reward over 200 steps minus the greedy's" in out and "nan" not in out
  assert script.period([(1, 2), (3, 4)] * 5) == 2
  assert script.period([(1, 2)] * 4 + [(3, 4)]) is None


def test_the_compare_script_pairs_seeds(tmp_path, capsys):
  script = _script("patrol_compare")
  lines = [{"seed": s, "greedy_gates_per_hour": g, "episodic_gates_per_hour": e,
            "scripted_gates_per_hour": 117.6, "online_gates_per_hour": 90.0}
           for s, g, e in ((3, 200.0, 150.0), (1, 100.0, 130.0), (2, 240.0, 40.0))]
  path = tmp_path / "lines.jsonl"
  path.write_text("\n".join(json.dumps(line) for line in lines) + "\n")
  script.main([str(path)])
  out = capsys.readouterr().out
  assert "Seeds 1-3 (3 runs)" in out
  assert "| paired: root minus episodic hybrid | +73.3 [" in out and "-30.0, 200.0, 50.0" in out
  assert "Root ahead on 2 of 3 seeds; below the helmsman: root 1 (min 100.0), episodic " \
         "hybrid 1 (min 40.0)." in out


def test_both_apis_take_the_task_files_rewards():
  # The patrol's dm_control environment once ignored [environment]'s rewards.
  import dataclasses
  task = agents.load_task("ship_patrol_average_reward")
  agent = agents.build(task, seed=0)
  env_section = dataclasses.replace(agent.config.environment, gate_reward=7.0,
                                    out_of_bounds_reward=-9.0)
  agent.config = dataclasses.replace(agent.config, environment=env_section)
  rules = agent.make_env("dm_control").task.rules
  assert (rules.success_reward, rules.failure_reward) == (7.0, -9.0)
  rules = agent.make_env("gymnasium").unwrapped.rules
  assert (rules.success_reward, rules.failure_reward) == (7.0, -9.0)
