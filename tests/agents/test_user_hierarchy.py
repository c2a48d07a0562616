"""A user's hierarchy from scratch (the README's `Waypoints`: a `ShipHierarchy` of the
user's own rules and a subtask with arguments), in the user's own module, through the
command line by its import path: trained, saved by node name, evaluated on both
backends, and resumed from a checkpoint to the same numbers as a run never stopped."""
import json
import os
import pathlib
import re
import subprocess
import sys

import numpy as np
import pytest

from hpg_mj import storage
from hpg_mj.experiments import runs

REPO = pathlib.Path(__file__).resolve().parents[2]
CLI = [sys.executable, "-c", "import sys; from hpg_mj import cli; sys.exit(cli.main(sys.argv[1:]))"]

TASK = """
[task]
kind = "my_hierarchy:Waypoints"
description = "the README's waypoints, from the user's own module"
[environment]
world = "ship"
backend = "analytic"
gate_reward = 100.0
out_of_bounds_reward = -100.0
max_steps = 1000
[protocol]
episodes = 600
seed = 0
"""


def _module(folder):
  """my_hierarchy.py: the README block's code up to its class, as a user saves it."""
  text = (REPO / "README.md").read_text().split("## Write your own hierarchy\n", 1)[1]
  code = re.search(r"```python\n(.*?)```", text, re.S).group(1).split("agent = Waypoints")[0]
  (folder / "my_hierarchy.py").write_text(code)
  (folder / "t.toml").write_text(TASK)


def _run(folder, *args):
  return subprocess.run(CLI + [str(a) for a in args], capture_output=True, text=True,
                        cwd=folder, env=dict(os.environ, PYTHONPATH=""))


def test_the_command_line_trains_saves_and_evaluates_it(tmp_path):
  _module(tmp_path)
  done = _run(tmp_path, "train", "t.toml", "--episodes", 300, "--out", "a", "--json")
  assert done.returncode == 0, done.stderr
  assert json.loads(done.stdout)["episodes_measured"] == 300
  saved = storage.load(tmp_path / "a")[1]
  assert {"rng_state", "root.q", "root.trace_index", "goto.theta", "goto.values"} <= set(saved)
  assert np.any(saved["root.q"] != 0.0) and np.any(saved["goto.theta"] != 0.0)
  for backend in ("analytic", "mujoco"):
    done = _run(tmp_path, "evaluate", "a", "--episodes", 2, "--backend", backend, "--json")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["episodes_measured"] == 2


def test_a_run_stopped_and_resumed_gives_the_numbers_of_one_never_stopped(tmp_path, monkeypatch):
  _module(tmp_path)
  monkeypatch.syspath_prepend(str(tmp_path))
  task = str(tmp_path / "t.toml")
  runs.run(task, 0, 600, tmp_path / "whole", checkpoint_every=200)
  with pytest.raises(runs.RunInterrupted):
    runs.run(task, 0, 600, tmp_path / "cut", checkpoint_every=200, stop_after=300)
  runs.run(task, 0, 600, tmp_path / "cut", checkpoint_every=200)
  np.testing.assert_array_equal(np.load(tmp_path / "whole" / "record.npy"),
                                np.load(tmp_path / "cut" / "record.npy"))
  whole, cut = (storage.load(tmp_path / d / "agent")[1] for d in ("whole", "cut"))
  assert sorted(whole) == sorted(cut)
  for name in whole:
    np.testing.assert_array_equal(whole[name], cut[name], err_msg=name)


def test_a_trained_folder_trained_further_is_the_run_never_stopped(tmp_path):
  """`hpg-mj train --resume DIR --episodes N` goes on from the saved generator and
  learners: 200 + 100 episodes save the arrays and record of 300 at once, bit for bit;
  what the saved agent fixes (its task file, seed, folder) is refused in one line."""
  _module(tmp_path)
  said = {}
  for args in (("t.toml", "--episodes", 200, "--out", "a"), ("--resume", "a", "--episodes", 100),
               ("t.toml", "--episodes", 300, "--out", "b")):
    done = _run(tmp_path, "train", *args, "--json")
    assert done.returncode == 0, done.stderr
    said[args[0]] = json.loads(done.stdout)
  assert said["t.toml"]["episodes"] == 300 and "resumed_from" not in said["t.toml"]
  assert [said["--resume"][k] for k in ("episodes", "resumed_from", "episodes_added")] == [
      300, 200, 100]                      # the whole record's, and what this run added
  (meta_a, a), (_, b) = storage.load(tmp_path / "a"), storage.load(tmp_path / "b")
  assert sorted(a) == sorted(b) and len(a["record"]) == 300 and meta_a["episodes"] == 300
  for name in a:
    np.testing.assert_array_equal(a[name], b[name], err_msg=name)
  assert not [p for p in os.listdir(tmp_path) if ".resumed-" in p or ".before-" in p]
  for args, said in ((("--resume", "a"), "--resume: give --episodes N, the episodes to train "
                      "further"),
                     (("t.toml", "--resume", "a", "--episodes", 5), "--resume takes no task "
                      "file: the saved agent goes on with its own task file and generator, "
                      "into its own folder"),
                     (("--resume", "a", "--episodes", 5, "--set", "environment.max_steps=9"),
                      "--resume takes no --set: the saved agent goes on with its own task "
                      "file and generator, into its own folder; to go on with keys set (a "
                      "curriculum: environment.level=hard), from Python: agents.rebuilt(agent, "
                      "['environment.level=hard']).train(n)")):
    done = _run(tmp_path, "train", *args)
    assert done.returncode == 2 and done.stderr.strip().splitlines() == [
        f"hpg-mj train: error: {said}"], done.stderr


