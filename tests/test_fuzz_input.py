"""Fuzzing what a user gives `hpg-mj` (issue 23 item 3): task files, experiment
files and command-line options, mutated by hypothesis (types, ranges, missing and
unknown keys and sections, names that are paths, odd strings, raw bytes). Every
case ends in a valid run (exit 0) or one line `hpg-mj CMD: error: ...` (exit 2),
never a traceback, and nothing is written outside the output folder.

Cheap by construction: the taxi's flat Q-learner, a few episodes, one worker;
inputs whose run would be long (many runs, long episodes) are only read. The
examples are derandomized, so CI sees the same cases on every run."""
import contextlib
import copy
import io
import json
import math
import os
import pathlib
import tempfile
import tomllib

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, event, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from hpg_mj import agents  # noqa: E402
from hpg_mj import cli  # noqa: E402
from hpg_mj import taskfile  # noqa: E402
from hpg_mj.experiments import runner  # noqa: E402

TASK_NAME = "taxi_fuel_flat_q"
TASK = tomllib.loads(agents.shipped_tasks()[TASK_NAME].read_text())
EXPERIMENT = {
    "experiment": {"name": "fz", "description": "fuzzed", "tasks": [TASK_NAME], "runs": 1,
                   "episodes": 1000, "quick_runs": 1, "quick_episodes": 1000, "tuning": True},
    "figure": [{"name": "curve", "kind": "curve", "metric": "mean_return", "x": "episodes",
                "title": "t", "ylabel": "y", "paper": "p"}],
}
SETTINGS = settings(max_examples=120, deadline=None, derandomize=True, database=None,
                    suppress_health_check=list(HealthCheck))

# Names that would be paths, and other odd strings.
NAMES = st.sampled_from(["..", "../escaped", "../../escaped", "/tmp/hpg_mj_fuzz_escaped", "a/b",
                         "a\\b", "", ".", ".hidden", "-rf", "x" * 101, "ok", "é", "a b",
                         "taxi_fuel_flat_q", "ship_hybrid", "my_pkg.agents:Nothing",
                         "os:system", "hpg_mj.agents.base:Agent"])
