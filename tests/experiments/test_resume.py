"""Runs write their metrics as they go, checkpoint atomically, survive SIGKILL and
damaged checkpoints, and give the same numbers under any executor (Ray against a run
made alone: tests/experiments/test_locks.py)."""
import os
import pathlib
import random
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import hpg_mj
from hpg_mj import agents
from hpg_mj import storage
from hpg_mj.experiments import runner, runs
from experiment_file import assert_same_run, experiment_text, final_run



def _experiment(tmp_path, task="ship_hybrid", n_runs=1, episodes=6000):
  path = tmp_path / f"{task}.toml"
  metric = "mean_return" if task.startswith("taxi") else "gate_passes"
  path.write_text(experiment_text("resume", task, n_runs, episodes, "one task, one seed", metric))
  return path


def test_progress_is_written_as_the_run_goes(tmp_path):
  run_dir = tmp_path / "run"
  task = agents.load_task("taxi_fuel_flat_q")
  with pytest.raises(runs.RunInterrupted):
    runs.run(str(task.path), 0, 5000, run_dir, checkpoint_every=2000, stop_after=3000)
  lines = (run_dir / "progress.csv").read_text().splitlines()
  assert lines[0] == "episodes,wall_seconds,episodes_per_second,mean_return"
  assert [int(line.split(",")[0]) for line in lines[1:]] == [1000, 2000, 3000]
  assert runs.read_progress(run_dir)[0] == 3000
  assert [p.name for p in (run_dir / "checkpoints").iterdir()] == ["ep2000"]
  assert not runs.is_finished(run_dir)
  # Resumed from episode 2000: the rows after it are cut, then written again.
  runs.run(str(task.path), 0, 5000, run_dir, checkpoint_every=2000)
  lines = (run_dir / "progress.csv").read_text().splitlines()
  assert [int(line.split(",")[0]) for line in lines[1:]] == [1000, 2000, 3000, 4000, 5000]
  assert "resumed from checkpoint ep2000 (episode 2000)" in (run_dir / "events.log").read_text()
  assert not (run_dir / "checkpoints").exists()      # a finished run keeps its agent only
  record = np.load(run_dir / "record.npy")
  assert record.shape[0] == 5000


def test_a_run_killed_with_sigkill_resumes_bit_identical(tmp_path):
  path = _experiment(tmp_path)
  env = dict(os.environ, PYTHONPATH=str(pathlib.Path(hpg_mj.__file__).resolve().parents[1]))
  command = [sys.executable, "-m", "hpg_mj.cli", "run", str(path), "--workers", "1", "--quiet",
             "--checkpoint-every", "1000"]
  # The uninterrupted run.
  whole = subprocess.run(command + ["--out", str(tmp_path / "whole")], env=env, check=True,
                         capture_output=True, text=True)
  assert "resume: 1 run (1 new, " in whole.stdout, whole.stdout
  # The same command, killed at a random point after its first checkpoint...
  rnd = random.Random()
  target = rnd.randrange(1500, 5000)
  pause = rnd.uniform(0.0, 0.2)
  out = tmp_path / "killed"
  run_dir = out / "resume" / "ship_hybrid" / "seed0"
  proc = subprocess.Popen(command + ["--out", str(out)], env=env, stdout=subprocess.DEVNULL,
                          stderr=subprocess.DEVNULL)
  deadline = time.monotonic() + 300
  while runs.read_progress(run_dir)[0] < target and proc.poll() is None:
    assert time.monotonic() < deadline, "the run did not progress"
    time.sleep(0.01)
  time.sleep(pause)
  proc.send_signal(signal.SIGKILL)
  proc.wait()
  assert proc.returncode == -signal.SIGKILL, (target, pause)
  assert not runs.is_finished(run_dir), "the run finished before it was killed"
  killed_at = runs.read_progress(run_dir)[0]
  # ...and run again: it resumes from its last checkpoint (and says so).
  again = subprocess.run(command + ["--out", str(out)], env=env, check=True,
                         capture_output=True, text=True)
  assert "resume: 1 run (1 resumed, " in again.stdout, again.stdout
  log = (run_dir / "events.log").read_text()
  assert "resumed from checkpoint ep" in log, log
  assert_same_run(final_run(tmp_path / "whole" / "resume" / "ship_hybrid" / "seed0"), final_run(run_dir))
  print(f"killed near episode {killed_at} (target {target}, pause {pause:.3f} s)")


def test_a_damaged_checkpoint_falls_back_to_the_previous_good_one(tmp_path, capsys):
  task = str(agents.load_task("ship_flat_pg").path)
  runs.run(task, 1, 4000, tmp_path / "whole", checkpoint_every=1000)
  run_dir = tmp_path / "broken"
  with pytest.raises(runs.RunInterrupted):
    runs.run(task, 1, 4000, run_dir, checkpoint_every=1000, stop_after=3000)
  assert [p.name for p in runs._checkpoints(run_dir)] == ["ep3000", "ep2000"]
  arrays = run_dir / "checkpoints" / "ep3000" / storage.ARRAYS
  blob = bytearray(arrays.read_bytes())
  blob[len(blob) // 2] ^= 0xFF
  arrays.write_bytes(bytes(blob))
  runs.run(task, 1, 4000, run_dir, checkpoint_every=1000)
  err = capsys.readouterr().err
  assert "damaged checkpoint ep3000" in err and "SHA-256" in err
  log = (run_dir / "events.log").read_text()
  assert "resumed from checkpoint ep2000 (episode 2000)" in log
  assert (run_dir / "damaged-ep3000").is_dir() is False     # removed with the checkpoints
  assert_same_run(final_run(tmp_path / "whole"), final_run(run_dir))


def test_a_checkpoint_cut_short_is_ignored(tmp_path):
  task = str(agents.load_task("taxi_fuel_hpg").path)
  run_dir = tmp_path / "run"
  with pytest.raises(runs.RunInterrupted):
    runs.run(task, 0, 3000, run_dir, checkpoint_every=1000, stop_after=1000)
  # A kill while writing ep2000 leaves only its temporary folder.
  (run_dir / "checkpoints" / ".tmp-ep2000").mkdir()
  (run_dir / "checkpoints" / ".tmp-ep2000" / storage.ARRAYS).write_bytes(b"PK\x03\x04")
  runs.run(task, 0, 3000, run_dir, checkpoint_every=1000)
  runs.run(task, 0, 3000, tmp_path / "whole", checkpoint_every=1000)
  assert_same_run(final_run(tmp_path / "whole"), final_run(run_dir))


def test_bad_checkpoint_interval_is_refused(tmp_path):
  with pytest.raises(ValueError, match="checkpoint_every must be a positive number"):
    runs.run(str(agents.load_task("ship_hybrid").path), 0, 10, tmp_path, checkpoint_every=0)


def test_unknown_executor_and_bad_counts_are_refused(tmp_path):
  experiment = runner.load_experiment(_experiment(tmp_path))
  with pytest.raises(ValueError, match=r"unknown executor 'dask'; valid executors: \['process', 'ray'\]"):
    runner.run_experiment(experiment, tmp_path, executor="dask")
  with pytest.raises(ValueError, match="workers must be a positive number of processes, got 0"):
    runner.run_experiment(experiment, tmp_path, workers=0)
  with pytest.raises(ValueError, match="checkpoint_every must be a positive number of episodes"):
    runner.run_experiment(experiment, tmp_path, checkpoint_every=-5)
  assert not (tmp_path / "resume").exists()
