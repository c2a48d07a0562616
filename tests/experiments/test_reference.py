"""Issue 21's sample-efficiency figures and "Reference scores" table: greedy points
along a run (`runs.run(greedy_at=...)`) that change nothing the run learns and
survive a resume, the experiment key that declares them, and `hpg-mj reproduce
reference` drawn from whatever runs exist (a tabular learner and a real
Stable-Baselines3 one, tiny budgets)."""
import json
import pathlib
import runpy

import numpy as np
import pytest

from hpg_mj import cli
from hpg_mj.experiments import bounds, runner, runs, stats
from experiment_file import assert_refused


def _points(run_dir):
  return [json.loads(line) for line in (run_dir / "greedy_curve.jsonl").read_text().splitlines()]


def test_greedy_points_change_nothing_and_survive_a_resume(tmp_path):
  task = "taxi_fuel_flat_q"
  plain = runs.run(task, 0, 3000, tmp_path / "plain")
  with pytest.raises(runs.RunInterrupted):
    runs.run(task, 0, 3000, tmp_path / "cut", checkpoint_every=1000, stop_after=2000,
             greedy_at=(1000, 2000))
  assert [p["episodes"] for p in _points(tmp_path / "cut")] == [1000, 2000]
  # A point past the checkpoint (written just before a kill) is measured again.
  with open(tmp_path / "cut" / "greedy_curve.jsonl", "a") as f:
    f.write(json.dumps({"episodes": 2500, "steps": 1, "mean_return": 99.0}) + "\n")
  cut = runs.run(task, 0, 3000, tmp_path / "cut", greedy_at=(1000, 2000))
  whole = runs.run(task, 0, 3000, tmp_path / "whole", greedy_at=(1000, 2000))
  for name in ("record", "greedy"):
    plain_array = np.load(tmp_path / "plain" / f"{name}.npy")
    np.testing.assert_array_equal(plain_array, np.load(tmp_path / "cut" / f"{name}.npy"))
    np.testing.assert_array_equal(plain_array, np.load(tmp_path / "whole" / f"{name}.npy"))
  assert cut["greedy"] == whole["greedy"] == plain["greedy"]
  curve = cut["greedy_curve"]
  assert curve == whole["greedy_curve"] == _points(tmp_path / "cut")
  assert [p["episodes"] for p in curve] == [1000, 2000, 3000]
  record = np.load(tmp_path / "plain" / "record.npy")
  assert [p["steps"] for p in curve] == [int(record["steps"][:n].sum()) for n in (1000, 2000, 3000)]
  assert curve[-1] == {"episodes": 3000, "steps": plain["primitive_steps"], **plain["greedy"]}
  assert curve[0]["mean_return_normalized"] == pytest.approx(bounds.normalized(
      "taxi_fuel", curve[0])["mean_return_normalized"])
  assert "greedy_curve" not in plain


def test_greedy_points_leave_a_stable_baselines3_run_as_it_was(tmp_path):
  pytest.importorskip("stable_baselines3")
  from test_sb3 import tiny_task
  path = tiny_task(tmp_path, "taxi_fuel_ppo")
  plain = runs.run(path, 3, 4, tmp_path / "plain")
  pointed = runs.run(path, 3, 4, tmp_path / "pointed", greedy_at=(1, 2))
  np.testing.assert_array_equal(np.load(tmp_path / "plain" / "record.npy"),
                                np.load(tmp_path / "pointed" / "record.npy"))
  assert pointed["greedy"] == plain["greedy"]
  assert [(p["episodes"], p["steps"]) for p in pointed["greedy_curve"]] == [
      (1, 1000), (2, 2000), (4, 4000)]
  # Its greedy scores are over every fixed start, and normalized like every
  # episodic agent's (SPEC 7, 7.1); its online ones over its last rows.
  assert plain["greedy"]["episodes_measured"] == 1000
  assert "mean_return_normalized" in plain["greedy"] and "mean_return_normalized" in plain
  assert plain["rows_measured"] == 4


