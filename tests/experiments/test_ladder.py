"""The task ladder's reference table (issue 41, item 3): an experiment file runs each
ladder task file at each of its `levels` (the file's [environment] level set, the copy
written where its runs read it), and `hpg-mj reproduce ladder` tables and draws the
runs found, with who leads at each level and the headroom checks."""
import json

import numpy as np
import pytest

from hpg_mj.experiments import bounds
from hpg_mj.experiments import figures
from hpg_mj.experiments import ladder, reference, runner
from experiment_file import assert_refused

EXPERIMENT = """
[experiment]
name = "tiny_ladder"
description = "the current's hybrid at two levels"
tasks = ["ship_current_hybrid"]
levels = [{levels}]
runs = 1
episodes = 1000
quick_runs = 1
quick_episodes = 1000
first_seed = 1000

[[figure]]
name = "tiny_ladder"
kind = "curve"
metric = "gate_passes"
x = "episodes"
title = "gate passes"
ylabel = "gate passes per 1,000 episodes"
paper = "none"
"""


def test_an_experiment_runs_each_task_at_each_level_and_the_ladder_report_reads_them(
    tmp_path):
  path = tmp_path / "tiny_ladder.toml"
  path.write_text(EXPERIMENT.format(levels='"hard", "easy"'))
  experiment = runner.load_experiment(path)
  assert [t.path.stem for t in experiment["task_files"]] == ["ship_current_hybrid_hard",
                                                             "ship_current_hybrid_easy"]
  assert experiment["task_files"][0].name == "Hierarchical hybrid (current), hard"
  out = tmp_path / "out"
  results, root, _ = runner.run_experiment(experiment, out)
  copy = root / "tasks" / "ship_current_hybrid_hard.toml"
  assert 'level = "hard"' in copy.read_text()               # what its runs read
  assert json.loads((root / "ship_current_hybrid_hard" / "seed1000" / "metrics.json")
                    .read_text())["task"] == "ship_current_hybrid_hard"
  hard = results["ship_current_hybrid_hard"][0]["greedy"]
  easy = results["ship_current_hybrid_easy"][0]["greedy"]
  assert {"J_normalized", "gate_pass_rate_normalized"} <= set(hard)
  assert hard != easy                                       # other bounds, other starts
  # The steering task's published MushroomRL J is not set beside a ladder task's.
  figures.write_report(root, experiment, results, {})
  assert "| J (MushroomRL rewards), greedy |" in (root / "REPORT.md").read_text()
  assert "J ~ -92.7" not in (root / "REPORT.md").read_text()
  # A file changed since its runs began is not run over them.
  copy.write_text(copy.read_text() + "\n# edited\n")
  (root / "ship_current_hybrid_hard" / "seed1000" / "metrics.json").unlink()
  with pytest.raises(ValueError, match="holds another text than tiny_ladder.toml makes now"):
    runner.run_experiment(experiment, out)

  report = ladder.write(out, experiments={"ship_current": [experiment]})
  text = report.read_text()
  assert "## ship_current" in text and "| Hierarchical hybrid (current) |" in text
  assert "- easy: Hierarchical hybrid (current) leads (" in text   # (hard: unfinished now)
  assert ("- headroom (gate_pass_rate, normalized, the mean over runs): a hierarchy "
          "reaches 90 at easy: ") in text
  # For scale, the scripted helmsman's normalized score from the published bounds.
  bound = bounds.bounds()["tasks"]["ship_current/hard"]
  helmsman = 100 * (bound["helmsman"]["gate_pass_rate"] - bound["random"]["gate_pass_rate"]) / (
      bound["best"]["gate_pass_rate"] - bound["random"]["gate_pass_rate"])
  assert "- for scale, not a learner: the scripted helmsman" in text
  assert f", hard {helmsman:.1f} (gate_pass_rate, normalized); easy " in text
  j = 100 * (bound["helmsman"]["J"] - bound["random"]["J"]) / (
      bound["best"]["J"] - bound["random"]["J"])
  assert f", hard {j:.1f} (J, normalized)." in text                  # its J, as the learners'

  assert (report.parent / "ladder.png").is_file()
  rows = (report.parent / "ladder.csv").read_text().splitlines()
  assert rows[0] == "task,level,learner,score,mean,low,high,runs" and len(rows) == 2  # easy
  mean = float(rows[1].split(",")[4])
  assert np.isclose(mean, easy["gate_pass_rate_normalized"], atol=1e-4)   # (written to 4 places)
  lines = (report.parent / "runs.jsonl").read_text().splitlines()
  assert {json.loads(line)["task"] for line in lines} == {"ship_current_hybrid_easy"}
  # Runs landed piece by piece: an earlier report's runs.jsonl completes the seeds not
  # finished here (the hard level's, unfinished now), and a run finished here wins.
  earlier = tmp_path / "earlier.jsonl"
  landed = dict(json.loads(lines[0]), task="ship_current_hybrid_hard", seed=1000)
  landed["greedy"] = dict(landed["greedy"], gate_pass_rate_normalized=12.5)
  stale = dict(json.loads(lines[0]), seed=1000)
  stale["greedy"] = dict(stale["greedy"], gate_pass_rate_normalized=-7.0)
  earlier.write_text(json.dumps(landed) + "\n" + json.dumps(stale) + "\n")
  report = ladder.write(out, experiments={"ship_current": [experiment]},
                        earlier=reference.read_earlier(earlier))
  rows = {tuple(r.split(",")[:3]): r.split(",") for r in
          (report.parent / "ladder.csv").read_text().splitlines()[1:]}
  assert float(rows[("ship_current", "hard", "Hierarchical hybrid (current)")][4]) == 12.5
  # The hard check says which learners it has not seen yet (none here: the one has run).
  assert "not yet run at hard" not in report.read_text()
  assert np.isclose(float(rows[("ship_current", "easy", "Hierarchical hybrid (current)")][4]),
                    easy["gate_pass_rate_normalized"], atol=1e-4)


