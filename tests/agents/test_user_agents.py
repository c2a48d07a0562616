"""An agent hpg_mj does not ship, defined outside the package, goes through all of
hpg_mj: registered by an entry point, trained and evaluated by `hpg-mj`, saved and
loaded, checkpointed and resumed after SIGKILL, drawn in an experiment's figure
and REPORT.md. The README's two blocks run exactly as printed (and the hierarchy
tutorial's rule of the user's own)."""
import json
import os
import pathlib
import re
import signal
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest

from hpg_mj import agents
from hpg_mj import provenance
from hpg_mj import storage
from hpg_mj.experiments import runs

REPO = pathlib.Path(__file__).resolve().parents[2]
README = (REPO / "README.md").read_text()
CLI = [sys.executable, "-c", "import sys; from hpg_mj import cli; sys.exit(cli.main(sys.argv[1:]))"]


def _block(heading, text=README):
  """The first python block under a heading of the README (or of `text`)."""
  section = text.split(f"## {heading}\n", 1)[1]
  return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_an_unknown_kind_lists_the_registered_ones(tmp_path):
  path = tmp_path / "t.toml"
  path.write_text('[task]\nkind = "no_such_agent"\n')
  with pytest.raises(agents.TaskFileError, match=r"allowed: \[.*'ship_hybrid'.*'taxi_hpg'"):
    agents.load_task(path)
  with pytest.raises(KeyError, match="registered: .*taxi_maxq"):
    agents.lookup("no_such_agent")


@pytest.mark.parametrize("heading", ["Write your own agent", "Write your own hierarchy"])
def test_the_readme_blocks_run_as_printed(tmp_path, monkeypatch, capsys, heading):
  monkeypatch.chdir(tmp_path)
  exec(compile(_block(heading), f"README.md: {heading}", "exec"), {"__name__": "readme"})
  printed = capsys.readouterr().out
  if heading == "Write your own agent":
    value = float(printed.split(":")[-1])
    assert -200 < value < 20                        # a mean return the taxi can have
  else:                                             # the waypoints, from scratch
    assert int(re.search(r"arrivals: (\d+)", printed).group(1)) > 100
    assert "['goto.theta', 'goto.values', 'root.q']" in printed


def test_the_tutorials_user_rule_ends_the_legs(capsys):
  """docs/tutorial_hierarchy.md's block, as printed: the user's @njit end rule ends
  the legs (100 m is 56 control steps; within its 200-step limit many succeed)."""
  text = (REPO / "docs" / "tutorial_hierarchy.md").read_text()
  exec(compile(_block("A rule of your own", text), "tutorial_hierarchy.md", "exec"), {})
  found = re.search(r"leg successes: (\d+) straight, (\d+) diagonal", capsys.readouterr().out)
  assert int(found.group(1)) + int(found.group(2)) > 10


def test_the_tutorials_taxi_hierarchy_runs_on_the_machine(capsys):
  """docs/tutorial_hierarchy.md's taxi block, as printed: the shipped HPG's blocks over
  a Navigate of the user's (its own view, end and STEP reward) compile into one program
  and deliver."""
  text = (REPO / "docs" / "tutorial_hierarchy.md").read_text()
  namespace = {}
  exec(compile(_block("A hierarchy of your own on the taxi", text), "tutorial_hierarchy.md",
               "exec"), namespace)
  assert type(namespace["agent"].machine).__name__ == "Program"
  delivered = float(re.search(r"delivered: ([\d.]+)", capsys.readouterr().out).group(1))
  assert delivered > 0.3
  assert namespace["agent"].state()["navigate.q"].shape == (125 * 4,)


TASK = """
[task]
kind = "tabular_q"
description = "an agent from another package"
[environment]
world = "taxi"
backend = "analytic"
fuel = false
capacity = 12
max_steps = 200
[policy]
alpha = 0.5
epsilon = 0.1
[protocol]
episodes = 3000
seed = 0
"""

EXPERIMENT = """
[experiment]
name = "mine"
description = "a user's agent in an experiment"
tasks = ["{task}"]
runs = 1
episodes = 3000
quick_runs = 1
quick_episodes = 1000

[[figure]]
name = "mine"
kind = "curve"
metric = "mean_return"
x = "episodes"
title = "my agent"
ylabel = "return"
paper = "nothing"
"""


