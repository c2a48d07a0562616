"""Experiments: several task files x several seeds, run in parallel, each run's
record stored as it finishes, figures drawn from the stored records.

An experiment file (tasks/experiments/*.toml):

    [experiment]
    name = "fig7_11"
    description = "..."
    tasks = ["ship_hybrid", "ship_flat_pg", "ship_actor_critic"]   # shipped names or paths
    runs = 5
    episodes = 50000
    quick_runs = 2
    quick_episodes = 5000

Layout of the output folder (one per experiment):

    OUT/<experiment>/<task>/seed<k>/               one run (`hpg_mj.experiments.runs`:
                                                   progress.csv, checkpoints, events.log,
                                                   record.npy, agent/, metrics.json)
    OUT/<experiment>/<figure>.png, <figure>.csv    see `hpg_mj.experiments.figures`
    OUT/<experiment>/REPORT.md

A run whose metrics.json exists is finished and is skipped when the command is
run again; an unfinished one resumes from its last checkpoint. Runs go to a
process pool (or to Ray); every run draws only from its own seeded generator,
so results do not depend on the executor or the number of workers.
"""
import concurrent.futures
import json
import os
import pathlib
import time

import numpy as np

from hpg_mj.experiments import kinds
from hpg_mj.experiments import runs
from hpg_mj.experiments import taskfile

EXPERIMENT_SCHEMA = {"experiment": {"name": "str", "description": "str", "tasks": "str_list",
                                    "runs": "int", "episodes": "int", "quick_runs": "int",
                                    "quick_episodes": "int"}}


def load_experiment(path):
  """Reads an experiment file and checks every task file it names, before anything runs."""
  import tomllib
  path = pathlib.Path(path)
  if not path.is_file():
    shipped = shipped_experiments()
    if str(path) in shipped:
      path = shipped[str(path)]
    else:
      raise taskfile.TaskFileError(f"{path}: no such experiment file; shipped: {sorted(shipped)}")
  try:
    data = tomllib.loads(path.read_text())
  except tomllib.TOMLDecodeError as err:
    raise taskfile.TaskFileError(f"{path}: not valid TOML: {err}") from None
  if set(data) != {"experiment"}:
    raise taskfile.TaskFileError(f"{path}: needs exactly one section [experiment], got "
                                 f"{sorted(data)}")
  section = data["experiment"]
  keys = EXPERIMENT_SCHEMA["experiment"]
  unknown = set(section) - set(keys)
  if unknown:
    raise taskfile.TaskFileError(f"{path}: [experiment] unknown key(s) {sorted(unknown)}; "
                                 f"allowed: {sorted(keys)}")
  for key, kind in keys.items():
    if key not in section:
      raise taskfile.TaskFileError(f"{path}: [experiment] {key} is missing")
    value = section[key]
    if kind == "str_list":
      ok = isinstance(value, list) and value and all(isinstance(v, str) for v in value)
    elif kind == "int":
      ok = isinstance(value, int) and not isinstance(value, bool) and value >= 1
    else:
      ok = isinstance(value, str)
    if not ok:
      wanted = {"str_list": "a non-empty list of task names", "int": "a positive integer",
                "str": "a string"}[kind]
      raise taskfile.TaskFileError(f"{path}: [experiment] {key} must be {wanted}, got {value!r}")
  tasks = [kinds.load_task(t) for t in section["tasks"]]   # refused here, before any run
  worlds = sorted({t.section("environment")["world"] for t in tasks})
  if len(worlds) > 1:
    raise taskfile.TaskFileError(f"{path}: [experiment] tasks compare one world, ship or "
                                 f"taxi; these mix {worlds}")
  return dict(section, path=path, task_files=tasks)


def shipped_experiments():
  return {p.stem: p for p in sorted(
      (p for folder in kinds.shipped_tasks_dirs() for p in (folder / "experiments").glob("*.toml")),
      key=lambda p: p.stem)}


def pending(experiment, out, quick=False):
  """The (task file, seed, episodes, run folder) of every unfinished run."""
  return [job for job in jobs(experiment, out, quick) if not runs.is_finished(job[3])]


def jobs(experiment, out, quick=False):
  """The (task file, seed, episodes, run folder) of every run of the experiment."""
  n_runs = experiment["quick_runs"] if quick else experiment["runs"]
  episodes = experiment["quick_episodes"] if quick else experiment["episodes"]
  root = pathlib.Path(out) / experiment["name"]
  return [(str(task.path), seed, episodes, str(root / task.path.stem / f"seed{seed}"))
          for task in experiment["task_files"] for seed in range(n_runs)]


