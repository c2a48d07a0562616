"""Experiment files, parallel runs, skipping finished runs, figures and report."""
import json

import numpy as np
import pytest

from hpg_mj import cli
from hpg_mj.agents import _ship
from hpg_mj import taskfile
from hpg_mj.experiments import runner
from experiment_file import assert_refused

EXPERIMENT = """
[experiment]
name = "tiny"
description = "two tasks, two seeds"
tasks = ["ship_hybrid", "ship_flat_pg"]
runs = 2
episodes = 1000
quick_runs = 1
quick_episodes = 1000
tuning = true     # the machinery under test, on tuning seeds
""" + runner.shipped_experiments()["fig7_11"].read_text().split("[[figure]]", 1)[1].join(
    ["\n[[figure]]", ""]).replace('"ship_flat_pg", "ship_actor_critic"]', '"ship_flat_pg"]')

TAXI = """
[experiment]
name = "tiny"
description = "three taxi learners, two seeds"
tasks = ["taxi_fuel_hpg", "taxi_fuel_maxq", "taxi_fuel_flat_q"]
runs = 2
episodes = 3000
quick_runs = 1
quick_episodes = 1000
tuning = true     # the machinery under test, on tuning seeds
""" + runner.shipped_experiments()["fig6"].read_text().split("[[figure]]", 1)[1].join(
    ["\n[[figure]]", ""])


def test_results_do_not_depend_on_the_number_of_workers(tmp_path):
  path = tmp_path / "tiny.toml"
  path.write_text(EXPERIMENT)
  experiment = runner.load_experiment(path)
  one, root_one, _ = runner.run_experiment(experiment, tmp_path / "one", workers=1)
  two, root_two, _ = runner.run_experiment(experiment, tmp_path / "two", workers=2)
  for task in ("ship_hybrid", "ship_flat_pg"):
    for a, b in zip(runner.load_records(root_one, task, 2), runner.load_records(root_two, task, 2)):
      np.testing.assert_array_equal(a, b)
    for a, b in zip(one[task], two[task]):
      for m in (a, b):        # the seconds differ; compile + train = wall
        assert m.pop("wall_seconds") == pytest.approx(
            m.pop("compile_seconds") + m.pop("train_seconds"), abs=0.0015)
      assert a == b


def test_finished_runs_are_skipped_and_figures_written(tmp_path, capsys):
  path = tmp_path / "tiny.toml"
  path.write_text(EXPERIMENT)
  out = tmp_path / "out"
  assert cli.main(["run", str(path), "--out", str(out), "--workers", "1", "--quiet"]) == 0
  assert "(4 new" in capsys.readouterr().out
  metrics = out / "tiny" / "ship_hybrid" / "seed0" / "metrics.json"
  stamp = metrics.stat().st_mtime_ns
  assert cli.main(["run", str(path), "--out", str(out), "--workers", "1", "--quiet"]) == 0
  assert "(0 new" in capsys.readouterr().out
  assert metrics.stat().st_mtime_ns == stamp
  # The same folder asked for runs of another length is refused, not reused.
  path.write_text(EXPERIMENT.replace("episodes = 1000\n", "episodes = 2000\n", 1))
  assert cli.main(["run", str(path), "--out", str(out), "--workers", "1", "--quiet"]) == 2
  assert "holds a finished run of 1000 episodes, but tiny.toml asks for 2000" in \
      capsys.readouterr().err
  assert metrics.stat().st_mtime_ns == stamp
  # A damaged metrics.json is named, not a bare JSON error.
  path.write_text(EXPERIMENT)
  text = metrics.read_text()
  metrics.write_text('{"gate_pass_rate": 0.9, "epis')
  assert cli.main(["run", str(path), "--out", str(out), "--workers", "1", "--quiet"]) == 2
  assert f"{metrics} is damaged" in capsys.readouterr().err
  metrics.write_text(text)
  for fig in ("fig7", "fig8", "fig9", "fig10", "fig11"):
    assert (out / "tiny" / f"{fig}.png").stat().st_size > 1000
    rows = np.loadtxt(out / "tiny" / f"{fig}.csv", delimiter=",", skiprows=1, ndmin=2)
    assert rows.shape[0] == 1
  report = (out / "tiny" / "REPORT.md").read_text()
  assert "about 220 control steps" in report and "Flat PGRL" in report
  assert "Against the paper's best: Hierarchical hybrid ahead of Flat PGRL: " in report
  assert "**Not for publication**" in report                  # tuning = true
  assert "| J (MushroomRL rewards), greedy | " in report and "straight-line bound" in report
  finished = json.loads(metrics.read_text())
  assert finished["episodes"] == 1000
  # SPEC section 7: the final agent's greedy episodes on the fixed 1,000 starts.
  greedy = np.load(metrics.parent / "greedy.npy")
  assert len(greedy) == finished["greedy"]["episodes_measured"] == 1000
  assert finished["greedy"]["J"] == pytest.approx(float(np.mean(
      _ship.mushroom_j(greedy, 5000, -300.0))))
  # SPEC section 7.1: the scores also normalized against the published bounds.
  from hpg_mj.experiments import bounds
  ship = bounds.bounds()["tasks"]["ship"]
  assert finished["greedy"]["J_normalized"] == pytest.approx(
      100 * (finished["greedy"]["J"] - ship["random"]["J"]) / (ship["best"]["J"]
                                                             - ship["random"]["J"]))
  assert "| J, greedy, normalized (0 random, 100 best known) | " in report
  header = (out / "tiny" / "fig9.csv").read_text().splitlines()[0]
  assert "ship_hybrid_ci_low" in header and "ship_hybrid_fraction_passed" in header