def test_evaluated_from_another_folder_it_says_where_its_class_was(tmp_path):
  _module(tmp_path)
  assert _run(tmp_path, "train", "t.toml", "--episodes", 5, "--out", "a").returncode == 0
  (tmp_path / "elsewhere").mkdir()
  done = _run(tmp_path / "elsewhere", "evaluate", tmp_path / "a", "--episodes", 2)
  assert done.returncode == 2 and done.stderr.strip().splitlines()[-1] == (
      "hpg-mj evaluate: error: t.toml: [task] kind = 'my_hierarchy:Waypoints': no module "
      "'my_hierarchy' in the current folder or on sys.path: run from the folder that holds "
      "my_hierarchy.py, or put that folder on PYTHONPATH (its class was saved from "
      f"{tmp_path / 'my_hierarchy.py'})")


def test_made_and_saved_in_python_without_a_task_file_it_loads_in_another_process(tmp_path):
  """The README's own lines (`Waypoints(seed=0)`, no task file), then `agents.save`:
  the saved folder records a task file that rebuilds its configuration, so another
  process loads it by its class's import path and the command line evaluates it; a
  class defined in the script itself (__main__) is refused in one line saying why."""
  _module(tmp_path)
  script = ("import sys\nfrom hpg_mj import agents\nfrom hpg_mj.taskfile import updated\n"
            "{head}\nagent = Waypoints(updated(Waypoints.Config(), environment={{'max_steps': 300}}),"
            " seed=2)\nrecord = agent.train(40)\nagents.save(agent, sys.argv[1], record)\n"
            "print(sorted(agent.parameters()))\n")
  (tmp_path / "make.py").write_text(script.format(head="from my_hierarchy import Waypoints"))
  done = subprocess.run([sys.executable, "make.py", "in_module"], capture_output=True,
                        text=True, cwd=tmp_path, env=dict(os.environ, PYTHONPATH=""))
  assert done.returncode == 0, done.stderr
  meta = json.loads((tmp_path / "in_module" / "agent.json").read_text())
  assert meta["kind"] == "my_hierarchy:Waypoints" and "max_steps = 300" in meta["task_text"]
  done = _run(tmp_path, "evaluate", "in_module", "--episodes", 2, "--json")
  assert done.returncode == 0, done.stderr
  assert json.loads(done.stdout)["episodes_measured"] == 2
  # as `python make.py` would have saved it with the class written in make.py itself
  (tmp_path / "in_script").mkdir()
  for name in os.listdir(tmp_path / "in_module"):
    text = (tmp_path / "in_module" / name).read_bytes()
    if name == "agent.json":
      text = text.replace(b"my_hierarchy:Waypoints", b"__main__:Waypoints")
    (tmp_path / "in_script" / name).write_bytes(text)
  done = _run(tmp_path, "evaluate", "in_script", "--episodes", 2)
  assert done.returncode != 0
  assert "saved from a class defined in a script (__main__), which another process cannot " \
         "import: put the class in a module" in done.stderr.strip().splitlines()[-1]


def test_record_fields_the_machine_does_not_fill_or_the_metrics_need_are_one_line(tmp_path):
  """A misspelt record field would stay a column of zeros, a missing `passed` would fail
  only at the metrics, after training: both are refused when the graph is built, from
  the command line in one line naming the class, the field and what is allowed."""
  _module(tmp_path)
  text = (tmp_path / "my_hierarchy.py").read_text()
  for name, fields, expected in (
      ("Misspelt", '("passed", "steps", "return", "goto_succeses")',
       r"Misspelt.record_fields: 'goto_succeses' is no field the machine records; allowed: "
       r"\['passed', 'steps', 'return', 'illegal', 'calls', 'goto_runs', 'goto_successes', "
       r"'turn_runs', 'turn_successes'\]$"),
      ("NoPassed", '("steps", "return", "goto_runs")',
       r"NoPassed.record_fields lacks \['passed'\]: the task's metrics read "
       r"\['passed', 'steps', 'return'\]$")):
    text += f"\n\nclass {name}(Waypoints):\n  record_fields = {fields}\n"
    (tmp_path / f"{name}.toml").write_text(TASK.replace("my_hierarchy:Waypoints",
                                                        f"my_hierarchy:{name}"))
    (tmp_path / "my_hierarchy.py").write_text(text)
    done = _run(tmp_path, "train", f"{name}.toml", "--episodes", 5, "--out", name)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert re.search(expected, done.stderr.strip()), done.stderr
    assert not (tmp_path / name).exists()
