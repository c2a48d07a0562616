"""An agent hpg_mj does not ship, defined outside the package, goes through all of
hpg_mj: registered by an entry point, trained and evaluated by `hpg-mj`, saved and
loaded, checkpointed and resumed after SIGKILL, drawn in an experiment's figure
and REPORT.md. The README's two blocks run exactly as printed."""
import json
import os
import pathlib
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from hpg_mj import agents
from hpg_mj.agents import storage
from hpg_mj.experiments import runs

REPO = pathlib.Path(__file__).resolve().parents[2]
README = (REPO / "README.md").read_text()
CLI = [sys.executable, "-c", "import sys; from hpg_mj import cli; sys.exit(cli.main(sys.argv[1:]))"]


def _block(heading):
  """The first python block under a README heading."""
  section = README.split(f"## {heading}\n", 1)[1]
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
  else:
    assert "diagonal: 0" in printed                 # the four-way root never sails diagonally
    assert int(re.search(r"straight runs: (\d+)", printed).group(1)) > 0


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
  metrics.pop("wall_seconds")
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
