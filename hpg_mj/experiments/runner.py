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

    OUT/<experiment>/<task>/seed<k>/record.npy     the per-episode record
    OUT/<experiment>/<task>/seed<k>/metrics.json   the task's metrics over the last 1,000
    OUT/<experiment>/<figure>.png, <figure>.csv    see `hpg_mj.experiments.figures`

A run whose metrics.json exists is finished and is skipped when the command is
run again. Runs go to a process pool; every run draws only from its own seeded
generator, so results do not depend on the number of workers.
"""
import concurrent.futures
import json
import os
import pathlib
import time

import numpy as np

from hpg_mj.experiments import kinds
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


def _run_one(task_path, seed, episodes, run_dir):
  """One (task, seed) run in a worker process; writes its record and metrics."""
  task = kinds.load_task(task_path)
  agent, record, wall = kinds.train(task, episodes=episodes, seed=seed)
  run_dir = pathlib.Path(run_dir)
  run_dir.mkdir(parents=True, exist_ok=True)
  tmp = run_dir / "record.npy.tmp"
  with open(tmp, "wb") as f:
    np.save(f, record)
  os.replace(tmp, run_dir / "record.npy")
  metrics = agent.metrics(record)
  metrics.update({"task": task.path.stem, "seed": seed, "episodes": episodes,
                  "wall_seconds": round(wall, 3)})
  tmp = run_dir / "metrics.json.tmp"
  tmp.write_text(json.dumps(metrics, indent=2) + "\n")
  os.replace(tmp, run_dir / "metrics.json")     # written last: the run is finished
  return metrics


def pending(experiment, out, quick=False):
  """The (task file, seed, episodes, run folder) of every unfinished run."""
  runs = experiment["quick_runs"] if quick else experiment["runs"]
  episodes = experiment["quick_episodes"] if quick else experiment["episodes"]
  root = pathlib.Path(out) / experiment["name"]
  jobs = []
  for task in experiment["task_files"]:
    for seed in range(runs):
      run_dir = root / task.path.stem / f"seed{seed}"
      if not (run_dir / "metrics.json").is_file():
        jobs.append((str(task.path), seed, episodes, str(run_dir)))
  return jobs


def run_experiment(experiment, out, quick=False, workers=None, progress=None):
  """Runs every unfinished (task, seed) of an experiment; returns {task: [metrics]}."""
  runs = experiment["quick_runs"] if quick else experiment["runs"]
  root = pathlib.Path(out) / experiment["name"]
  jobs = pending(experiment, out, quick)
  workers = workers or os.cpu_count() or 1
  start = time.perf_counter()
  if jobs:
    if workers == 1:
      for job in jobs:
        _run_one(*job)
        if progress:
          progress(job)
    else:
      with concurrent.futures.ProcessPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(_run_one, *job): job for job in jobs}
        for future in concurrent.futures.as_completed(futures):
          future.result()
          if progress:
            progress(futures[future])
  results = {}
  for task in experiment["task_files"]:
    results[task.path.stem] = [
        json.loads((root / task.path.stem / f"seed{seed}" / "metrics.json").read_text())
        for seed in range(runs)]
  return results, root, time.perf_counter() - start


def load_records(root, task_name, runs):
  return [np.load(pathlib.Path(root) / task_name / f"seed{seed}" / "record.npy",
                  allow_pickle=False) for seed in range(runs)]
