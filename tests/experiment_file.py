"""A one-curve experiment file for the tests of the run machinery (on the tuning
seeds, which the machinery under test may use), and what a finished run is, for
comparing two runs."""
import json
import pathlib

import numpy as np

from hpg_mj import storage

TEMPLATE = """
[experiment]
name = "{name}"
description = "{description}"
tasks = ["{task}"]
runs = {runs}
episodes = {episodes}
quick_runs = 1
quick_episodes = 1000
tuning = true     # the machinery under test, on tuning seeds

[[figure]]
name = "curve"
kind = "curve"
metric = "{metric}"
x = "episodes"
title = "a curve"
ylabel = "{ylabel}"
paper = "nothing"
"""


def experiment_text(name, task, runs, episodes, description="one task", metric=None,
                    ylabel="a metric"):
  """The text of the experiment file; the metric defaults to the task's world's."""
  metric = metric or ("mean_return" if task.startswith("taxi") else "gate_passes")
  return TEMPLATE.format(name=name, description=description, task=task, runs=runs,
                         episodes=episodes, metric=metric, ylabel=ylabel)


def final_run(run_dir):
  """The finished run: metrics without the seconds, record, final agent arrays."""
  run_dir = pathlib.Path(run_dir)
  metrics = json.loads((run_dir / "metrics.json").read_text())
  wall = metrics.pop("wall_seconds")
  # compile + train = wall (the seconds differ from run to run; numba's compiling apart)
  assert abs(metrics.pop("compile_seconds") + metrics.pop("train_seconds") - wall) < 0.0015
  metrics.pop("provenance")     # what made it, not what it is (a Ray worker may run the checkout)
  _, arrays = storage.load(run_dir / "agent")
  return metrics, np.load(run_dir / "record.npy"), arrays


def assert_same_run(a, b):
  """Two `final_run`s are equal: metrics, record and every array of the agent."""
  assert a[0] == b[0]
  np.testing.assert_array_equal(a[1], b[1])
  assert sorted(a[2]) == sorted(b[2])
  for name in a[2]:
    np.testing.assert_array_equal(a[2][name], b[2][name], err_msg=name)


def assert_refused(tmp_path, text, message):
  """An experiment file of this text is refused when loaded, before anything runs."""
  import pytest

  from hpg_mj import taskfile
  from hpg_mj.experiments import runner
  path = tmp_path / "bad.toml"
  path.write_text(text)
  with pytest.raises(taskfile.TaskFileError, match=message):
    runner.load_experiment(path)
