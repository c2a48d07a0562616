"""Run folders are locked: two commands on one output folder never write the same
run, a second one waits (or refuses with a message naming the run and its holder),
a lock left by a killed process blocks nothing, and the results equal a run made
alone, on the process pool and on Ray."""
import json
import os
import pathlib
import signal
import subprocess
import sys
import threading
import time

import pytest

import hpg_mj
from hpg_mj import agents
from hpg_mj.experiments import locks, runner, runs
from experiment_file import assert_same_run, experiment_text, final_run

ENV = dict(os.environ, PYTHONPATH=str(pathlib.Path(hpg_mj.__file__).resolve().parents[1]))
# The commands run from outside the checkout, so that they import the installed
# hpg_mj, as this process does (`python -m` puts the working folder first).
CWD = pathlib.Path(hpg_mj.__file__).resolve().parents[1]


def _experiment(tmp_path, task="taxi_fuel_hpg", episodes=3000):
  path = tmp_path / f"{task}.toml"
  metric = "mean_return" if task.startswith("taxi") else "gate_passes"
  path.write_text(experiment_text("locked", task, 2, episodes, "one task, two seeds", metric))
  return path


def _command(path, out, *extra):
  return [sys.executable, "-m", "hpg_mj.cli", "run", str(path), "--out", str(out), "--quiet",
          "--checkpoint-every", "1000", *extra]


@pytest.fixture(scope="module")
def alone(tmp_path_factory):
  """The experiment run alone, in this process: each seed's final run, and under
  "metrics" what `run_experiment` returned for each."""
  tmp = tmp_path_factory.mktemp("alone")
  experiment = runner.load_experiment(_experiment(tmp))
  results, root, _ = runner.run_experiment(experiment, tmp / "out", workers=1,
                                           checkpoint_every=1000)
  runs_alone = {seed: final_run(root / "taxi_fuel_hpg" / f"seed{seed}") for seed in range(2)}
  return {**runs_alone, "metrics": results["taxi_fuel_hpg"]}


def _same_metrics(a, b):
  """Two runs' metrics (as `run_experiment` returns them) alike but for their seconds and
  provenance; each run's seconds add up (compile + train = wall)."""
  a, b = dict(a), dict(b)
  for m in (a, b):
    assert m.pop("wall_seconds") == pytest.approx(
        m.pop("compile_seconds") + m.pop("train_seconds"), abs=0.0015)
    m.pop("provenance")
  assert a == b


def _holder_process(run_dir):
  """A process that takes the run's lock, says so on stdout, and sleeps."""
  code = ("import sys, time; from hpg_mj.experiments import locks\n"
          f"with locks.hold({str(run_dir)!r}, command='the holder'):\n"
          "  print('held', flush=True); time.sleep(600)\n")
  proc = subprocess.Popen([sys.executable, "-c", code], env=ENV, cwd=CWD, stdout=subprocess.PIPE,
                          text=True)
  assert proc.stdout.readline().strip() == "held"
  return proc