EXPERIMENT = """
[experiment]
name = "points"
description = "greedy points"
tasks = ["taxi_fuel_flat_q"]
runs = 1
episodes = 3000
quick_runs = 1
quick_episodes = 1000
tuning = true
greedy_at = [100, 1000]

[[figure]]
name = "points"
kind = "greedy_curve"
metric = "mean_return"
reference = "optimal"
title = "greedy points"
ylabel = "mean return, greedy"
paper = "nothing"
"""


@pytest.mark.parametrize("old,new,message", [
    ("greedy_at = [100, 1000]", "greedy_at = [1000, 100]", r"greedy_at = \[1000, 100\]; allowed: "
     r"increasing episode counts in 1..2999"),
    ("greedy_at = [100, 1000]", "greedy_at = [0, 100]", "greedy_at = \\[0, 100\\]; allowed"),
    ("greedy_at = [100, 1000]", "greedy_at = [100, 3000]", "allowed: increasing episode counts"),
    ("greedy_at = [100, 1000]", "greedy_at = 100", "greedy_at must be a non-empty list"),
    ('metric = "mean_return"', 'metric = "J"', r"metric = 'J'; allowed for the taxi: "
     r"\['mean_return', 'mean_return_normalized'\]"),
    ('metric = "mean_return"', 'metric = "mean_return_normalized"',
     "reference = 'optimal' needs metric = 'mean_return'"),
])
def test_malformed_greedy_points_are_refused(tmp_path, old, new, message):
  assert_refused(tmp_path, EXPERIMENT.replace(old, new, 1), message)


def test_an_experiment_of_greedy_points_draws_its_curve(tmp_path, capsys):
  path = tmp_path / "points.toml"
  path.write_text(EXPERIMENT)
  assert cli.main(["run", str(path), "--out", str(tmp_path), "--workers", "1", "--quiet"]) == 0
  metrics = json.loads((tmp_path / "points" / "taxi_fuel_flat_q" / "seed0" / "metrics.json")
                       .read_text())
  rows = (tmp_path / "points" / "points.csv").read_text().splitlines()
  assert rows[0] == ("taxi_fuel_flat_q_mean_return_steps,taxi_fuel_flat_q_mean_return_mean,"
                     "taxi_fuel_flat_q_mean_return_ci_low,taxi_fuel_flat_q_mean_return_ci_high")
  assert [float(r.split(",")[1]) for r in rows[1:]] == pytest.approx(
      [p["mean_return"] for p in metrics["greedy_curve"]], abs=1e-5)
  assert "Ours (greedy, the final agents): Flat Q-learning" in \
      (tmp_path / "points" / "REPORT.md").read_text()


def _finished(out, experiment, task, seed, episodes, greedy_at):
  """A finished run where `hpg-mj reproduce reference --quick` looks for one."""
  return runs.run(task, seed, episodes, out / f"{experiment}_quick" / task.split("/")[-1]
                  .removesuffix(".toml") / f"seed{seed}", greedy_at=greedy_at)


