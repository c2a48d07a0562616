"""Task files are validated before anything runs; saved agents round-trip exactly
and damaged or foreign ones are refused."""
import json
import pathlib

import numpy as np
import pytest

from hpg_mj import cli
from hpg_mj import agents
from hpg_mj import storage, taskfile

REPO = pathlib.Path(__file__).resolve().parents[2]
SHIP = REPO / "tasks" / "ship_hybrid.toml"


def _variant(tmp_path, old, new):
  text = SHIP.read_text()
  assert old in text
  path = tmp_path / "variant.toml"
  path.write_text(text.replace(old, new, 1))
  return path


def test_shipped_task_files_load():
  task = agents.load_task(SHIP)
  assert task.kind == "ship_hybrid"
  assert task.section("root")["alpha"] == 0.1
  assert task.section("low_level")["tiles"] == (5, 5, 36, 5)
  assert task.section("protocol")["tuning_seeds"] == list(range(10))


@pytest.mark.parametrize("old,new,message", [
    ("alpha = 0.1", "alpah = 0.1", r"\[root\] unknown key\(s\) \['alpah'\]; allowed: .*'alpha'"),
    ("alpha = 0.1", "alpha = \"fast\"", r"\[root\] alpha must be a number, got 'fast'"),
    ("episodes = 50000", "", r"\[protocol\] episodes is missing \(an integer\)"),
    ("episodes = 50000", "episodes = 5.5", r"\[protocol\] episodes must be an integer"),
    ("kind = \"ship_hybrid\"", "kind = \"ship_magic\"", r"kind = 'ship_magic' is not allowed"),
    ("backend = \"analytic\"", "backend = \"bullet\"", r"allowed: \['analytic', 'mujoco'\]"),
    ("tiles = [5, 5, 36, 5]", "tiles = [5, 5, 36]", r"tiles must be a list of 4 positive"),
    ("[protocol]", "[protocols]", r"unknown section\(s\) \['protocols'\]"),
    ("trace_decay = 0.9", "trace_decay = 1.9", r"\[root\] trace_decay = 1.9 is out of range; allowed: >= 0 and <= 1"),
    ("seed = 0", "seed = 0\nseed = 1", r"not valid TOML"),
    ("tuning_seeds = [0,", "tuning_seeds = [-1,", r"tuning_seeds must be a non-empty list of"),
    ("baseline = 0.3", "baseline = 1.5", r"\[low_level\] baseline = 1.5 is out of range"),
])
def test_malformed_task_files_are_refused(tmp_path, old, new, message):
  path = _variant(tmp_path, old, new)
  with pytest.raises(taskfile.TaskFileError, match=message) as info:
    agents.build(agents.load_task(path))
  assert str(path) in str(info.value)


def test_cli_train_refuses_a_bad_file_before_running(tmp_path, capsys):
  path = _variant(tmp_path, "alpha = 0.1", "alpah = 0.1")
  assert cli.main(["train", str(path), "--out", str(tmp_path / "agent")]) == 2
  assert "unknown key" in capsys.readouterr().err
  assert not (tmp_path / "agent").exists()


def test_train_save_load_and_resume_exactly(tmp_path):
  task = agents.load_task(SHIP)
  agent, record, _ = agents.train(task, episodes=300, seed=3)
  agents.save(agent, tmp_path / "a", record)
  loaded, loaded_record, meta = agents.load(tmp_path / "a")
  np.testing.assert_array_equal(loaded_record, record)
  assert meta["episodes"] == 300 and loaded.episodes == 300
  for name, value in agent.state().items():
    np.testing.assert_array_equal(loaded.state()[name], value)
  # Continuing the loaded agent == continuing the original: the state is whole.
  more_a = agent.train(100, "analytic")
  more_b = loaded.train(100, "analytic")
  np.testing.assert_array_equal(more_a, more_b)
  for name, value in agent.state().items():
    np.testing.assert_array_equal(loaded.state()[name], value)


