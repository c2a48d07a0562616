"""`hpg-mj reproduce beyond` (hpg_mj.experiments.beyond): its three parts on tiny
protocols, their files, a report that says what was measured, and tuning seeds
refused."""
import csv

import numpy as np
import pytest

from hpg_mj import agents
from hpg_mj.experiments import beyond

# (patrol, route, subtask) protocols small enough for a test: the numbers mean
# nothing here, only that every part runs, writes its files and reports them.
TINY = (((100,), 4, 2, 1, 300, 1), ((100, 101), 600), ((100, 101), 1000))


def test_reproduce_beyond_writes_every_part(tmp_path):
  lines = []
  report = beyond.run(tmp_path, protocols=TINY, progress=lines.append)
  root = tmp_path / "beyond"
  for name in ("beyond_patrol.png", "beyond_patrol.csv", "beyond_patrol_final.csv",
               "seed100.json", "beyond_route.png", "beyond_route.csv",
               "subtask_width.png", "subtask_width.csv", "REPORT.md"):
    assert (root / name).is_file(), name
  text = report.read_text()
  for heading in ("## The continuing ship task", "## A route past the paper's",
                  "## A more expressive low-level policy"):
    assert heading in text
  assert "Paired by seed, average-reward root minus episodic hybrid" in text
  assert "Seeds 100-101 (2 runs" in text
  with open(root / "beyond_route.csv") as f:
    rows = list(csv.DictReader(f))
  assert [int(float(r["seed"])) for r in rows] == [100, 101]
  assert all(0.0 <= float(r["gate_pass_rate"]) <= 1.0 for r in rows)
  with open(root / "subtask_width.csv") as f:
    curves = list(csv.DictReader(f))
  # 2 subtasks x 2 policies x one point per 1,000 calls
  assert len(curves) == 4
  assert {r["policy"] for r in curves} == set(beyond.WIDTH_VARIANTS)
  assert sum("route seed" in line for line in lines) == 2


def test_route_seed_matches_its_greedy_record():
  task = agents.load_task(beyond.ROUTE_TASK)
  starts = beyond.route_starts(20)
  _, record, numbers = beyond.route_seed(task, 100, 300, starts)
  ok = record["passed"] > 0
  assert len(record) == 20
  assert numbers["gate_pass_rate"] == ok.mean()
  if ok.any():
    assert numbers["steps_to_gate"] == record["steps"][ok].mean()
  np.testing.assert_array_equal(beyond.route_starts(20), starts)   # fixed, not drawn anew


def test_tuning_seeds_are_refused(tmp_path):
  with pytest.raises(ValueError, match=r"seeds \[3\] are tuning seeds"):
    beyond.run(tmp_path, protocols=(((3,), 4, 2, 1, 300, 1),) + TINY[1:])
