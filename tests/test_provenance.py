"""Every saved agent, finished run and report records what made it; an agent made
by another version says so when loaded; nothing is overwritten silently."""
import hashlib
import json
import re
import warnings
from importlib import metadata

import numpy as np
import pytest

import hpg_mj
from hpg_mj import agents, cli, provenance
from hpg_mj.experiments import runs
from experiment_file import experiment_text

TINY = experiment_text("tiny", "taxi_fuel_flat_q", 2, 1000, "one task, two seeds",
                       "mean_return", ylabel="return")
COMMIT = re.compile(r"^([0-9a-f]{40}(-dirty)?|unknown)$")


def _check(record, task, seed):
  assert record["hpg_mj"] == hpg_mj.__version__ == metadata.version("hpg_mj")
  assert COMMIT.match(record["git_commit"]), record["git_commit"]
  for dist, key in (("numpy", "numpy"), ("numba", "numba"), ("mujoco", "mujoco"),
                    ("dm-control", "dm_control"), ("gymnasium", "gymnasium")):
    assert record[key] == metadata.version(dist)
  assert record["python"].count(".") == 2
  assert record["task_file_sha256"] == hashlib.sha256(task.text.encode()).hexdigest()
  assert record["seed"] == seed and record["cores"] >= 1


def test_a_saved_agent_records_its_provenance(tmp_path):
  task = agents.load_task("taxi_fuel_flat_q")
  agent, record, _ = agents.train(task, episodes=20, seed=4)
  agents.save(agent, tmp_path / "agent", record)
  meta = json.loads((tmp_path / "agent" / "agent.json").read_text())
  _check(meta["provenance"], task, 4)
  with warnings.catch_warnings():
    warnings.simplefilter("error")                  # the same version: no warning
    agents.load(tmp_path / "agent")


def test_an_agent_of_another_version_says_so(tmp_path, capsys):
  task = agents.load_task("taxi_fuel_flat_q")
  agent, record, _ = agents.train(task, episodes=20, seed=0)
  agents.save(agent, tmp_path / "agent", record)
  path = tmp_path / "agent" / "agent.json"
  meta = json.loads(path.read_text())
  meta["provenance"].update(numba="0.59.0", git_commit="0" * 40)
  path.write_text(json.dumps(meta))
  with pytest.warns(provenance.VersionWarning,
                    match=rf"numba 0.59.0, here {metadata.version('numba')}") as caught:
    agents.load(tmp_path / "agent")
  assert f"git_commit {'0' * 40}, here" in str(caught[0].message)
  assert cli.main(["evaluate", str(tmp_path / "agent"), "--episodes", "3", "--json"]) == 0
  err = capsys.readouterr().err
  assert err.startswith(f"hpg-mj evaluate: warning: {tmp_path / 'agent'} was made by another "
                        "version: ")
  del meta["provenance"]
  path.write_text(json.dumps(meta))
  with pytest.warns(provenance.VersionWarning, match="records no versions"):
    agents.load(tmp_path / "agent")


def test_a_commit_that_differs_only_in_uncommitted_changes_says_so(monkeypatch):
  # A newcomer read "git_commit 29cbed2..., here 29cbed2...-dirty" as two versions.
  commit = "a" * 40
  for then, now, words in ((commit, commit + "-dirty", "with"), (commit + "-dirty", commit,
                                                                  "without")):
    monkeypatch.setattr(provenance, "versions",
                        lambda: {key: "x" for key in provenance.VERSION_KEYS} | {"git_commit": now})
    recorded = {key: "x" for key in provenance.VERSION_KEYS} | {"git_commit": then}
    assert provenance.differences(recorded) == [
        f"git_commit {then}, here the same commit {words} uncommitted changes to the "
        "checkout's files"]
  recorded["git_commit"] = "b" * 40
  assert provenance.differences(recorded) == [f"git_commit {'b' * 40}, here {commit}"]


