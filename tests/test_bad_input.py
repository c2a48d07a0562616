"""Bad input to `hpg-mj` (issue 23): names in experiment files that would write
outside --out, output paths that would replace or mix into a user's files, short
experiments, files that are not UTF-8, seeds past what the generator takes. Each
is refused in one line that names the file, key or option and what is allowed,
with exit status 2 and nothing written."""
import json
import os
import pathlib

import pytest

from hpg_mj import cli
from hpg_mj import storage
from hpg_mj.experiments import runner
from hpg_mj.learners import rng

from experiment_file import experiment_text

TASK = "taxi_fuel_flat_q"           # the cheapest shipped agent


def tree(root):
  """Every path under `root` (to see that nothing was written)."""
  return sorted(str(p.relative_to(root)) for p in pathlib.Path(root).rglob("*"))


def refused(capsys, argv, *words):
  """Runs the command; holds that it exits 2 with one line naming `words`."""
  try:
    rc = cli.main([str(a) for a in argv])
  except SystemExit as exit_:                # argparse refuses by SystemExit(2)
    rc = exit_.code
  assert rc == 2
  err = capsys.readouterr().err
  lines = err.strip().splitlines()
  assert len(lines) == 1 and "Traceback" not in err, err
  for word in words:
    assert word in lines[0], (word, lines[0])
  return lines[0]


@pytest.mark.parametrize("name", ["..", "../../escaped_exp", "a/b", "a\\b", "", ".hidden",
                                  "-rf", "ABSOLUTE"])
def test_an_experiment_name_cannot_write_outside_out(tmp_path, capsys, monkeypatch, name):
  work = tmp_path / "work"
  work.mkdir()
  monkeypatch.chdir(work)
  if name == "ABSOLUTE":
    name = str(tmp_path / "elsewhere")
  path = work / "e.toml"
  path.write_text(experiment_text(name.replace("\\", "\\\\"), TASK, 1, 1000))
  before = tree(tmp_path)
  refused(capsys, ["run", path, "--out", work / "out" / "a" / "b", "--quiet"],
          "e.toml", "[experiment] name", "allowed:")
  assert tree(tmp_path) == before


@pytest.mark.parametrize("name", ["../x", "/tmp/x", ".", "a/b"])
def test_a_figure_name_cannot_write_outside_out(tmp_path, capsys, name):
  path = tmp_path / "e.toml"
  path.write_text(experiment_text("fine", TASK, 1, 1000).replace('name = "curve"',
                                                                 f'name = "{name}"'))
  before = tree(tmp_path)
  refused(capsys, ["run", path, "--out", tmp_path / "out", "--quiet"],
          "[[figure]] #1 name", "allowed:")
  assert tree(tmp_path) == before


def test_a_task_file_whose_name_is_dot_dot_is_refused_in_an_experiment(tmp_path, capsys):
  from hpg_mj import agents
  task = tmp_path / "...toml"          # its stem, the run folders' name, is ".."
  task.write_text(agents.shipped_tasks()[TASK].read_text())
  path = tmp_path / "e.toml"
  path.write_text(experiment_text("fine", str(task), 1, 1000))
  before = tree(tmp_path)
  refused(capsys, ["run", path, "--out", tmp_path / "out", "--quiet"],
          "[experiment] tasks", "'..'", "allowed:")
  assert tree(tmp_path) == before


def test_an_experiment_shorter_than_one_curve_point_is_refused_when_read(tmp_path, capsys):
  path = tmp_path / "e.toml"
  path.write_text(experiment_text("short", TASK, 1, 200))
  refused(capsys, ["run", path, "--out", tmp_path / "out", "--quiet"],
          "[experiment] episodes = 200", ">= 1000")
  assert not (tmp_path / "out").exists()


def test_a_run_onto_a_file_is_refused_before_any_run(tmp_path, capsys):
  path = tmp_path / "e.toml"
  path.write_text(experiment_text("fine", TASK, 1, 1000))
  (tmp_path / "notes.txt").write_text("mine")
  refused(capsys, ["run", path, "--out", tmp_path / "notes.txt", "--quiet"],
          "--out", "notes.txt", "is a file")
  assert (tmp_path / "notes.txt").read_text() == "mine"


def test_files_that_are_not_utf8_are_named(tmp_path, capsys):
  bad = tmp_path / "bad.toml"
  bad.write_bytes(b"\xff\xfe[task]\n")
  refused(capsys, ["train", bad, "--out", tmp_path / "a"], "bad.toml", "not UTF-8", "0xff")
  refused(capsys, ["run", bad, "--out", tmp_path / "a"], "bad.toml", "not UTF-8")
  assert tree(tmp_path) == ["bad.toml"]