def test_two_commands_at_once_give_the_run_made_alone(tmp_path, alone):
  path = _experiment(tmp_path)
  for attempt in range(3):
    out = tmp_path / f"out{attempt}"
    procs = [subprocess.Popen(_command(path, out, "--workers", "2"), env=ENV, cwd=CWD,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(2)]
    results = [proc.communicate(timeout=300) for proc in procs]
    for proc, (stdout, stderr) in zip(procs, results):
      assert proc.returncode == 0, stderr
      assert "Traceback" not in stderr and "Errno" not in stderr, stderr
      assert "REPORT.md" in stdout
    for seed in range(2):
      run_dir = out / "locked" / "taxi_fuel_hpg" / f"seed{seed}"
      assert_same_run(final_run(run_dir), alone[seed])
      log = (run_dir / "events.log").read_text()
      assert log.count("started seed") == 1, log       # trained by one command only
      assert log.count("finished") == 1, log


def test_a_held_run_is_waited_for_then_run(tmp_path, alone):
  path = _experiment(tmp_path)
  out = tmp_path / "out"
  run_dir = out / "locked" / "taxi_fuel_hpg" / "seed0"
  holder = _holder_process(run_dir)
  try:
    proc = subprocess.Popen(_command(path, out, "--workers", "1"), env=ENV, cwd=CWD,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = proc.stderr.readline()
    assert f"run {run_dir} is held by pid {holder.pid}" in line and "'the holder'" in line
    assert "waiting for it" in line
    assert proc.poll() is None
    assert not (run_dir / "progress.csv").exists()        # nothing written meanwhile
  finally:
    holder.kill()
    holder.wait()
  stdout, stderr = proc.communicate(timeout=300)
  assert proc.returncode == 0, stderr
  for seed in range(2):
    assert_same_run(final_run(out / "locked" / "taxi_fuel_hpg" / f"seed{seed}"), alone[seed])


def test_no_wait_refuses_a_held_run_naming_it_and_its_holder(tmp_path):
  path = _experiment(tmp_path)
  out = tmp_path / "out"
  run_dir = out / "locked" / "taxi_fuel_hpg" / "seed1"
  holder = _holder_process(run_dir)
  try:
    proc = subprocess.run(_command(path, out, "--no-wait"), env=ENV, cwd=CWD, capture_output=True,
                          text=True, timeout=300)
  finally:
    holder.kill()
    holder.wait()
  assert proc.returncode == 2
  assert proc.stderr.startswith(f"hpg-mj run: error: run {run_dir} is held by pid {holder.pid}")
  assert "'the holder'" in proc.stderr and "Traceback" not in proc.stderr
  assert not (out / "locked" / "taxi_fuel_hpg" / "seed0" / "progress.csv").exists()


def test_a_lock_left_by_a_killed_process_blocks_nothing(tmp_path, alone):
  out = tmp_path / "out"
  run_dir = out / "locked" / "taxi_fuel_hpg" / "seed0"
  holder = _holder_process(run_dir)
  holder.send_signal(signal.SIGKILL)
  holder.wait()
  assert (run_dir / locks.LOCK_FILE).is_file()             # the file stays; its lock went
  assert locks.holder_if_locked(run_dir) is None
  proc = subprocess.run(_command(_experiment(tmp_path), out, "--no-wait"), env=ENV, cwd=CWD,
                        capture_output=True, text=True, timeout=300)
  assert proc.returncode == 0, proc.stderr
  assert_same_run(final_run(run_dir), alone[0])


def test_a_run_refuses_without_waiting_and_waits_otherwise(tmp_path):
  run_dir = tmp_path / "run"
  task = str(agents.load_task("taxi_fuel_flat_q").path)
  messages = []
  with locks.hold(run_dir, command="first"):
    with pytest.raises(locks.RunLocked, match=rf"run {run_dir} is held by pid {os.getpid()} "):
      runs.run(task, 0, 1000, run_dir, wait=False)
    refused = runner._run_on_ray(task, 0, 1000, str(run_dir), wait=False)
    assert isinstance(refused, runner._Refused) and "'first'" in refused
    # Another thread's open file is another lock holder: this one waits for it.
    thread = threading.Thread(target=lambda: messages.append(runs.run(task, 0, 1000, run_dir)))
    thread.start()
    time.sleep(3)
    assert thread.is_alive() and not runs.is_finished(run_dir)
  thread.join(timeout=120)
  assert messages and messages[0]["episodes"] == 1000
  assert json.loads((run_dir / locks.LOCK_FILE).read_text())["pid"] == os.getpid()


def test_ray_waits_for_a_held_run_and_refuses_with_no_wait(tmp_path, alone):
  pytest.importorskip("ray", reason="Ray is an optional extra: pip install 'hpg_mj[ray]'")
  experiment = runner.load_experiment(_experiment(tmp_path))
  out = tmp_path / "out"
  run_dir = out / "locked" / "taxi_fuel_hpg" / "seed0"
  holder = _holder_process(run_dir)
  told = []

  def on_wait(message):
    told.append(message)
    threading.Timer(2.0, holder.kill).start()      # the holder dies while Ray waits
  try:
    with pytest.raises(locks.RunLocked, match=rf"run {run_dir} is held by pid {holder.pid}"):
      runner.run_experiment(experiment, out, workers=2, executor="ray", wait=False)
    assert not (out / "locked" / "taxi_fuel_hpg" / "seed1").exists()   # nothing started
    results, _, _ = runner.run_experiment(experiment, out, workers=2, executor="ray",
                                          checkpoint_every=1000, on_wait=on_wait)
  finally:
    holder.kill()
    holder.wait()
  assert len(told) == 1 and "waiting for it" in told[0]
  # Ray gives the numbers the process pool gives (`alone`), runs and metrics.
  for seed in range(2):
    assert_same_run(final_run(out / "locked" / "taxi_fuel_hpg" / f"seed{seed}"), alone[seed])
  for a, b in zip(alone["metrics"], results["taxi_fuel_hpg"], strict=True):
    _same_metrics(a, b)
