"""The installed package carries its MJCF assets; the CLI answers."""
import json
import pathlib

import pytest

import hpg_mj
from hpg_mj import _assets, cli

REPO = pathlib.Path(__file__).resolve().parents[1]


def test_assets_load_from_the_installed_package():
  package_dir = pathlib.Path(hpg_mj.__file__).resolve().parent
  if package_dir == REPO / "hpg_mj":
    pytest.skip("running from the source tree (PYTHONPATH); scripts/test.sh tests the wheel")
  assert _assets.assets_dir().resolve() == package_dir / "assets"
  for name in ("ship.xml", "taxi.xml"):
    assert (package_dir / "assets" / name).is_file()
  assert (package_dir / "tasks" / "ship_hybrid.toml").is_file()
  assert "site-packages" in package_dir.parts


def test_unknown_model_lists_what_exists():
  with pytest.raises(FileNotFoundError, match=r"available: \['ship.xml', 'ship_current.xml', "
                                              r"'ship_harbour.xml', 'ship_regatta.xml', 'taxi.xml'\]"):
    _assets.read_model("boat.xml")


def test_cli_verify_ship(capsys):
  assert cli.main(["verify", "ship", "--controls", "200", "--starts", "1"]) == 0
  out = capsys.readouterr().out
  assert "MuJoCo ship" in out and "analytic ship" in out and "met" in out


def test_cli_bench_train_json_gives_the_ratios_the_table_prints(capsys, monkeypatch):
  """`bench train --task A --task B` prints "A / B: 2.00x" after its table; with --json
  each task after the first carries the same ratio (the measuring itself stubbed)."""
  from hpg_mj import bench
  rates = {"a": 3000.0, "b": 1500.0, "c": 0.0}
  monkeypatch.setattr(bench, "bench_task", lambda path, seconds, assignments: {
      "task": path, "unit": "control steps/s", "steps_per_second": rates[path]})
  assert cli.main(["bench", "train", "--task", "a", "--task", "b", "--task", "c",
                   "--json"]) == 0
  rows = json.loads(capsys.readouterr().out)
  assert "first_over_this" not in rows[0]
  assert rows[1]["first_over_this"] == 2.0 and rows[1]["first"] == "a"
  assert rows[2]["first_over_this"] is None



def test_cli_bench_train_json_takes_the_median_of_interleaved_rounds(capsys, monkeypatch):
  """With --rounds a JSON row is the median round's whole (its steps, seconds and rate
  agree: a newcomer found round 1's steps beside the median's rate), each round's rate
  kept, the order reversed every other round (the measuring itself stubbed: a rate per
  call)."""
  from hpg_mj import bench
  calls = []
  rates = iter([1.0, 10.0, 20.0, 2.0, 3.0, 30.0])      # a b | b a | a b

  def measure(path, seconds, assignments):
    calls.append((path, tuple(assignments)))
    rate = next(rates)
    return {"task": path, "unit": "control steps/s", "steps": 2 * rate,
            "train_seconds": 2.0, "steps_per_second": rate}
  monkeypatch.setattr(bench, "bench_task", measure)
  assert cli.main(["bench", "train", "--task", "a", "--task", "b", "--rounds", "3",
                   "--set", "environment.level=hard", "--json"]) == 0
  rows = json.loads(capsys.readouterr().out)
  assert calls == [(path, ("environment.level=hard",)) for path in "abbaab"]
  assert rows[0]["rounds_steps_per_second"] == [1.0, 2.0, 3.0]
  assert rows[0]["steps_per_second"] == 2.0 and rows[1]["steps_per_second"] == 20.0
  assert rows[0]["median_round"] == rows[1]["median_round"] == 1
  assert all(row["steps"] / row["train_seconds"] == row["steps_per_second"] for row in rows)
  assert rows[1]["first_over_this"] == 0.1


def test_cli_bench_train_sets_keys_of_its_task_files_as_train_does(capsys):
  """`bench train --set` goes through `hpg-mj train --set`'s checks (refused before
  anything compiles), and only with --task."""
  assert cli.main(["bench", "train", "--task", "ship_current_hybrid", "--set",
                   "environment.levl=hard"]) == 2
  assert "--set 'environment.levl=hard': [environment] has no key 'levl'" in \
      capsys.readouterr().err
  assert cli.main(["bench", "train", "--set", "environment.level=hard"]) == 2
  assert "--set sets keys of the --task files; give them with --task" in capsys.readouterr().err


def test_cli_render_rejects_an_unknown_task(capsys, tmp_path):
  assert cli.main(["render", "--domain", "ship", "--task", "race",
                   "--out", str(tmp_path / "x.mp4")]) == 2
  assert "valid: " in capsys.readouterr().err


def test_every_subpackage_is_in_the_wheel():
  import tomllib
  listed = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
               ["packages"])
  found = {".".join(p.parent.relative_to(REPO).parts)
           for p in (REPO / "hpg_mj").glob("**/__init__.py") if p.parent != REPO / "hpg_mj"}
  assert found | {"hpg_mj", "hpg_mj.assets", "hpg_mj.tasks", "hpg_mj.tasks.experiments",
                 "hpg_mj.golden"} == listed


def test_shipped_tasks_load_by_name():
  from hpg_mj import agents
  names = agents.shipped_tasks()
  assert {"ship_hybrid", "ship_flat_pg", "ship_actor_critic", "taxi_fuel_hpg",
          "taxi_fuel_flat_q"} <= set(names)
  assert agents.load_task("ship_hybrid").kind == "ship_hybrid"
  with pytest.raises(ValueError, match=r"no shipped task of that name; did you mean "
                                       r"'ship_hybrid'\? shipped: \['ship_"):
    agents.load_task("ship_hybird")