def test_a_finished_run_and_its_report_record_their_provenance(tmp_path, capsys):
  task = agents.load_task("taxi_fuel_flat_q")
  metrics = runs.run(str(task.path), 2, 1000, tmp_path / "run")
  _check(metrics["provenance"], task, 2)
  assert json.loads((tmp_path / "run" / "metrics.json").read_text()) == metrics
  _check(json.loads((tmp_path / "run" / "agent" / "agent.json").read_text())["provenance"],
         task, 2)
  experiment = tmp_path / "tiny.toml"
  experiment.write_text(TINY)
  assert cli.main(["run", str(experiment), "--out", str(tmp_path / "out"), "--quiet",
                   "--workers", "1"]) == 0
  report = (tmp_path / "out" / "tiny" / "REPORT.md").read_text()
  section = report.split("## Provenance", 1)[1]
  here = provenance.versions()
  assert (f"hpg_mj {here['hpg_mj']} (commit {here['git_commit']}), python {here['python']}, "
          f"numpy {here['numpy']}, numba {here['numba']}, mujoco {here['mujoco']}, dm_control "
          f"{here['dm_control']}, gymnasium {here['gymnasium']}") in section
  assert "- Runs made by " in section and ": all of them." in section
  sha = hashlib.sha256(task.text.encode()).hexdigest()
  assert f"| taxi_fuel_flat_q | {sha} | 0, 1 |" in section


def test_train_refuses_to_replace_an_agent_without_force(tmp_path, capsys):
  out = tmp_path / "agent"
  base = ["train", "taxi_fuel_flat_q", "--episodes", "30", "--out", str(out), "--quiet", "--json"]
  assert cli.main(base) == 0
  first = (out / "arrays.npz").read_bytes()
  capsys.readouterr()
  assert cli.main(base[:3] + ["40"] + base[4:]) == 2
  assert capsys.readouterr().err == (f"hpg-mj train: error: {out} holds a saved agent "
                                     "(agent.json, arrays.npz); pass --force to replace it, or "
                                     "choose another --out\n")
  assert (out / "arrays.npz").read_bytes() == first
  assert cli.main(base[:3] + ["40"] + base[4:] + ["--force"]) == 0
  assert json.loads((out / "agent.json").read_text())["episodes"] == 40


@pytest.mark.parametrize("argv, message", [
    (["evaluate", "AGENT", "--episodes", "0"], "argument --episodes: 0 is out of range; allowed: >= 1"),
    (["evaluate", "AGENT", "--episodes", "-5"], "argument --episodes: -5 is out of range; allowed: >= 1"),
    (["evaluate", "AGENT", "--episodes", "ten"], "argument --episodes: 'ten' is not an integer; allowed: >= 1"),
    (["train", "taxi_fuel_flat_q", "--episodes", "0"], "argument --episodes: 0 is out of range; allowed: >= 1"),
    (["train", "taxi_fuel_flat_q", "--seed", "-1"], "argument --seed: -1 is out of range; allowed: >= 0"),
    (["run", "fig6", "--workers", "0"], "argument --workers: 0 is out of range; allowed: >= 1"),
    (["run", "fig6", "--checkpoint-every", "-3"], "argument --checkpoint-every: -3 is out of range; allowed: >= 1"),
])
def test_bad_counts_are_refused_with_the_allowed_range(argv, message, capsys):
  with pytest.raises(SystemExit) as exit_:
    cli.main(argv)
  assert exit_.value.code == 2
  err = capsys.readouterr().err
  # One line (issue 23), not argparse's usage block.
  assert err == f"hpg-mj {argv[0]}: error: {message} (see hpg-mj {argv[0]} --help)\n"


def test_a_reports_provenance_names_seeds_by_their_ranges():
  """REPORT.md's provenance lists a task's seeds as ranges where they run on (the ladder's
  report named each of its ~1,000 runs one by one)."""
  from hpg_mj.experiments import figures
  assert figures.seed_list([1009, *range(1000, 1009), 1011, 1013, 1014]) == \
      "1000-1009, 1011, 1013, 1014"
  assert figures.seed_list([]) == ""
  made = lambda commit: {"hpg_mj": "0.1.0", "git_commit": commit}
  results = {"a_easy": [{"seed": s, "provenance": made("x")} for s in range(1000, 1010)],
             "b_easy": [{"seed": s, "provenance": made("y")} for s in (1100, 1101, 1102)]}
  lines = figures.provenance_lines(results)
  made_lines = [line for line in lines if line.startswith("- Runs made by")]
  assert len(made_lines) == 2
  assert made_lines[0].endswith(": a_easy seeds 1000-1009.")
  assert made_lines[1].endswith(": b_easy seeds 1100-1102.")
  assert "| a_easy | None | 1000-1009 |" in lines