@pytest.mark.parametrize("old,new,message", [
    ('runs = 2', 'runs = 0', "runs must be a positive integer"),
    ('runs = 2', 'run = 2', r"unknown key\(s\) \['run'\]"),
    ('"ship_flat_pg"]', '"ship_flat_pgg"]',
     "no shipped task of that name; did you mean 'ship_flat_pg'\\? shipped: "),
    ('episodes = 1000\n', '', "episodes is missing"),
    ('metric = "gate_passes"', 'metric = "gate"', r"\[\[figure\]\] 'fig7' metric = 'gate'; allowed:"),
    ('x = "episodes"', 'x = "time"', r"'fig7' x = 'time'; allowed: \['episodes', 'steps'\]"),
    ('kind = "curve"', 'kind = "bars"', r"\[\[figure\]\] #1 kind = 'bars'; allowed"),
    ('ylabel = "gate passes"\n', '', r"\[\[figure\]\] #1 ylabel is missing"),
    ('title = "Gate passes per 1,000 episodes"\nylabel = "gate passes"\n', '',
     r"\[\[figure\]\] #1 title and ylabel are missing \(title: a string; ylabel: a string\)"),
    ('paper_value = 4.0', 'paper_value = "4"', "paper_value must be a number"),
    ('paper_order = ["ship_hybrid", "ship_flat_pg"]', 'paper_order = ["ship_actor_critic"]',
     "names task 'ship_actor_critic', which is not in"),
    ('name = "fig8"', 'name = "fig7"', "'fig7' is named twice"),
    ('name = "fig8"', 'colour = "red"\nname = "fig8"', r"unknown key\(s\) \['colour'\]"),
    ('better = "lower"', 'better = "smaller"', r"'fig9' better = 'smaller'; allowed: \['higher', 'lower'\]"),
    ('paper_best = "ship_hybrid"', 'paper_best = "hybrid"', "names task 'hybrid', which is not in"),
])
def test_malformed_experiment_files_are_refused_before_running(tmp_path, old, new, message):
  assert_refused(tmp_path, EXPERIMENT.replace(old, new, 1), message)