def test_a_level_redrawn_by_another_experiment_joins_its_learner_in_one_row(tmp_path):
  """A level made harder is run again on fresh seeds by an experiment of its own; the
  table holds one row a learner, its levels from each experiment's seeds."""
  (tmp_path / "tiny_ladder.toml").write_text(EXPERIMENT.format(levels='"easy"'))
  (tmp_path / "tiny_hard.toml").write_text(
      EXPERIMENT.format(levels='"hard"').replace('name = "tiny_ladder"', 'name = "tiny_hard"')
      .replace("first_seed = 1000", "first_seed = 1300"))
  loaded = [runner.load_experiment(tmp_path / f"{n}.toml") for n in ("tiny_ladder", "tiny_hard")]

  def run(stem, seed, value):
    return {"seed": seed, "episodes": 1000,
            "greedy": {"gate_pass_rate_normalized": value, "J_normalized": value}}
  earlier = {("ship_current_hybrid_easy", 1000): run("ship_current_hybrid_easy", 1000, 91.0),
             ("ship_current_hybrid_hard", 1000): run("ship_current_hybrid_hard", 1000, 80.0),
             ("ship_current_hybrid_hard", 1300): run("ship_current_hybrid_hard", 1300, 20.0)}
  found = ladder.collect(tmp_path / "out", experiments={"ship_current": loaded},
                         earlier=earlier)["ship_current"]
  assert len(found) == 1 and found[0]["label"] == "Hierarchical hybrid (current)"
  runs_ = found[0]["runs"]
  # the former hard level's run (seed 1000) is not the hard experiment's: left out
  assert [m["seed"] for m in runs_["easy"]] == [1000] and not runs_["medium"]
  assert [m["seed"] for m in runs_["hard"]] == [1300]
  assert ladder.headroom("ship_current", found) == (True, True)
  # A learner with no run at hard yet is named beside the check's "yes".
  (tmp_path / "tiny_other.toml").write_text(
      EXPERIMENT.format(levels='"easy"').replace('name = "tiny_ladder"', 'name = "tiny_other"')
      .replace('"ship_current_hybrid"', '"ship_current_flat_pg"'))
  loaded.append(runner.load_experiment(tmp_path / "tiny_other.toml"))
  text = ladder.write(tmp_path / "out", experiments={"ship_current": loaded},
                      earlier=earlier).read_text()
  assert ("no learner reaches 70 at hard: yes (of those run there; not yet run at hard: "
          "Flat PGRL (current)).") in text


def test_levels_are_refused_in_one_line_where_they_cannot_apply(tmp_path):
  assert_refused(tmp_path, EXPERIMENT.format(levels='"easy", "easy"'),
                 r"\[experiment\] levels = \['easy', 'easy'\]; allowed: one or more levels, "
                 "each once")
  assert_refused(tmp_path, EXPERIMENT.format(levels='"extreme"'),
                 r"bad.toml: \[experiment\] levels: 'extreme' is not a level; allowed: "
                 r"\['easy', 'medium', 'hard'\]")
  assert_refused(tmp_path, EXPERIMENT.format(levels='"easy"').replace(
      '"ship_current_hybrid"', '"ship_hybrid"'),
      r"\[experiment\] levels: ship_hybrid.toml has no \[environment\] level \(only the "
      r"ladder's tasks have levels\)")


def test_the_shipped_ladder_experiments_load_and_run_past_the_tuning_seeds():
  loaded = ladder.shipped()
  assert set(loaded) == set(ladder.TASKS)
  for task, experiments in loaded.items():
    assert experiments, task
    for experiment in experiments:
      assert experiment["levels"] == ["easy", "medium", "hard"]
      assert experiment["first_seed"] > 9 and not experiment["tuning"]
      worlds = {t.section("environment")["world"] for t in experiment["task_files"]}
      assert worlds == {task}