VALUES = st.one_of(
    st.sampled_from([0, 1, 2, 3, -1, 7, 1000, 2 ** 31, 2 ** 63 - 1, 2 ** 64, -2 ** 63]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.booleans(),
    st.text(max_size=10),
    NAMES,
    st.lists(st.integers(-3, 12), max_size=4),
    st.lists(NAMES, max_size=3),
    st.dictionaries(st.text(max_size=4), st.integers(0, 3), max_size=2),
)


def _value(v):
  """A TOML value (tomllib writes none)."""
  if isinstance(v, bool):
    return "true" if v else "false"
  if isinstance(v, int):
    return str(v)
  if isinstance(v, float):
    return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
  if isinstance(v, str):
    return _key(v)         # JSON's escapes are TOML's, but for \ud800-style surrogate pairs
  if isinstance(v, list):
    return "[" + ", ".join(_value(x) for x in v) + "]"
  return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"


def _key(k):
  return json.dumps(k, ensure_ascii=False)


def dumps(data):
  """TOML text of a dict of tables (arrays of tables for lists of dicts)."""
  lines = [f"{_key(k)} = {_value(v)}" for k, v in data.items()
           if not isinstance(v, dict) and not (isinstance(v, list) and v and
                                               all(isinstance(x, dict) for x in v))]
  for k, v in data.items():
    if isinstance(v, dict):
      lines.append(f"[{_key(k)}]")
      lines += [f"{_key(key)} = {_value(x)}" for key, x in v.items()]
    elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
      for table in v:
        lines.append(f"[[{_key(k)}]]")
        lines += [f"{_key(key)} = {_value(x)}" for key, x in table.items()]
  return "\n".join(lines) + "\n"


def _tables(data):
  """(container, key) of every value in the tables of `data`, tables included."""
  places = []
  for name, table in data.items():
    places.append((data, name))
    if isinstance(table, dict):
      places += [(table, key) for key in table]
      if isinstance(table.get("grid"), dict):
        places += [(table["grid"], key) for key in table["grid"]]
    elif isinstance(table, list):
      for item in table:
        if isinstance(item, dict):
          places += [(item, key) for key in item]
  return places


def _near(value):
  """A value of the same type as `value`, often in range: most runs should be valid."""
  if isinstance(value, bool):
    return st.booleans()
  if isinstance(value, int):
    return st.sampled_from([0, 1, 2, 3, 7, 1000, value])
  if isinstance(value, float):
    return st.sampled_from([0.0, 0.5, 1.0, 1e-9, 2.0, value])
  if isinstance(value, str):
    return st.one_of(NAMES, st.text(max_size=10), st.just(value))
  return st.just(value)


def mutated(data, draw):
  """`data` after 1-3 mutations, as TOML bytes (sometimes with raw bytes changed)."""
  data = copy.deepcopy(data)
  for _ in range(draw(st.sampled_from([1, 1, 1, 2, 3]))):
    places = _tables(data)
    how = draw(st.sampled_from(["near", "near", "near", "replace", "replace", "delete", "add"]))
    if how == "add" or not places:
      tables = [v for v in data.values() if isinstance(v, dict)] + [data]
      table = draw(st.sampled_from(tables))
      table[draw(st.text(min_size=1, max_size=8))] = draw(VALUES)
      continue
    container, key = draw(st.sampled_from(places))
    if how == "delete":
      del container[key]
    elif how == "near":
      container[key] = draw(_near(container[key]))
    else:
      container[key] = draw(VALUES)
  text = dumps(data).encode("utf-8", "surrogatepass")
  if draw(st.integers(0, 7)) == 0:                 # now and then, bytes
    at = draw(st.integers(0, len(text)))
    text = text[:at] + draw(st.binary(min_size=1, max_size=3)) + text[at + 1:]
  return text


@contextlib.contextmanager
def sandbox():
  """A fresh folder as the current one: (its parent, the folder)."""
  old = os.getcwd()
  with tempfile.TemporaryDirectory() as parent:
    box = pathlib.Path(parent) / "box"
    box.mkdir()
    os.chdir(box)
    try:
      yield pathlib.Path(parent), box
    finally:
      os.chdir(old)


def tree(root):
  return {p for p in pathlib.Path(root).rglob("*")}


def _inside(path, folder):
  path, folder = os.path.abspath(path), os.path.abspath(folder)
  return path == folder or path.startswith(folder + os.sep)


def run_cli(argv, parent, allowed):
  """Runs `hpg-mj argv`; holds that it ends in exit 0 or in one error line (exit 2),
  and that every new path under `parent` (which holds the escape targets too) is
  inside one of `allowed`. Returns the exit status."""
  before = tree(parent)
  err, out = io.StringIO(), io.StringIO()
  with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
    try:
      rc = cli.main([str(a) for a in argv])
    except SystemExit as exit_:       # argparse's refusals
      rc = exit_.code
  text = err.getvalue()
  assert "Traceback" not in text, text
  lines = text.strip().splitlines()
  if rc != 0:
    assert rc == 2 and len(lines) == 1, (argv, rc, text)
    assert lines[0].startswith("hpg-mj") and ": error: " in lines[0], lines
  said = lines[0].split(": error: ", 1)[1].split(".toml: ")[-1] if rc else ""
  event(f"{argv[0]}: exit {rc}" + (f" ({said[:30]})" if rc else ""))
  new = tree(parent) - before
  outside = [p for p in new if not any(_inside(p, a) or (p.is_dir() and _inside(a, p))
                                        for a in allowed)]     # or a folder made on the way
  assert not outside, (argv, sorted(map(str, outside)))
  return rc


def _short(task):
  """Whether a loaded task file's episodes are short enough to run here."""
  env = task.section("environment")
  return env.get("max_steps", 0) <= 5000


def read_then_run(text, name, load, too_long, argv):
  """Writes the mutated file; if `load` takes it and `too_long(loaded)`, stops there
  (read and taken); else runs `argv(path, out)` through `run_cli` (a refusal by
  `load` must reach the user as one line)."""
  with sandbox() as (parent, box):
    path = box / name
    path.write_bytes(text)
    try:
      loaded = load(path)
    except taskfile.TaskFileError:
      loaded = None
    if loaded is not None and too_long(loaded):
      event(f"{name}: read, too long to run")
      return
    run_cli(argv(path, box / "out"), parent, [box / "out"])


@SETTINGS
@given(st.data())
def test_mutated_task_files_train_or_are_refused_in_one_line(data):
  read_then_run(mutated(TASK, data.draw), "t.toml", agents.load_task,
                lambda task: not _short(task),
                lambda path, out: ["train", path, "--episodes", 2, "--seed", 1, "--out", out,
                                   "--quiet"])


@settings(SETTINGS, max_examples=60)
@given(st.data())
def test_mutated_experiment_files_run_or_are_refused_in_one_line(data):
  read_then_run(mutated(EXPERIMENT, data.draw), "e.toml", runner.load_experiment,
                lambda e: (e["runs"] * e["episodes"] > 2000
                           or not all(_short(t) for t in e["task_files"])),
                lambda path, out: ["run", path, "--out", out, "--workers", 1, "--quiet"])


PATHS = ["out/new", "notes.txt", "notes.txt/sub", "mine", "../escaped", "ABSOLUTE", "", ".",
         "agent"]                         # ABSOLUTE: a path outside the folder, made absolute
COUNTS = ["1", "2", "0", "-1", "x", "", "1.5", "2e0"]
OPTIONS = {          # each command's options, with good and bad values
    "train": {"--episodes": COUNTS, "--seed": ["0", "3", str(2 ** 64 - 1), str(2 ** 64), "-1",
                                               "1e3", "seed"],
              "--backend": ["analytic", "mujoco", "gpu", ""], "--out": PATHS,
              "--json": None, "--quiet": None, "--force": None},
    "evaluate": {"--episodes": COUNTS, "--seed": ["0", str(2 ** 64), "-2"],
                 "--backend": ["analytic", "gpu"], "--policy": ["greedy", "sampled", "best"],
                 "--json": None},
    "run": {"--workers": ["1", "0", "x"], "--checkpoint-every": ["500", "0", "-1", "y"],
            "--executor": ["process", "dask"], "--out": PATHS, "--quick": None,
            "--no-wait": None, "--quiet": None},
}
FOREIGN = {"--bogus": None, "--help-me": None, "--policy": ["greedy"], "--force": None}
FIRST = {"train": [TASK_NAME, "t.toml", "agent", "nowhere", ""],
         "evaluate": ["agent", "mine", "notes.txt", "nowhere", ""],
         "run": ["e.toml", "nowhere.toml", "notes.txt", "agent", ""]}


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
  folder = tmp_path_factory.mktemp("trained") / "agent"
  assert cli.main(["train", TASK_NAME, "--episodes", "3", "--out", str(folder), "--quiet"]) == 0
  return folder


@settings(SETTINGS, max_examples=120)
@given(st.data())
def test_mutated_command_lines_run_or_are_refused_in_one_line(trained, data):
  command = data.draw(st.sampled_from(sorted(OPTIONS)))
  options = {**OPTIONS[command], **FOREIGN} if data.draw(st.integers(0, 4)) == 0 else \
      OPTIONS[command]
  names = data.draw(st.lists(st.sampled_from(sorted(options)), max_size=4))
  with sandbox() as (parent, box):
    (box / "notes.txt").write_text("mine")
    (box / "mine").mkdir()
    (box / "mine" / "paper.tex").write_text("mine")
    (box / "agent").mkdir()
    for f in trained.iterdir():
      (box / "agent" / f.name).write_bytes(f.read_bytes())
    (box / "e.toml").write_text(dumps(EXPERIMENT))
    argv = [command, data.draw(st.sampled_from(FIRST[command]))]
    if command == "train" and "--episodes" not in names:
      argv += ["--episodes", "2"]       # never the task file's 100,000
    if command == "run" and "--workers" not in names:
      argv += ["--workers", "1"]        # no process pool to start
    for name in names:
      argv.append(name)
      if options[name] is not None:
        value = data.draw(st.sampled_from(options[name]))
        argv.append(str(parent / "elsewhere") if value == "ABSOLUTE" else value)
    outs = [argv[k + 1] for k, a in enumerate(argv[:-1]) if a == "--out"]
    allowed = [box / o for o in outs] or [box / "runs"]
    before = {p: p.read_bytes() for p in tree(box) if p.is_file()}
    rc = run_cli(argv, parent, allowed)
    for p, content in before.items():   # nothing of the user's is replaced
      if p.parent.name != "agent" or "--force" not in argv:
        assert p.read_bytes() == content, (argv, p)
    if rc == 0 and command == "train":
      assert any((box / o / "agent.json").is_file() for o in outs) or not outs