def test_an_experiment_of_ones_own_needs_its_name_tasks_runs_and_episodes(tmp_path, capsys):
  """Left out: description, the --quick protocol (one run of the same episodes) and
  [[figure]] (one greedy curve of the world's first greedy metric)."""
  path = tmp_path / "mine.toml"
  path.write_text('[experiment]\nname = "mine"\ntasks = ["ship_hybrid"]\nruns = 2\n'
                  'episodes = 40\nfirst_seed = 100\n')
  experiment = runner.load_experiment(path)
  assert (experiment["description"], experiment["quick_runs"],
          experiment["quick_episodes"]) == ("", 1, 40)
  assert [(f["name"], f["kind"], f["metric"]) for f in experiment["figures"]] == [
      ("mine", "greedy_curve", "gate_pass_rate")]
  assert cli.main(["run", str(path), "--out", str(tmp_path / "out"), "--quick"]) == 0
  capsys.readouterr()
  done = tmp_path / "out" / "mine_quick"
  assert sorted(p.name for p in (done / "ship_hybrid").iterdir()) == ["seed100"]
  assert (done / "mine.png").is_file()
  assert (done / "REPORT.md").read_text().startswith("# mine\n")
  for tasks, metric in (('"ship_hybrid"', "gate_passes"), ('"taxi_fuel_hpg"', "mean_return")):
    path.write_text(f'[experiment]\nname = "long"\ntasks = [{tasks}]\nruns = 2\n'
                    'episodes = 2000\nfirst_seed = 100\n')     # a learning curve
    figure, = runner.load_experiment(path)["figures"]
    assert (figure["kind"], figure["metric"], figure["x"]) == ("curve", metric, "episodes")
    # The taxi's curve draws its exact optimum, and the report its steps to 95% of it.
    assert figure.get("reference") == ("optimal" if "taxi" in tasks else None)
  path.write_text(path.read_text() + "[figure]\nname = 1\n")
  with pytest.raises(taskfile.TaskFileError, match=r"\[\[figure\]\] must be tables"):
    runner.load_experiment(path)


def test_taxi_experiment_draws_figure_6(tmp_path, capsys):
  path = tmp_path / "taxi.toml"
  path.write_text(TAXI)
  out = tmp_path / "out"
  assert cli.main(["run", str(path), "--out", str(out), "--workers", "2", "--quiet"]) == 0
  assert (out / "tiny" / "fig6.png").stat().st_size > 1000
  rows = np.loadtxt(out / "tiny" / "fig6.csv", delimiter=",", skiprows=1, ndmin=2)
  assert rows.shape == (3, 12)
  assert "Optimal mean return (value iteration): 6.1446" in (out / "tiny" / "REPORT.md").read_text()


def test_mixed_experiment_is_refused(tmp_path):
  path = tmp_path / "mixed.toml"
  path.write_text(EXPERIMENT.replace('"ship_flat_pg"]', '"taxi_fuel_flat_q"]', 1))
  with pytest.raises(taskfile.TaskFileError, match=r"these mix \['ship', 'taxi'\]"):
    runner.load_experiment(path)
  assert cli.main(["run", str(path), "--out", str(tmp_path / "o"), "--workers", "1",
                   "--quiet"]) == 2
  assert not (tmp_path / "o").exists()


def test_reproduce_quick_figure_6(tmp_path, capsys):
  assert cli.main(["reproduce", "fig6", "--quick", "--out", str(tmp_path), "--quiet"]) == 0
  assert (tmp_path / "fig6_quick" / "fig6.png").is_file()       # never mistaken for full runs
  # Quick runs, like full ones, are seeds past the tuning seeds 0-9 (SPEC section 7).
  assert (tmp_path / "fig6_quick" / "taxi_fuel_hpg" / "seed102" / "metrics.json").is_file()
  assert not (tmp_path / "fig6_quick" / "taxi_fuel_hpg" / "seed0").exists()
  report = (tmp_path / "REPORT.md").read_text()
  assert "3 runs x 100,000 episodes (seeds 100-102), QUICK protocol" in report
  assert "| million primitive steps to 95% of the optimum |" in report
  assert "## fig6:" in report and "Optimal mean return (value iteration): 6.1446" in report
  assert cli.main(["reproduce", "fig13", "--out", str(tmp_path)]) == 2
  assert "valid: all, fig6, fig7" in capsys.readouterr().err