def _package(tmp_path):
  """my_agents, installed by a dist-info with an entry point in group hpg_mj.agents."""
  site = tmp_path / "site"
  (site / "my_agents").mkdir(parents=True)
  code = _block("Write your own agent").split("agents.register(")[0]
  assert len(code.strip().splitlines()) < 60
  (site / "my_agents" / "__init__.py").write_text(code)
  info = site / "my_agents-0.1.dist-info"
  info.mkdir()
  (info / "METADATA").write_text("Metadata-Version: 2.1\nName: my_agents\nVersion: 0.1\n")
  (info / "entry_points.txt").write_text("[hpg_mj.agents]\ntabular_q = my_agents:TabularQ\n")
  env = dict(os.environ, PYTHONPATH=str(site))
  return env


def _final(run_dir):
  metrics = json.loads((run_dir / "metrics.json").read_text())
  wall = metrics.pop("wall_seconds")          # the seconds differ; compile + train = wall
  assert abs(metrics.pop("compile_seconds") + metrics.pop("train_seconds") - wall) < 0.0015
  return metrics, np.load(run_dir / "record.npy"), storage.load(run_dir / "agent")[1]


def test_an_agent_from_another_package_goes_through_everything(tmp_path):
  env = _package(tmp_path)
  task = tmp_path / "tabular_q.toml"
  task.write_text(TASK)

  def cli(*args, check=True):
    return subprocess.run(CLI + [str(a) for a in args], env=env, capture_output=True, text=True,
                          check=check, cwd=tmp_path)

  trained = json.loads(cli("train", task, "--episodes", 300, "--out", tmp_path / "a",
                           "--json").stdout)
  assert trained["episodes_measured"] == 300 and trained["mean_return"] > -200
  evaluated = json.loads(cli("evaluate", tmp_path / "a", "--episodes", 10, "--json").stdout)
  assert evaluated["episodes_measured"] == 10 and evaluated["policy"] == "greedy"
  # An experiment with it, whole; and killed after its first checkpoint, then resumed.
  experiment = tmp_path / "mine.toml"
  experiment.write_text(EXPERIMENT.format(task=task))
  run = ["run", experiment, "--checkpoint-every", 1000, "--quiet", "--workers", 1]
  cli(*run, "--out", tmp_path / "whole")
  out = tmp_path / "killed"
  run_dir = out / "mine" / "tabular_q" / "seed0"
  proc = subprocess.Popen(CLI + [str(a) for a in run + ["--out", out]], env=env, cwd=tmp_path,
                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
  deadline = time.monotonic() + 300
  while runs.read_progress(run_dir)[0] < 1500 and proc.poll() is None:
    assert time.monotonic() < deadline
    time.sleep(0.01)
  proc.send_signal(signal.SIGKILL)
  proc.wait()
  assert proc.returncode == -signal.SIGKILL and not runs.is_finished(run_dir)
  cli(*run, "--out", out)
  assert "resumed from checkpoint ep" in (run_dir / "events.log").read_text()
  whole, killed = _final(tmp_path / "whole" / "mine" / "tabular_q" / "seed0"), _final(run_dir)
  assert whole[0] == killed[0]
  np.testing.assert_array_equal(whole[1], killed[1])
  for name, value in whole[2].items():
    np.testing.assert_array_equal(value, killed[2][name], err_msg=name)
  report = (out / "mine" / "REPORT.md").read_text()
  assert "tabular_q" in report and (out / "mine" / "mine.png").stat().st_size > 1000


# ---- a user's agent found by the command line without a package (issue 23) ------------

def _module(folder, register):
  """my_agents.py in `folder`: the README block's class, as its section says to put it
  (with or without its `agents.register` line)."""
  code = _block("Write your own agent").split("agents.register(")[0]
  if register:
    code += 'agents.register("tabular_q", TabularQ)\n'
  (folder / "my_agents.py").write_text(code)


def _run(folder, *args):
  return subprocess.run(CLI + [str(a) for a in args], capture_output=True, text=True,
                        cwd=folder, env=dict(os.environ, PYTHONPATH=""))


def test_the_command_line_finds_a_class_by_its_import_path(tmp_path):
  _module(tmp_path, register=False)
  (tmp_path / "t.toml").write_text(TASK.replace('kind = "tabular_q"',
                                                'kind = "my_agents:TabularQ"'))
  done = _run(tmp_path, "train", "t.toml", "--episodes", 50, "--out", "a", "--json")
  assert done.returncode == 0, done.stderr
  assert json.loads(done.stdout)["episodes_measured"] == 50
  meta = json.loads((tmp_path / "a" / "agent.json").read_text())
  assert meta["agent_class"] == "my_agents:TabularQ"
  # Evaluated and filmed in new processes, found by the recorded import path.
  done = _run(tmp_path, "evaluate", "a", "--episodes", 3, "--json")
  assert done.returncode == 0, done.stderr
  assert json.loads(done.stdout)["episodes_measured"] == 3
  done = _run(tmp_path, "render", "--agent", "a", "--out", "a.gif", "--gif", "--width", 32,
              "--height", 32, "--max-frames", 12, "--quiet")
  assert done.returncode == 0, done.stderr
  assert (tmp_path / "a.gif").stat().st_size > 100
  # Where the module cannot be imported, one line says which and why.
  elsewhere = tmp_path / "elsewhere"
  elsewhere.mkdir()
  done = _run(elsewhere, "evaluate", tmp_path / "a", "--episodes", 3)
  assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
  assert "'my_agents:TabularQ': no module 'my_agents'" in done.stderr


def test_import_registers_a_users_module_before_the_command(tmp_path):
  _module(tmp_path, register=True)
  (tmp_path / "t.toml").write_text(TASK)
  done = _run(tmp_path, "train", "t.toml", "--episodes", 50, "--out", "a")
  assert done.returncode == 2 and "kind = 'tabular_q' is not allowed" in done.stderr
  for way in ("'module:Class'", "--import MODULE", "entry-point group 'hpg_mj.agents'"):
    assert way in done.stderr, way                  # the three ways, named
  done = _run(tmp_path, "--import", "my_agents", "train", "t.toml", "--episodes", 50,
              "--out", "a", "--json")
  assert done.returncode == 0, done.stderr
  assert json.loads((tmp_path / "a" / "agent.json").read_text())["kind"] == "tabular_q"
  # A new process without --import: found by the recorded class, whose module registers it.
  done = _run(tmp_path, "evaluate", "a", "--episodes", 3, "--json")
  assert done.returncode == 0, done.stderr
  # A .py path works as a module name does.
  done = _run(tmp_path / "a", "--import", tmp_path / "my_agents.py", "train", tmp_path / "t.toml",
              "--episodes", 20, "--out", tmp_path / "b", "--quiet")
  assert done.returncode == 0, done.stderr


def test_a_module_that_fails_to_import_is_one_line(tmp_path):
  (tmp_path / "broken.py").write_text("x = 1\ny = undefined_name\n")
  done = _run(tmp_path, "--import", "broken", "doctor")
  assert done.returncode == 2 and "Traceback" not in done.stderr
  assert done.stderr.strip() == ("hpg-mj doctor: error: --import broken: importing it raised "
                                 "NameError: name 'undefined_name' is not defined "
                                 f"({tmp_path / 'broken.py'}, line 2)")
  # A .py path never shadows a module imported already (os, imported at start-up).
  (tmp_path / "os.py").write_text("raise SystemExit('must not run')\n")
  done = _run(tmp_path, "--import", "os.py", "doctor")
  assert done.returncode == 2 and "'os' is not an identifier or is taken" in done.stderr


def test_an_agent_saved_from_a_script_says_why_it_is_not_found(tmp_path):
  (tmp_path / "script.py").write_text(_block("Write your own agent") +
                                      'agents.save(agent, "a", record)\n')
  done = subprocess.run([sys.executable, "script.py"], cwd=tmp_path, capture_output=True,
                        text=True)
  assert done.returncode == 0, done.stderr
  meta = json.loads((tmp_path / "a" / "agent.json").read_text())
  assert meta["agent_class"] == "__main__:TabularQ"
  done = _run(tmp_path, "evaluate", "a", "--episodes", 3)
  assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
  assert "defined in a script (__main__)" in done.stderr and "'module:Class'" in done.stderr


def test_load_returns_what_its_docstring_says(tmp_path):
  assert "returns (agent, record, metadata)" in " ".join(agents.load.__doc__.split())
  task = agents.load_task("taxi_fuel_flat_q")
  agent, record, _ = agents.train(task, episodes=7, seed=2)
  agents.save(agent, tmp_path / "a", record, {"metrics": {"x": 1.0}})
  loaded, loaded_record, meta = agents.load(tmp_path / "a")
  assert isinstance(loaded, type(agent)) and loaded.episodes == 7 and loaded.seed == 2
  np.testing.assert_array_equal(loaded_record, record)
  assert meta["metrics"] == {"x": 1.0} and meta["agent_class"] == agents.class_path(type(agent))
  for name, value in agent.state().items():
    np.testing.assert_array_equal(loaded.state()[name], value, err_msg=name)


def test_the_hierarchy_tutorials_task_file_trains_the_readmes_waypoints(tmp_path):
  """docs/tutorial_hierarchy.md's least task file, with the README's Waypoints class in
  my_module.py beside it as the page says, trains and is evaluated by the command line."""
  code = _block("Write your own hierarchy").split("agent = Waypoints(seed=0)")[0]
  (tmp_path / "my_module.py").write_text(code)
  text = (REPO / "docs" / "tutorial_hierarchy.md").read_text().split("## Its task file\n")[1]
  (tmp_path / "mine.toml").write_text(re.search(r"```toml\n(.*?)```", text, re.S).group(1))
  trained = json.loads(_run(tmp_path, "train", "mine.toml", "--episodes", 50, "--out", "runs/mine",
                            "--json").stdout)
  assert trained["episodes_measured"] == 50 and "gate_pass_rate_normalized" in trained
  done = _run(tmp_path, "evaluate", "runs/mine", "--episodes", 5, "--json")
  assert done.returncode == 0, done.stderr
  assert json.loads(done.stdout)["policy"] == "greedy"


def test_the_hierarchy_tutorials_ladder_environment_is_a_whole_section(tmp_path):
  """Its ladder [environment] block, put in a shipped ladder task file in place of its
  own, loads: every key the section needs is in the block."""
  text = (REPO / "docs" / "tutorial_hierarchy.md").read_text().split("## Its task file\n")[1]
  block = re.findall(r"```toml\n(.*?)```", text, re.S)[1]
  shipped = (REPO / "tasks" / "ship_goal_hybrid.toml").read_text()
  head, rest = shipped.split("[environment]\n", 1)
  path = tmp_path / "t.toml"
  path.write_text(head + block + "\n[" + rest.split("\n[", 1)[1])
  task = agents.load_task(path)
  assert (task.config.environment.world, task.config.environment.level) == ("ship_goal", "hard")


def test_a_saved_agent_whose_class_file_was_edited_loads_with_a_warning(tmp_path,
                                                                        monkeypatch):
  """A newcomer edited their module after saving and `hpg-mj evaluate` scored the saved
  agent with the edited rules (0.900 -> 0.698) without a word. The folder records the
  class file's SHA-256; loading it after an edit warns, naming the file."""
  code = _block("Write your own agent").split("agents.register(")[0]
  module = tmp_path / "edited_module.py"
  module.write_text(code)
  monkeypatch.syspath_prepend(str(tmp_path))
  import importlib
  mine = importlib.import_module("edited_module")
  agent = mine.TabularQ(seed=0)
  record = agent.train(5)
  agents.save(agent, tmp_path / "a", record)
  meta = json.loads((tmp_path / "a" / "agent.json").read_text())
  assert meta["agent_file"] == str(module)
  with warnings.catch_warnings():
    warnings.simplefilter("error", provenance.VersionWarning)
    agents.load(tmp_path / "a")                      # unchanged: no warning
  module.write_text(code + "\n# edited\n")
  with pytest.warns(provenance.VersionWarning, match="edited_module.py, has changed since it "
                    "was saved"):
    agents.load(tmp_path / "a")


def test_a_steering_agent_given_a_ladder_environment_is_refused_in_one_line():
  """A newcomer subclassed ShipHierarchy (the steering ship's) with a LadderEnvironment
  for the harbour: it trained the steering ship silently, its rules reading past the
  observation. An agent's sections must be of its Config's classes."""
  code = _block("Write your own hierarchy").split("agent = Waypoints(seed=0)")[0]
  space = {}
  exec(compile(code, "readme", "exec"), space)
  Waypoints = space["Waypoints"]
  environment = agents.LadderEnvironment(world="ship_harbour", level="easy")
  with pytest.raises(ValueError, match=r"^Waypoints: its \[environment\] is a "
                     r"LadderEnvironment; its Config takes a ShipEnvironment; a ladder task's "
                     r"environment is for an agent of the ladder \(subclass "
                     r"hpg_mj.agents.ShipLadderHierarchy"):
    Waypoints(Waypoints.Config(environment=environment), seed=0)
