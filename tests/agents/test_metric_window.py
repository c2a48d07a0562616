"""The online metrics mean one thing (issue 23 item 5): every shipped agent's
`metrics(record)` is over its declared window, the record's last `metric_window`
rows, which the documentation states and `hpg-mj train --json` names; compile time and
training time are reported apart."""
import json
import pathlib

import numba
import numpy as np
import pytest

from hpg_mj import agents
from hpg_mj import cli
from hpg_mj.agents import window
from hpg_mj.experiments import beyond

# Where the README's long text moved (issue 22): "Train and evaluate a shipped agent".
GUIDE = (pathlib.Path(__file__).resolve().parents[2] / "docs" / "getting_started.md").read_text()
TOTALS = ("control_steps", "primitive_steps")     # counts of the whole record
DOCUMENTED = {"episodes": "an episodic agent's last 1,000 episodes",
              "hours": "the continuing patrol's last 125 hours",
              "rows of 1,000 control steps": "a Stable-Baselines3 agent's last 100 rows of "
                                             "1,000 control steps"}


def _one_task_per_kind():
  tasks = {}
  for path in agents.shipped_tasks().values():
    task = agents.load_task(path)
    tasks.setdefault(task.kind, task)
  return tasks


TASKS = _one_task_per_kind()


def _record(agent, rows, seed):
  """A record of `rows` rows with values the metrics can read (steps >= 1, flags 0/1)."""
  gen = np.random.default_rng(seed)
  data = gen.integers(0, 4, size=(rows, len(agent.record_fields))).astype(float)
  for k, name in enumerate(agent.record_fields):
    if name == "steps":
      data[:, k] = gen.integers(1, 400, rows) * (agent.record_steps or 1)
    elif name == "passed":
      data[:, k] = gen.integers(0, 2, rows)
    elif name in ("return", "gain"):
      data[:, k] = gen.normal(-50.0, 30.0, rows)
  return agent.as_record(data)


def test_every_shipped_agent_has_a_task_file_here():
  assert sorted(TASKS) == sorted(agents._SHIPPED)


@pytest.mark.parametrize("kind", sorted(TASKS))
def test_the_online_metrics_are_over_the_declared_window(kind):
  agent = agents.build(TASKS[kind], seed=0)
  n = agent.metric_window
  record = _record(agent, 3 * n + 7, seed=len(kind))
  whole, last = agent.metrics(record), agent.metrics(record[-n:])
  # The rows before the window change nothing but the whole-record counts.
  earlier = record.copy()
  earlier[:-n] = _record(agent, 2 * n + 7, seed=99)
  for key, value in whole.items():
    if key in TOTALS:
      assert value == int(record["steps"].sum()), key
      continue
    assert value == pytest.approx(last[key], nan_ok=True), key
    assert agent.metrics(earlier)[key] == pytest.approx(value, nan_ok=True), key
  # (A Stable-Baselines3 agent's row sums the episodes that ended in its 1,000 steps.)
  assert whole.get("rows_measured", whole["episodes_measured"]) == n
  # The documentation states this window.
  assert DOCUMENTED[window.unit(agent)].endswith(window.phrase(agent))
  assert DOCUMENTED[window.unit(agent)] in " ".join(GUIDE.split())


def test_the_patrols_window_is_the_block_beyond_reads():
  patrol = agents.lookup("ship_patrol")
  assert patrol.metric_window == beyond.FULL[2] == 125
  assert window.phrase(patrol) == "last 125 hours"


def test_train_names_the_window_and_reports_compile_time_apart(tmp_path, capsys):
  from hpg_mj.agents.taxi_flat_q import TaxiFlatQ
  fresh = numba.njit(lambda rows: rows + 0.0)      # not cached: compiled in its first train

  class FreshlyCompiled(TaxiFlatQ):
    def compiled(self, episodes, learn, sample):
      return fresh(super().compiled(episodes, learn, sample))

  agents.register("freshly_compiled_test", FreshlyCompiled, replace=True)
  task = tmp_path / "t.toml"
  task.write_text(TASKS["taxi_flat_q"].text.replace('kind = "taxi_flat_q"',
                                                    'kind = "freshly_compiled_test"'))
  seconds = []
  for k in range(2):
    assert cli.main(["train", str(task), "--episodes", "20", "--json", "--quiet",
                     "--out", str(tmp_path / f"a{k}")]) == 0
    metrics = json.loads(capsys.readouterr().out)
    # 20 episodes run: the window holds those, not the 1,000 it would hold
    assert metrics["online_window"] == ("all 20 episodes of training (fewer than the window, "
                                        "the last 1,000)")
    assert metrics["online_window_rows"] == 20 == metrics["episodes_measured"]
    assert metrics["wall_seconds"] == pytest.approx(
        metrics["compile_seconds"] + metrics["train_seconds"], abs=0.0015)
    seconds.append(metrics["compile_seconds"])
  assert seconds[0] > 0.0 and seconds[1] == 0.0     # compiled once, in the first train


def test_the_window_never_claims_more_rows_than_were_run():
  """`hpg-mj train TASK --episodes 500 --json` had reported online_window_rows 1000."""
  hybrid, patrol = agents.lookup("ship_hybrid"), agents.lookup("ship_patrol")
  assert window.described(hybrid, 500) == {
      "online_window": "all 500 episodes of training (fewer than the window, the last 1,000)",
      "online_window_rows": 500}
  for rows in (1000, 1001, 50000):
    assert window.described(hybrid, rows) == {"online_window": "last 1,000 episodes of training",
                                              "online_window_rows": 1000}
  assert window.described(patrol, 3)["online_window_rows"] == 3
  assert window.over(patrol, 3, "the evaluation") == (
      "all 3 hours of the evaluation (fewer than the window, the last 125)")


def test_evaluate_names_its_window_too(tmp_path, capsys):
  assert cli.main(["train", "taxi_fuel_flat_q", "--episodes", "5", "--quiet",
                   "--out", str(tmp_path / "a")]) == 0
  capsys.readouterr()
  assert cli.main(["evaluate", str(tmp_path / "a"), "--episodes", "1200", "--json"]) == 0
  metrics = json.loads(capsys.readouterr().out)
  assert metrics["evaluation_window"] == "last 1,000 episodes of the evaluation"
  assert metrics["episodes_measured"] == 1000 and metrics["episodes"] == 1200
  assert cli.main(["evaluate", str(tmp_path / "a"), "--episodes", "7", "--json"]) == 0
  metrics = json.loads(capsys.readouterr().out)
  assert metrics["evaluation_window"] == ("all 7 episodes of the evaluation (fewer than the "
                                          "window, the last 1,000)")
  assert metrics["episodes_measured"] == 7


def test_train_says_its_normalized_scores_are_online_and_how_to_get_the_benchmarks(
    tmp_path, capsys):
  """A newcomer read `hpg-mj train`'s J_normalized as a benchmark score: its text output
  says the scores are online, over which window, and which command gives the greedy one."""
  out = tmp_path / "a"
  assert cli.main(["train", "taxi_fuel_hpg", "--episodes", "30", "--out", str(out)]) == 0
  last = capsys.readouterr().out.splitlines()[-1]
  assert last == ("(the scores above are online: all 30 episodes of training (fewer than the "
                  "window, the last 1,000), exploring and learning; the benchmark's score, "
                  f"greedy on the fixed starts: hpg-mj evaluate {out})")