def test_a_ladder_experiment_draws_the_greedy_metrics_of_its_task(tmp_path):
  """A greedy_curve of a ladder task draws that task's greedy metrics (the regatta's are
  its finish and return, not J)."""
  text = EXPERIMENT.format(levels='"easy"').replace("ship_current_hybrid",
                                                    "ship_regatta_hybrid")
  curve = text.replace('kind = "curve"\nmetric = "gate_passes"\nx = "episodes"',
                       'kind = "greedy_curve"\nmetric = "{metric}"')
  path = tmp_path / "regatta.toml"
  path.write_text(curve.format(metric="finish_rate_normalized"))
  assert runner.load_experiment(path)["figures"][0]["metric"] == "finish_rate_normalized"
  assert_refused(tmp_path, curve.format(metric="J"),
                 r"metric = 'J'; allowed for the ship_regatta: \['finish_rate', ")


def test_a_method_of_ones_own_is_set_beside_the_table_from_its_official_scores(tmp_path,
                                                                                capsys):
  """A newcomer's CEM controller, scored with benchmark.evaluate, could reach the
  ladder's report only through its internals. `reproduce ladder --add FILE` reads a JSON
  line a run (the official metrics, a label, a seed): the table gains the method's row,
  the report its line against the best reference learner, and the headroom checks stay
  the reference learners'."""
  from hpg_mj import benchmark, cli
  steer = benchmark.evaluate(lambda obs: np.zeros(len(obs)), "ship_regatta", level="hard",
                             batched=True)
  assert steer.metrics["official"]
  lines = [json.dumps({"label": "steady", "seed": seed, **steer.metrics}) for seed in (1000, 1001)]
  added = tmp_path / "mine.jsonl"
  added.write_text("\n".join(lines) + "\n")
  # Two reference runs of the waypoints at the regatta's hard level, as runs.jsonl holds them.
  earlier = tmp_path / "runs.jsonl"
  earlier.write_text("".join(json.dumps({"task": "ship_regatta_waypoints_hard", "seed": s,
                                         "greedy": {"finish_rate_normalized": v,
                                                    "mean_return_normalized": v}}) + "\n"
                             for s, v in ((1000, 40.0), (1001, 50.0))))
  assert cli.main(["reproduce", "ladder", "--existing", "--out", str(tmp_path / "out"),
                   "--earlier", str(earlier), "--add", str(added)]) == 0
  text = (tmp_path / "out" / "ladder" / "REPORT.md").read_text()
  mine = steer.metrics["finish_rate_normalized"]
  assert f"| steady (yours) | - | - | - | - | {mine:.1f} [{mine:.1f}, {mine:.1f}]" in text
  assert ("- steady (yours), against the best reference learner: hard: "
          f"{mine:.1f} [{mine:.1f}, {mine:.1f}], behind Waypoints (regatta) (45.0 [40.0, 50.0]), "
          "distinguishable (the intervals are apart).") in text
  assert "the checks are the reference learners', not yours" in text
  assert "steady" not in (tmp_path / "out" / "ladder" / "runs.jsonl").read_text()
  assert "steady (yours)" in (tmp_path / "out" / "ladder" / "ladder.csv").read_text()
  # Each bad line is refused in one line naming it, before anything is written.
  bad = dict(json.loads(lines[0]))
  for change, message in (({"official": False}, r"line 1: not official \(official = False\)"),
                          ({"seed": 3}, r"line 1: seed 3 is a tuning seed of the ladder's "
                                        r"task files \(0-9\)"),
                          ({"task": "ship"}, r"line 1: task 'ship' at level 'hard'; allowed"),
                          ({"label": ""}, r"line 1: label '' and seed 1000; allowed")):
    added.write_text(json.dumps({**bad, **change}) + "\n")
    with pytest.raises(ValueError, match=message):
      ladder.read_added(added)
  added.write_text(lines[0] + "\n" + lines[0] + "\n")
  with pytest.raises(ValueError, match=r"line 2: 'steady' on ship_regatta at hard seed 1000 "
                                       "is given twice"):
    ladder.read_added(added)
  other = tmp_path / "other.jsonl"                 # one method's runs over two files
  other.write_text(lines[1] + "\n"
                   + json.dumps({**json.loads(lines[0]), "task": "ship_current"}) + "\n")
  added.write_text(lines[0] + "\n")
  both = ladder.read_added(added, other)
  assert [[m["seed"] for m in e["runs"]["hard"]] for e in both["ship_regatta"]] == [[1000, 1001]]
  assert [e["label"] for e in both["ship_current"]] == ["steady (yours)"]
  added.write_text("{not json\n")
  with pytest.raises(ValueError, match=r"line 1: not a run"):
    ladder.read_added(added)
  assert cli.main(["reproduce", "reference", "--existing", "--out", str(tmp_path / "o2"),
                   "--add", str(added)]) == 2
  assert "--add sets a method of one's own beside the ladder's table" in capsys.readouterr().err