def test_train_never_replaces_or_mixes_into_what_is_not_an_agent(tmp_path, capsys):
  notes = tmp_path / "notes.txt"
  notes.write_text("mine")
  refused(capsys, ["train", TASK, "--episodes", 5, "--out", notes], "--out", "is a file")
  refused(capsys, ["train", TASK, "--episodes", 5, "--out", notes, "--force"], "is a file")
  assert notes.read_text() == "mine"
  # A folder of the user's own: refused; with --force the agent goes beside the files.
  mine = tmp_path / "mydir"
  mine.mkdir()
  (mine / "paper.tex").write_text("mine")
  refused(capsys, ["train", TASK, "--episodes", 5, "--out", mine], "paper.tex", "--force")
  assert tree(mine) == ["paper.tex"]
  assert cli.main(["train", TASK, "--episodes", "5", "--out", str(mine), "--force",
                   "--quiet"]) == 0
  assert tree(mine) == ["agent.json", "arrays.npz", "paper.tex"]
  assert (mine / "paper.tex").read_text() == "mine"
  # A saved agent is replaced only with --force.
  capsys.readouterr()
  refused(capsys, ["train", TASK, "--episodes", 5, "--out", mine], "saved agent", "--force")
  # A file of an agent's name that is not one is never replaced, even with --force.
  other = tmp_path / "other"
  other.mkdir()
  (other / storage.METADATA).write_text(json.dumps({"mine": True}))
  refused(capsys, ["train", TASK, "--episodes", 5, "--out", other, "--force"],
          "agent.json", "not a saved hpg_mj agent")
  assert json.loads((other / storage.METADATA).read_text()) == {"mine": True}
  # Below a file: refused too.
  refused(capsys, ["train", TASK, "--episodes", 5, "--out", notes / "sub"], "notes.txt",
          "is a file")


def test_seeds_are_held_to_what_the_generator_takes(tmp_path, capsys):
  assert rng.MAX_SEED == 2 ** 64 - 1
  # Past 64 bits a seed would alias a smaller one: make_state keeps the low bits.
  assert (rng.make_state(2 ** 64 + 5) == rng.make_state(5)).all()
  too_big = 99999999999999999999999
  for argv in (["train", TASK, "--seed", too_big], ["evaluate", tmp_path, "--seed", too_big],
               ["render", "--seed", too_big], ["verify", "ship", "--seed", too_big]):
    refused(capsys, argv, "--seed", f"0..{rng.MAX_SEED}")
  refused(capsys, ["train", TASK, "--seed", -1], "--seed", ">= 0")
  from hpg_mj import agents
  text = agents.shipped_tasks()[TASK].read_text()
  task = tmp_path / "t.toml"
  task.write_text(text.replace("seed = 0", f"seed = {2 ** 64}", 1))
  refused(capsys, ["train", task], "[protocol] seed", str(rng.MAX_SEED))
  path = tmp_path / "e.toml"
  path.write_text(experiment_text("fine", TASK, 3, 1000).replace(
      "tuning = true", f"tuning = true\nfirst_seed = {2 ** 64 - 2}"))
  refused(capsys, ["run", path, "--out", tmp_path / "out"], "first_seed", "allowed: seeds")
  # The largest seed is taken.
  assert cli.main(["train", TASK, "--seed", str(rng.MAX_SEED), "--episodes", "3", "--out",
                   str(tmp_path / "big"), "--quiet"]) == 0
  assert json.loads((tmp_path / "big" / "agent.json").read_text())["seed"] == rng.MAX_SEED


def test_render_checks_its_output_path_before_drawing(tmp_path, capsys):
  notes = tmp_path / "notes.txt"
  notes.write_text("mine")
  refused(capsys, ["render", "--out", notes / "v.mp4"], "--out", "notes.txt", "is a file")
  refused(capsys, ["render", "--out", tmp_path / "v.txt"], "--out", ".mp4, .gif")
  (tmp_path / "folder.mp4").mkdir()
  refused(capsys, ["render", "--out", tmp_path / "folder.mp4"], "is a folder")
  refused(capsys, ["render", "--agent", tmp_path / "nowhere", "--out", notes / "v.gif"],
          "is a file")
  if os.access("/proc", os.W_OK):           # root may "write" /proc, but no file lands there
    refused(capsys, ["render", "--out", "/proc/hpg_mj_test/v.mp4"], "cannot be written")
  mine = tmp_path / "mine.mp4"                # a video of the user's is not replaced
  mine.write_bytes(b"the user's film")
  refused(capsys, ["render", "--out", mine], "--out", "mine.mp4 exists", "--force")
  assert mine.read_bytes() == b"the user's film"
  assert tree(tmp_path) == ["folder.mp4", "mine.mp4", "notes.txt"]


def test_options_are_refused_in_one_line(tmp_path, capsys):
  refused(capsys, ["train", TASK, "--episodes", "0"], "--episodes", ">= 1", "--help")
  refused(capsys, ["train"], "give a task file")
  refused(capsys, ["bench", "envs", "--seconds", "nan"], "--seconds", "seconds > 0")
  refused(capsys, ["tune", TASK, "--seeds", "a,b"], "--seeds", "integers")
  refused(capsys, ["tune", TASK, "--json", tmp_path], "--json", "is a folder")
  refused(capsys, ["evaluate", tmp_path / "nowhere"], "nowhere", "agent.json")
  refused(capsys, ["--import", "no_such_module_here", "doctor"], "--import",
          "no_such_module_here")


def test_a_shipped_experiment_still_reads(tmp_path):
  for name in runner.shipped_experiments():
    runner.load_experiment(name)