def test_reproduce_reference_draws_whatever_runs_exist(tmp_path, capsys):
  pytest.importorskip("stable_baselines3")
  from test_sb3 import tiny_task
  out = tmp_path / "out"
  flat = [_finished(out, "reference_taxi_hierarchy", "taxi_fuel_flat_q", seed, 2000, (300, 1000))
          for seed in (100, 101)]
  ppo = _finished(out, "reference_taxi", str(tiny_task(tmp_path, "taxi_fuel_ppo")), 100, 3, (1,))
  assert cli.main(["reproduce", "reference", "--quick", "--existing", "--out", str(out)]) == 0
  root = out / "reference_quick"
  table = (root / "table.md").read_text()
  lines = {line.split(" | ")[0].strip("| "): line for line in table.splitlines()
           if line.startswith("| ")}
  returns = [m["greedy"]["mean_return"] for m in flat]
  normalized = [bounds.normalized("taxi_fuel", m["greedy"])["mean_return_normalized"]
                for m in flat]
  assert lines["Flat Q-learning"].split(" | ")[2:4] == [
      stats.format_summary(stats.summary(returns), 3, iqm=False),
      stats.format_summary(stats.summary(normalized), 1, iqm=False)]
  assert lines["Flat Q-learning"].endswith(
      "| 2 of 2 runs (seeds 100-101), 2,000 episodes each |")
  assert lines["PPO (SB3)"].split(" | ")[2] == stats.format_summary(
      stats.summary([ppo["greedy"]["mean_return"]]), 3, iqm=False)
  assert "| 1 of 2 runs (seed 100), 3 record rows of 1,000 steps each |" in lines["PPO (SB3)"]
  for learner in ("HPG", "MAXQ-Q", "DQN (SB3)", "Hierarchical hybrid", "SAC (SB3)"):
    assert lines[learner].endswith("| **not run here** |")
  csv = (root / "reference_taxi.csv").read_text().splitlines()
  assert csv[0].split(",")[:4] == [f"taxi_fuel_flat_q_mean_return_{k}"
                                   for k in ("steps", "mean", "ci_low", "ci_high")]
  mean, low, high = stats.band([[p["mean_return"] for p in m["greedy_curve"]] for m in flat])
  np.testing.assert_allclose([[float(v) for v in row.split(",")[1:4]] for row in csv[1:]],
                             np.column_stack([mean, low, high]), rtol=1e-5, atol=1e-5)
  assert (root / "reference_taxi.png").is_file() and not (root / "reference_ship.png").exists()
  assert len((root / "runs.jsonl").read_text().splitlines()) == 3
  assert "## reference: Reference scores" in (out / "REPORT.md").read_text()
  assert "QUICK protocol" in (root / "REPORT.md").read_text()
  assert "- DQN (SB3): tuned by scripts/tuning_runs.py" in table


def test_earlier_runs_complete_the_seeds_not_run_here(tmp_path, capsys):
  # --earlier: a seed finished under --out wins; a seed not run here takes the earlier
  # report's metrics; an earlier run of a seed the experiment no longer has is left out.
  first, second = tmp_path / "first", tmp_path / "second"
  for seed in (100, 101):
    _finished(first, "reference_taxi_hierarchy", "taxi_fuel_flat_q", seed, 2000, (1000,))
  assert cli.main(["reproduce", "reference", "--quick", "--existing", "--out", str(first)]) == 0
  earlier = first / "reference_quick" / "runs.jsonl"
  with open(earlier, "a") as f:
    f.write(json.dumps({"task": "taxi_fuel_flat_q", "seed": 7, "episodes": 5}) + "\n")
  here = _finished(second, "reference_taxi_hierarchy", "taxi_fuel_flat_q", 101, 1000, (500,))
  assert cli.main(["reproduce", "reference", "--quick", "--existing", "--earlier", str(earlier),
                   "--out", str(second)]) == 0
  table = (second / "reference_quick" / "table.md").read_text()
  assert "| 2 of 2 runs (seeds 100-101), 1,000 or 2,000 episodes each |" in table
  runs_ = [json.loads(line) for line in
           (second / "reference_quick" / "runs.jsonl").read_text().splitlines()]
  assert sorted((r["seed"], r["episodes"]) for r in runs_) == [(100, 2000), (101, 1000)]
  assert [r for r in runs_ if r["seed"] == 101][0]["greedy"] == here["greedy"]
  capsys.readouterr()
  assert cli.main(["reproduce", "reference", "--quick", "--existing", "--earlier",
                   str(tmp_path / "nowhere.jsonl"), "--out", str(second)]) == 2
  assert "--earlier " in capsys.readouterr().err
  (tmp_path / "bad.jsonl").write_text("{\"seed\": 3}\n")
  assert cli.main(["reproduce", "reference", "--quick", "--existing", "--earlier",
                   str(tmp_path / "bad.jsonl"), "--out", str(second)]) == 2
  assert "bad.jsonl, line 1: not a run of runs.jsonl" in capsys.readouterr().err
  assert cli.main(["reproduce", "fig6", "--earlier", str(earlier), "--out", str(second)]) == 2
  assert "--earlier completes `reproduce reference` or `reproduce ladder`" in \
      capsys.readouterr().err