def test_figure_12_marks_the_root_decisions(tmp_path, capsys):
  from hpg_mj import agents
  from hpg_mj.experiments import fig12
  task = tmp_path / "short.toml"
  task.write_text((agents.shipped_tasks()["ship_hybrid"]).read_text()
                  .replace("max_steps = 5000", "max_steps = 40"))
  text = runner.shipped_experiments()["fig12"].read_text()
  text = text.replace('tasks = ["ship_hybrid"]', f'tasks = ["{task}"]').replace(
      'task = "ship_hybrid"', 'task = "short"\nwidth = 96\nheight = 80').replace(
      "quick_episodes = 20000", "quick_episodes = 200")
  path = tmp_path / "f12.toml"
  path.write_text(text)
  out = tmp_path / "out"
  assert cli.main(["run", str(path), "--quick", "--out", str(out), "--quiet"]) == 0
  printed = capsys.readouterr().out
  assert "fig12: from (700.0, 700.0, 100.0, 3.65):" in printed
  folder = out / "fig12_quick"
  assert (folder / "fig12.png").stat().st_size > 1000
  summary = json.loads((folder / "fig12.json").read_text())
  for k, s in enumerate(summary):
    assert s["start"] == list(fig12.STARTS[k])
    assert 1 <= s["calls"] == len(s["decisions"]) and 1 <= s["steps"] <= 40
    assert (folder / f"fig12_{k}.mp4").stat().st_size > 1000
  assert "from (750, 180):" in (folder / "REPORT.md").read_text()
  agent, _, _ = agents.load(folder / "short" / "seed100" / "agent")
  path_, decisions, _ = fig12.sail(agent, fig12.STARTS[0])
  assert decisions[0][:2] == pytest.approx(fig12.STARTS[0][:2])   # the first call starts there


@pytest.mark.parametrize("old,new,message", [
    ("[750.0, 180.0, 80.0, 7.9]", "[750.0, 180.0]", r"starts must be a non-empty list of \[x, y"),
    ("\nseed = 100", "\nseed = 101", r"seed = 101, but the experiment's runs \(full and quick\) "
                                 r"have seeds 100..100"),
    ("first_seed = 100", "first_seed = 5", r"runs seeds 5..5, but ship_hybrid.toml was tuned "
                                           r"on seeds \[5\]"),
    ('task = "ship_hybrid"', 'task = "ship_flat_pg"', "names task 'ship_flat_pg', which is not"),
    ("video = true", "video = 1", "video must be true or false"),
])
def test_malformed_figure_12_is_refused(tmp_path, old, new, message):
  assert_refused(tmp_path, runner.shipped_experiments()["fig12"].read_text().replace(old, new, 1),
                 message)


def test_every_shipped_experiment_loads():
  for name in ("fig6", "fig7_11", "fig12"):
    experiment = runner.load_experiment(name)
    assert experiment["figures"]


def test_joining_a_token_cluster_without_the_token_setting_says_what_is_missing(monkeypatch):
  """Ray 2.60: a process joining `ray start --head` by its address is refused unless
  RAY_AUTH_MODE=token (checked by hand against a local head; here Ray's refusal
  is stood in for)."""
  ray = pytest.importorskip("ray")

  def refused(**kwargs):
    raise ConnectionError(f"Failed to connect to Ray cluster at {kwargs['address']}")
  monkeypatch.setattr(ray, "is_initialized", lambda: False)
  monkeypatch.setattr(ray, "init", refused)
  monkeypatch.delenv("RAY_AUTH_MODE", raising=False)
  with pytest.raises(ConnectionError, match=r"^--address 10.0.0.1:6379: Failed to connect to "
                     r"Ray cluster at 10.0.0.1:6379; .* without RAY_AUTH_MODE=token"):
    runner._run_ray([], 1, {}, lambda: None, None, "10.0.0.1:6379")
  monkeypatch.setenv("RAY_AUTH_MODE", "token")    # set, and still refused: Ray's own words
  with pytest.raises(ConnectionError, match=r"^Failed to connect to Ray cluster at 10.0.0.1"):
    runner._run_ray([], 1, {}, lambda: None, None, "10.0.0.1:6379")