class _Poller:
  """Progress over all runs of an experiment, read from their progress.csv files
  (the runs may be in other processes, or on Ray workers sharing the folder)."""

  def __init__(self, all_jobs, callback):
    self.jobs = all_jobs
    self.callback = callback
    self.total = sum(job[2] for job in all_jobs)

  def __call__(self):
    if self.callback is None:
      return
    done, figures = 0, {}
    for job in self.jobs:
      if runs.is_finished(job[3]):
        done += job[2]
        continue
      episodes, figure = runs.read_progress(job[3])
      done += min(episodes, job[2])
      if figure is not None:
        figures.setdefault(pathlib.Path(job[0]).stem, []).append(figure)
    self.callback(done, self.total, {task: float(np.mean(v)) for task, v in figures.items()})


EXECUTORS = ("process", "ray")


def _run_processes(todo, workers, checkpoint_every, poll, on_finished):
  if workers == 1:
    for job in todo:
      runs.run(*job, checkpoint_every=checkpoint_every)
      on_finished(job)
      poll()
    return
  with concurrent.futures.ProcessPoolExecutor(max_workers=workers) as pool:
    futures = {pool.submit(runs.run, *job, checkpoint_every=checkpoint_every): job for job in todo}
    waiting = set(futures)
    while waiting:
      finished, waiting = concurrent.futures.wait(
          waiting, timeout=0.5, return_when=concurrent.futures.FIRST_COMPLETED)
      for future in finished:
        future.result()
        on_finished(futures[future])
      poll()


def _run_ray(todo, workers, checkpoint_every, poll, on_finished, address):
  """Runs on a Ray cluster (`address`), or a local Ray instance of `workers` CPUs.
  Every worker writes into the same output folder: on a cluster of several
  machines it must be a shared file system, and hpg_mj installed on each."""
  try:
    import ray
  except ImportError:
    raise RuntimeError("--executor ray needs Ray: pip install 'hpg_mj[ray]'") from None
  started = not ray.is_initialized()
  if started:
    kwargs = {"address": address} if address else {"num_cpus": workers}
    ray.init(include_dashboard=False, log_to_driver=False, logging_level="ERROR", **kwargs)
  try:
    remote = ray.remote(num_cpus=1)(runs.run)
    refs = {remote.remote(*job, checkpoint_every=checkpoint_every): job for job in todo}
    waiting = list(refs)
    while waiting:
      finished, waiting = ray.wait(waiting, num_returns=1, timeout=0.5)
      for ref in finished:
        ray.get(ref)
        on_finished(refs[ref])
      poll()
  finally:
    if started:
      ray.shutdown()


def run_experiment(experiment, out, quick=False, workers=None, progress=None, on_finished=None,
                   executor="process", address=None, checkpoint_every=runs.CHECKPOINT_EVERY):
  """Runs every unfinished (task, seed) of an experiment; returns
  ({task: [metrics of each seed]}, experiment folder, wall seconds).

  `progress(episodes done, total episodes, {task: current figure})` is called
  about twice a second (the figure: gate passes or return over the latest 1,000
  episodes of the task's unfinished runs, averaged over them); `on_finished(job)` when a run finishes.
  """
  if executor not in EXECUTORS:
    raise ValueError(f"unknown executor {executor!r}; valid executors: {list(EXECUTORS)}")
  root = pathlib.Path(out) / experiment["name"]
  all_jobs = jobs(experiment, out, quick)
  todo = [job for job in all_jobs if not runs.is_finished(job[3])]
  workers = workers or os.cpu_count() or 1
  poll = _Poller(all_jobs, progress)
  on_finished = on_finished or (lambda job: None)
  start = time.perf_counter()
  if todo:
    if executor == "ray":
      _run_ray(todo, workers, checkpoint_every, poll, on_finished, address)
    else:
      _run_processes(todo, workers, checkpoint_every, poll, on_finished)
  results = {}
  for task in experiment["task_files"]:
    results[task.path.stem] = [json.loads((pathlib.Path(job[3]) / "metrics.json").read_text())
                               for job in all_jobs if job[0] == str(task.path)]
  return results, root, time.perf_counter() - start


def load_records(root, task_name, runs):
  return [np.load(pathlib.Path(root) / task_name / f"seed{seed}" / "record.npy",
                  allow_pickle=False) for seed in range(runs)]