def test_damaged_and_foreign_agents_are_refused(tmp_path):
  task = agents.load_task(SHIP)
  agent, record, _ = agents.train(task, episodes=10, seed=0)
  good = tmp_path / "good"
  agents.save(agent, good, record)
  # Damaged arrays.
  damaged = tmp_path / "damaged"
  damaged.mkdir()
  (damaged / "agent.json").write_text((good / "agent.json").read_text())
  blob = bytearray((good / "arrays.npz").read_bytes())
  blob[len(blob) // 2] ^= 0xFF
  (damaged / "arrays.npz").write_bytes(bytes(blob))
  with pytest.raises(storage.AgentFileError, match="damaged: its SHA-256 does not match"):
    agents.load(damaged)
  # Foreign metadata.
  foreign = tmp_path / "foreign"
  foreign.mkdir()
  (foreign / "arrays.npz").write_bytes((good / "arrays.npz").read_bytes())
  (foreign / "agent.json").write_text(json.dumps({"format": "something-else"}))
  with pytest.raises(storage.AgentFileError, match="not an hpg_mj agent"):
    agents.load(foreign)
  (foreign / "agent.json").write_text("{not json")
  with pytest.raises(storage.AgentFileError, match="not valid JSON"):
    agents.load(foreign)
  with pytest.raises(storage.AgentFileError, match="needs agent.json and arrays.npz"):
    agents.load(tmp_path / "nowhere")
  # A future version.
  meta = json.loads((good / "agent.json").read_text())
  meta["version"] = 99
  (foreign / "agent.json").write_text(json.dumps(meta))
  with pytest.raises(storage.AgentFileError, match="version 99"):
    agents.load(foreign)
  # Pickled objects are never loaded.
  assert "allow_pickle=False" in pathlib.Path(storage.__file__).read_text()


def test_cli_train_and_evaluate_print_json(tmp_path, capsys):
  out = tmp_path / "agent"
  assert cli.main(["train", str(SHIP), "--episodes", "1200", "--seed", "1", "--out", str(out),
                   "--json"]) == 0
  metrics = json.loads(capsys.readouterr().out)
  for key in ("gate_pass_rate", "steps_to_gate", "calls_per_episode", "diagonal_success_rate",
              "straight_success_rate", "control_steps", "wall_seconds"):
    assert key in metrics
  assert metrics["episodes_measured"] == 1000
  assert cli.main(["evaluate", str(out), "--episodes", "20", "--json"]) == 0
  evaluation = json.loads(capsys.readouterr().out)
  assert evaluation["episodes_measured"] == 20 and evaluation["policy"] == "greedy"
  assert cli.main(["evaluate", str(out), "--episodes", "3", "--backend", "mujoco",
                   "--policy", "sampled", "--json"]) == 0
  assert json.loads(capsys.readouterr().out)["backend"] == "mujoco"


TASK_FILES = sorted((REPO / "tasks").glob("*.toml"))


def test_every_kind_has_a_task_file():
  shipped = {n for n in agents.names() if agents.lookup(n).__module__.startswith("hpg_mj.")}
  assert {agents.load_task(p).kind for p in TASK_FILES} == shipped


@pytest.mark.parametrize("path", TASK_FILES, ids=lambda p: p.stem)
def test_a_configuration_written_as_a_task_file_reads_back_the_same(path):
  """`taskfile.dumps`, what `agents.save` records for an agent made in Python."""
  task = agents.load_task(path)
  text = taskfile.dumps(task.kind, task.config, 7, 3, 'a "quoted" \\ description')
  again = taskfile.loads(text, "saved.toml", agents._Registry)
  assert again.config == task.config and again.kind == task.kind
  assert (again.protocol.episodes, again.protocol.seed) == (7, 3)


# The Stable-Baselines3 agents' own tests (tests/test_sb3.py) train them with tiny budgets,
# and the JAX agents' (tests/jax/test_jax_ppo.py) in the JAX tests' own process.
OWN_TASK_FILES = [p for p in TASK_FILES
                  if not {"stable-baselines3", "jax"} & set(agents.lookup(agents.load_task(p).kind).tags)]


@pytest.mark.parametrize("path", OWN_TASK_FILES, ids=lambda p: p.stem)
def test_every_task_file_trains_saves_and_resumes_exactly(tmp_path, path):
  task = agents.load_task(path)
  agent, record, _ = agents.train(task, episodes=60, seed=2)
  metrics = agent.metrics(record)
  assert metrics["episodes_measured"] == 60
  agents.save(agent, tmp_path / "agent", record)
  loaded, _, _ = agents.load(tmp_path / "agent")
  np.testing.assert_array_equal(agent.train(20, "analytic"), loaded.train(20, "analytic"))
  for name, value in agent.state().items():
    np.testing.assert_array_equal(loaded.state()[name], value)
  # Evaluation through the MuJoCo world (dm_control / Gymnasium) works too (the
  # continuing ship_patrol's rows are hours: one). The ladder's flat PGRL and
  # option-critic files are evaluated fused: tests/hierarchy/test_ladder_paths.py takes
  # the step-by-step path through every ladder world (the hybrid's graph) and flat
  # PGRL's and the option-critic's graphs (the current and the goal), and the hybrids'
  # files here take the worlds' MuJoCo backends (each a graph's step-by-step compile:
  # seconds on a cold cache).
  rows = 1 if task.kind == "ship_patrol" else 2
  fused = task.kind in ("ship_ladder_flat_pg", "ship_ladder_option_critic")
  evaluation = loaded.evaluate(rows, "analytic" if fused else "mujoco")
  assert len(evaluation) == rows


@pytest.mark.parametrize("name", ["ship_hybrid", "taxi_fuel_hpg"])
def test_cli_renders_a_trained_agent(tmp_path, capsys, name):
  path = _variant(tmp_path, "max_steps = 5000", "max_steps = 25") if name == "ship_hybrid" \
      else REPO / "tasks" / f"{name}.toml"
  agent_dir = tmp_path / "agent"
  assert cli.main(["train", str(path), "--episodes", "30", "--out", str(agent_dir), "--quiet"]) == 0
  capsys.readouterr()
  out = tmp_path / "learned.gif"
  assert cli.main(["render", "--agent", str(agent_dir), "--out", str(out), "--width", "160",
                   "--height", "128"]) == 0
  assert "a greedy episode" in capsys.readouterr().out
  import imageio.v2 as imageio
  frames = imageio.mimread(out)
  assert len(frames) >= 3 and np.asarray(frames[0]).std() > 5