def test_existing_is_refused_for_the_papers_figures(tmp_path, capsys):
  assert cli.main(["reproduce", "fig6", "--existing", "--out", str(tmp_path)]) == 2
  assert "--existing draws `reproduce reference` and `reproduce ladder` from the runs found" \
      in capsys.readouterr().err


def test_tuning_runs_give_each_learner_its_grid_on_the_same_first_tuning_seeds(tmp_path):
  """scripts/tuning_runs.py --seeds: the equal tuning budget of the reference runs."""
  script = runpy.run_path(str(pathlib.Path(__file__).resolve().parents[2] / "scripts" /
                              "tuning_runs.py"))
  ppo, dqn = (runner.load_experiment(script["write"](name, tmp_path, 3))
              for name in ("taxi_fuel_ppo", "taxi_fuel_dqn"))
  for experiment in (ppo, dqn):
    assert (experiment["runs"], experiment["first_seed"], experiment["episodes"]) == (3, 0, 200)
    assert experiment["tuning"] and experiment["figures"][0]["kind"] == "greedy_curve"
  assert sorted((t.config.dqn.learning_rate, t.config.dqn.exploration_steps)
                for t in dqn["task_files"]) == [(1e-4, 20000), (1e-4, 40000), (5e-4, 20000),
                                                (5e-4, 40000)]
  assert len({(t.config.ppo.learning_rate, t.config.ppo.ent_coef) for t in ppo["task_files"]}) == 4
  with pytest.raises(ValueError, match=r"--seeds 11: .* has 10 tuning seeds; allowed: 1\.\.10"):
    script["write"]("taxi_fuel_ppo", tmp_path, 11)


def test_tuning_runs_write_the_tunings_record_from_its_runs(tmp_path, capsys):
  """scripts/tuning_runs.py --summary --task --json: figures/tuning/*.json's form, each
  configuration in `tuning.candidates`' order, a run without a score left out of the mean."""
  script = runpy.run_path(str(pathlib.Path(__file__).resolve().parents[2] / "scripts" /
                              "tuning_runs.py"))
  from hpg_mj import agents
  from hpg_mj.experiments import tuning
  task = agents.load_task("taxi_fuel_dqn")
  changes = tuning.candidates(task, task.tuning["budget"])
  folder = tmp_path / "runs"
  for k in range(len(changes)):
    for seed, score in ((1, -30.0 + k), (0, None if k == 3 else -20.123456 + k)):
      run = folder / f"taxi_fuel_dqn_tune{k}" / f"seed{seed}"
      run.mkdir(parents=True)
      (run / "metrics.json").write_text(json.dumps({"mean_return": score}))
  out = tmp_path / "record.json"
  assert script["main"](["--summary", str(folder), "--task", "taxi_fuel_dqn", "--json",
                         str(out)]) == 0
  record = json.loads(out.read_text())
  assert (record["task"], record["seeds"], record["score"]) == ("taxi_fuel_dqn", [0, 1],
                                                                  task.tuning["score"])
  assert [r["changes"] for r in record["results"]] == json.loads(json.dumps(changes))
  assert record["results"][0]["scores"] == [-20.1235, -30.0]       # seed 0, then seed 1
  assert record["results"][0]["mean"] == -25.06175       # of the rounded scores
  assert record["results"][3]["scores"] == [None, -27.0] and record["results"][3]["mean"] == -27.0
  assert not any(k.startswith("greedy_") for k in record["results"][0])   # none recorded
  assert "wrote" in capsys.readouterr().out


def test_the_combined_report_links_each_sections_pictures_in_its_folder(tmp_path):
  from hpg_mj.experiments import figures
  (tmp_path / "reference").mkdir()
  (tmp_path / "reference" / "reference_ship.png").write_bytes(b"png")
  (tmp_path / "reference" / "REPORT.md").write_text(
      "# Reference\n\n![Ship](reference_ship.png) and ![web](https://example.org/a.png)\n")
  text = figures.write_combined_report(tmp_path, ["reference"]).read_text()
  assert "![Ship](reference/reference_ship.png)" in text
  assert "![web](https://example.org/a.png)" in text
  assert (tmp_path / "reference" / "reference_ship.png").is_file()
