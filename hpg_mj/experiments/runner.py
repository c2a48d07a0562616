"""Experiments: several task files x several seeds, run in parallel, each run's
record stored as it finishes, figures drawn from the stored records.

An experiment file (tasks/experiments/*.toml):

```toml
[experiment]
name = "fig7_11"
description = "..."
tasks = ["ship_hybrid", "ship_flat_pg", "ship_actor_critic"]   # shipped names or paths
runs = 5
episodes = 50000
quick_runs = 2
quick_episodes = 5000
first_seed = 100           # optional (default 0): runs are seeds first_seed,
                           # first_seed + 1, ...; none may be a task's tuning seed
tuning = false             # optional: true allows tuning seeds (not for publication)
greedy_at = [100, 1000]    # optional: also measure each run greedily on the fixed
                           # starts after these many episodes (increasing, below
                           # episodes; a quick run keeps those below its own), and
                           # at its end: a "greedy_curve" figure's points

[[figure]]                 # one table per figure; see tasks/experiments/*.toml
name = "fig7"
kind = "curve"             # a metric per 1,000 episodes, mean over runs, 95% bootstrap band
metric = "gate_passes"     # figures.METRICS
x = "episodes"             # or "steps" (primitive or control steps)
title = "Gate passes per 1,000 episodes"
ylabel = "gate passes"
paper = "the hybrid ahead of both flat learners"   # what the paper states
paper_order = ["ship_hybrid", "ship_flat_pg"]      # optional: the paper's ranking,
# or paper_best = "ship_hybrid" (its best only; paper_tasks = [...] the learners
# the paper's statement covers, default all); better = "higher" or "lower"
# optional: paper_value = 4.0 (drawn in), reference = "optimal" (taxi: the exact optimum)

[[figure]]
name = "efficiency"
kind = "greedy_curve"      # a greedy metric at each greedy_at point against the
metric = "gate_pass_rate"  # control (primitive) steps trained, log axis; mean over
title = "..."              # runs, 95% bootstrap band (figures.GREEDY_METRICS)
ylabel = "gate pass rate, greedy"
paper = "..."

[[figure]]
name = "fig12"
kind = "trajectories"      # a trained hybrid's greedy episodes on the MuJoCo ship
                           # (kind = "options": an option-critic's learned options,
                           # `options_map`, with task, seed and starts)
task = "ship_hybrid"
seed = 100                 # whose final agent (one of the experiment's seeds)
starts = [[700.0, 700.0, 100.0, 3.65]]
video = true
title = "..."
paper = "..."
```

Layout of the output folder (one per experiment):

    OUT/<experiment>/<task>/seed<k>/               one run (OUT/<experiment>_quick/... with --quick) (`hpg_mj.experiments.runs`:
                                                   progress.csv, checkpoints, events.log,
                                                   record.npy, agent/, metrics.json)
    OUT/<experiment>/<figure>.png, <figure>.csv    see `hpg_mj.experiments.figures`
    OUT/<experiment>/REPORT.md

A run whose metrics.json exists is finished and is skipped when the command is
run again; an unfinished one resumes from its last checkpoint. Runs go to a
process pool (or to Ray); every run draws only from its own seeded generator,
so results do not depend on the executor or the number of workers. Each run
folder is locked while a process writes it (`hpg_mj.experiments.locks`): a
second command on the same folder waits for the runs another holds, or refuses.
"""
import concurrent.futures
import os
import pathlib
import sys
import time

import numpy as np

from hpg_mj import _stack
from hpg_mj import _paths
from hpg_mj import agents
from hpg_mj.experiments import locks
from hpg_mj.experiments import cores
from hpg_mj.experiments import runs
from hpg_mj import taskfile
from hpg_mj.learners import rng

POSITIVE = ("int_min", 1)
EXPERIMENT_SCHEMA = {"name": "str", "tasks": "str_list", "runs": POSITIVE, "episodes": POSITIVE}
# first_seed: the runs' first seed; tuning = true: an experiment on tuning seeds
# (for tuning or tests), whose reports say they are not for publication. Left out:
# description "", quick_runs 1, quick_episodes the episodes (`--quick`: one run of
# them), and no [[figure]]: one figure, the learning curve or the greedy scores
# (`default_figure`).
EXPERIMENT_OPTIONAL = {"description": "str", "quick_runs": POSITIVE, "quick_episodes": POSITIVE,
                       "first_seed": ("int_min", 0), "tuning": "bool",
                       "greedy_at": "int_list_any", "levels": "str_list"}
# levels = ["easy", "hard"]: each task file (a ladder task's, SPEC section 11) is run at
# each level, as `hpg-mj train --set environment.level=...` runs it, under the name
# "<file>_<level>"; the task file so made is written into the experiment's folder
# (OUT/<name>/tasks/), where its runs read it.

# [[figure]] tables (taskfile's types): every figure needs the common keys and
# those of its kind; the optional ones may be left out.
FIGURE_COMMON = {"name": "str", "kind": "str", "title": "str", "paper": "str"}
FIGURE_KINDS = {
    "curve": ({"metric": "str", "x": "str", "ylabel": "str"},
              {"paper_value": "float", "paper_order": "str_list", "paper_best": "str",
               "paper_tasks": "str_list", "better": "str", "reference": "str"}),
    "greedy_curve": ({"metric": "str", "ylabel": "str"}, {"reference": "str"}),
    "trajectories": ({"task": "str", "seed": ("int_min", 0),
                      "starts": ("float_lists", 4, "[x, y, heading in degrees, turning rate "
                                                   "in deg/s]"),
                      "video": "bool"},
                     {"width": POSITIVE, "height": POSITIVE, "quick_width": POSITIVE,
                      "quick_height": POSITIVE, "frame_every": POSITIVE,
                      "quick_frame_every": POSITIVE}),
    "options": ({"task": "str", "seed": ("int_min", 0),
                 "starts": ("float_lists", 4, "[x, y, heading in degrees, turning rate "
                                              "in deg/s]")}, {}),
}
# The agents each figure of a run's final agent can draw.
FIGURE_AGENTS = {"trajectories": ("ship_hybrid",), "options": ("ship_option_critic",)}


def default_figure(section, tasks):
  """The figure of an experiment file with no [[figure]]: the learning curve of gate
  passes (or, where a task's record has no passes, the mean return) per 1,000 episodes
  against episodes, where the runs (full and quick) have 1,000 episodes or more and
  every task records it (on the taxi with its exact optimum drawn in, and the report's
  primitive steps to 95% of it); else each task's greedy score at the runs' end (and at
  `greedy_at`), the world's first greedy metric (the ships' gate pass rate, the
  regatta's finish rate, the taxi's mean return)."""
  from hpg_mj.experiments import figures
  title = section["description"] or section["name"]
  if min(section["episodes"], section["quick_episodes"]) >= figures.BLOCK:
    for metric, label in (("gate_passes", "gate passes per 1,000 episodes"),
                          ("mean_return", "mean return per episode")):
      if all(figures.has_metric(t, metric) for t in tasks):
        fig = {"name": section["name"], "kind": "curve", "metric": metric,
               "x": "episodes", "title": title, "ylabel": label, "paper": "none"}
        if all(t.section("environment")["world"] == "taxi" for t in tasks):
          fig["reference"] = "optimal"        # the exact optimum, and the steps to 95% of it
        return fig
  world = tasks[0].section("environment")["world"]
  metric = figures.GREEDY_METRICS.get(world, ("mean_return",))[0]
  return {"name": section["name"], "kind": "greedy_curve", "metric": metric,
          "title": title, "ylabel": f"{metric}, greedy", "paper": "none"}


def _check_figures(path, section, tasks, figures_):
  from hpg_mj.experiments import figures
  if figures_ is None:
    figures_ = [default_figure(section, tasks)]
  if not isinstance(figures_, list) or not figures_:
    raise taskfile.TaskFileError(f"{path}: [[figure]] must be tables saying what is "
                                 f"plotted, got {figures_!r}")
  names = [t.path.stem for t in tasks]
  seen = set()
  checked = []
  for k, fig in enumerate(figures_):
    where = f"[[figure]] #{k + 1}"
    if not isinstance(fig, dict):
      raise taskfile.TaskFileError(f"{path}: {where} must be a table, got {fig!r}")
    kind = fig.get("kind")
    if kind not in FIGURE_KINDS:
      raise taskfile.TaskFileError(f"{path}: {where} kind = {kind!r}; allowed: "
                                   f"{sorted(FIGURE_KINDS)}")
    required, optional = FIGURE_KINDS[kind]
    fig = taskfile.check_table(path, where, fig, {**FIGURE_COMMON, **required}, optional)
    _paths.check_name(fig["name"], f"{path}: {where} name",      # OUT/<experiment>/<name>.png
                      taskfile.TaskFileError)
    checked.append(fig)
    where = f"[[figure]] {fig['name']!r}"
    if fig["name"] in seen:
      raise taskfile.TaskFileError(f"{path}: {where} is named twice")
    seen.add(fig["name"])
    named = fig.get("paper_order", []) + fig.get("paper_tasks", []) + [
        fig[k] for k in ("task", "paper_best") if k in fig]
    for task in named:
      if task not in names:
        raise taskfile.TaskFileError(f"{path}: {where} names task {task!r}, which is not in "
                                     f"[experiment] tasks {names}")
    if kind in ("curve", "greedy_curve"):
      problem = (figures.check_curve if kind == "curve" else figures.check_greedy_curve)(
          fig, tasks)
      if problem:
        raise taskfile.TaskFileError(f"{path}: {where} {problem}")
    else:
      allowed = FIGURE_AGENTS[kind]
      if tasks[names.index(fig["task"])].kind not in allowed:
        raise taskfile.TaskFileError(f"{path}: {where} ({kind}) draws a run of "
                                     f"{' or '.join(allowed)}; {fig['task']!r} is not one")
      first = section.get("first_seed", 0)
      last = first + min(section["runs"], section["quick_runs"]) - 1
      if not first <= fig["seed"] <= last:
        raise taskfile.TaskFileError(f"{path}: {where} seed = {fig['seed']}, but the "
                                     f"experiment's runs (full and quick) have seeds "
                                     f"{first}..{last}")
  return checked


def load_experiment(path):
  """Reads an experiment file and checks every task file and figure it names,
  before anything runs."""
  import tomllib
  path = pathlib.Path(path)
  if not path.is_file():
    shipped = shipped_experiments()
    if str(path) in shipped:
      path = shipped[str(path)]
    else:
      raise taskfile.TaskFileError(f"{path}: no such experiment file; shipped: {sorted(shipped)}")
  try:
    data = tomllib.loads(_paths.read_text(path, "experiment file", taskfile.TaskFileError))
  except tomllib.TOMLDecodeError as err:
    raise taskfile.TaskFileError(f"{path}: not valid TOML: {err}") from None
  if "experiment" not in data or set(data) - {"experiment", "figure"}:
    raise taskfile.TaskFileError(f"{path}: needs one [experiment] section and, if it says "
                                 f"what is plotted, [[figure]] tables; got {sorted(data)}")
  section = taskfile.check_table(path, "[experiment]", data["experiment"], EXPERIMENT_SCHEMA,
                                 EXPERIMENT_OPTIONAL)
  section.setdefault("description", "")
  section.setdefault("quick_runs", 1)
  section.setdefault("quick_episodes", section["episodes"])
  section.setdefault("first_seed", 0)
  section.setdefault("tuning", False)
  points = section.setdefault("greedy_at", [])
  if points and (points[0] < 1 or any(b <= a for a, b in zip(points, points[1:]))
                 or points[-1] >= section["episodes"]):
    raise taskfile.TaskFileError(f"{path}: [experiment] greedy_at = {points}; allowed: "
                                 f"increasing episode counts in 1..{section['episodes'] - 1} "
                                 f"(the end of each run is a point already)")
  _paths.check_name(section["name"], f"{path}: [experiment] name",   # OUT/<name>/
                    taskfile.TaskFileError)
  last_seed = section["first_seed"] + max(section["runs"], section["quick_runs"]) - 1
  if last_seed > rng.MAX_SEED:
    raise taskfile.TaskFileError(f"{path}: [experiment] first_seed = {section['first_seed']} "
                                 f"gives runs seeds up to {last_seed}; allowed: seeds in "
                                 f"0..{rng.MAX_SEED}")
  tasks = [agents.load_task(t) for t in section["tasks"]]   # refused here, before any run
  if "levels" in section:
    tasks = _at_levels(path, tasks, section["levels"])
  for t in tasks:                                   # OUT/<experiment>/<task file's name>/
    _paths.check_name(t.path.stem, f"{path}: [experiment] tasks: the name of {t.path}",
                      taskfile.TaskFileError)
  # SPEC section 7: published numbers never come from the seeds a task was tuned on.
  first = section["first_seed"]
  used = set(range(first, first + max(section["runs"], section["quick_runs"])))
  for t in tasks:
    tuned = sorted(used & set(t.tuning_seeds))
    if tuned and not section["tuning"]:
      raise taskfile.TaskFileError(
          f"{path}: [experiment] runs seeds {first}..{max(used)}, but {t.path.name} was tuned "
          f"on seeds {tuned} ([protocol] tuning_seeds); set first_seed past them (e.g. "
          f"{max(t.tuning_seeds) + 1}) so that no reported run uses a tuning seed, or "
          f"declare tuning = true (its reports are then marked not for publication)")
  worlds = sorted({t.section("environment")["world"] for t in tasks})
  if len(worlds) > 1:
    raise taskfile.TaskFileError(f"{path}: [experiment] tasks compare one world, ship or "
                                 f"taxi; these mix {worlds}")
  stems = [t.path.stem for t in tasks]
  if len(set(stems)) < len(stems):
    raise taskfile.TaskFileError(f"{path}: [experiment] tasks names a task twice: {stems}")
  figures_ = _check_figures(path, section, tasks, data.get("figure"))
  from hpg_mj.experiments import figures
  short = [k for k in ("episodes", "quick_episodes") if section[k] < figures.BLOCK]
  if short and any(fig["kind"] == "curve" for fig in figures_):
    raise taskfile.TaskFileError(f"{path}: [experiment] {short[0]} = {section[short[0]]}; a "
                                 f"curve plots one point per {figures.BLOCK:,} episodes, so "
                                 f"allowed: >= {figures.BLOCK}")
  return dict(section, path=path, task_files=tasks, figures=figures_)


def _at_levels(path, tasks, levels):
  """Each task file at each of `levels` (`levels` above): its [environment] level set,
  named "<file>_<level>" (its `path`, the name of the file `task_path` writes)."""
  import dataclasses
  from hpg_mj.worlds import ship_ladder
  if not levels or len(set(levels)) < len(levels):
    raise taskfile.TaskFileError(f"{path}: [experiment] levels = {levels}; allowed: one or "
                                 "more levels, each once")
  for level in levels:          # here, not as the task file refuses a --set (naming it)
    if level not in ship_ladder.LEVELS:
      raise taskfile.TaskFileError(f"{path}: [experiment] levels: {level!r} is not a level; "
                                   f"allowed: {list(ship_ladder.LEVELS)}")
  out = []
  for task in tasks:
    if "level" not in task.section("environment"):
      raise taskfile.TaskFileError(f"{path}: [experiment] levels: {task.path.name} has no "
                                   "[environment] level (only the ladder's tasks have levels)")
    for level in levels:
      at = agents.load_task(task.path, [f"environment.level={level}"])
      out.append(dataclasses.replace(at, path=pathlib.Path(f"{task.path.stem}_{level}.toml"),
                                     label=f"{at.name}, {level}"))
  return out


def task_path(experiment, task, root):
  """The file a run of `task` reads: the task file itself, or, for a task at a level
  (`levels`), the copy under ROOT/tasks/ (written by `run_experiment`)."""
  if "levels" not in experiment:
    return str(task.path)
  return str(pathlib.Path(root) / "tasks" / task.path.name)


def _write_level_files(experiment, root):
  """The task files at their levels (`levels`), under ROOT/tasks/; one already there
  with other text is refused (another experiment's, or changed since)."""
  if "levels" not in experiment:
    return
  (pathlib.Path(root) / "tasks").mkdir(parents=True, exist_ok=True)
  for task in experiment["task_files"]:
    target = pathlib.Path(task_path(experiment, task, root))
    if target.is_file() and target.read_text() != task.text:
      raise ValueError(f"{target} holds another text than {experiment['path'].name} makes "
                       "now (the task file changed since its runs began?); use another --out")
    if not target.is_file():
      target.write_text(task.text)


def shipped_experiments():
  """The shipped experiment files: name -> path, by name."""
  return {p.stem: p for p in sorted(
      (p for folder in agents.shipped_tasks_dirs() for p in (folder / "experiments").glob("*.toml")),
      key=lambda p: p.stem)}


def pending(experiment, out, quick=False):
  """The (task file, seed, episodes, run folder) of every unfinished run."""
  return [job for job in jobs(experiment, out, quick) if not runs.is_finished(job[3])]


def folder(experiment, out, quick=False):
  """The experiment's output folder: OUT/<name>, or OUT/<name>_quick for --quick, so
  that quick runs never stand in for full ones."""
  return pathlib.Path(out) / (experiment["name"] + ("_quick" if quick else ""))


def seeds(experiment, quick=False):
  """The seeds of the experiment's runs: first_seed onwards, one per run."""
  n_runs = experiment["quick_runs"] if quick else experiment["runs"]
  first = experiment.get("first_seed", 0)
  return list(range(first, first + n_runs))


def jobs(experiment, out, quick=False):
  """The (task file, seed, episodes, run folder) of every run of the experiment."""
  episodes = experiment["quick_episodes"] if quick else experiment["episodes"]
  root = folder(experiment, out, quick)
  # Seed by seed, so that the first runs the workers pick up are of different tasks
  # and compile (numba, cached for the later runs) different code at the same time.
  return [(task_path(experiment, task, root), seed, episodes,
           str(root / task.path.stem / f"seed{seed}"))
          for seed in seeds(experiment, quick) for task in experiment["task_files"]]


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


def _run_processes(todo, workers, options, poll, on_finished):
  if workers == 1:
    for job in todo:
      runs.run(*job, **options)
      on_finished(job)
      poll()
    return
  pool = concurrent.futures.ProcessPoolExecutor(max_workers=workers)
  try:
    futures = {pool.submit(_stack.roomy, runs.run, *job, **options): job for job in todo}
    waiting = set(futures)
    while waiting:
      finished, waiting = concurrent.futures.wait(
          waiting, timeout=0.5, return_when=concurrent.futures.FIRST_COMPLETED)
      for future in finished:
        future.result()
        on_finished(futures[future])
      poll()
  except BaseException:
    # Interrupted, or a run failed: stop the other runs now rather than let them
    # finish; each resumes from its last checkpoint when the command is run again.
    for process in list(getattr(pool, "_processes", {}).values()):
      process.terminate()
    pool.shutdown(wait=False, cancel_futures=True)
    raise
  pool.shutdown()


def _run_on_ray(*job, **options):
  """`runs.run` on a Ray worker; a refused run comes back as its message, so that
  the driver raises it as `locks.RunLocked`, not as a Ray task error."""
  try:
    return _stack.roomy(runs.run, *job, **options)
  except locks.RunLocked as err:
    return _Refused(str(err))


class _Refused(str):
  pass


def _run_ray(todo, workers, options, poll, on_finished, address):
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
    try:
      ray.init(include_dashboard=False, log_to_driver=False, logging_level="ERROR", **kwargs)
    except ConnectionError as err:
      if not address or os.environ.get("RAY_AUTH_MODE"):
        raise
      # Ray 2.60: `ray start --head` turns token authentication on where a token exists
      # (~/.ray/auth_token, which a local ray.init() writes), but a process joining
      # with an explicit address turns it on only if told (docs/experiments.md).
      raise ConnectionError(f"--address {address}: {err}; a cluster with token "
                            "authentication refuses a process that joins without "
                            "RAY_AUTH_MODE=token in its environment (and the cluster's token "
                            "in ~/.ray/auth_token or RAY_AUTH_TOKEN)") from None
  try:
    remote = ray.remote(num_cpus=1)(_run_on_ray)
    refs = {remote.remote(*job, **options): job for job in todo}
    waiting = list(refs)
    while waiting:
      finished, waiting = ray.wait(waiting, num_returns=1, timeout=0.5)
      for ref in finished:
        if isinstance(result := ray.get(ref), _Refused):
          raise locks.RunLocked(str(result))
        on_finished(refs[ref])
      poll()
  finally:
    if started:
      ray.shutdown()


def run_experiment(experiment, out, quick=False, workers=None, progress=None, on_finished=None,
                   executor="process", address=None, checkpoint_every=runs.CHECKPOINT_EVERY,
                   wait=True, command=None, on_wait=None):
  """Runs every unfinished (task, seed) of an experiment; returns
  ({task: [metrics of each seed]}, experiment folder, wall seconds).

  A run that another process holds (`locks`) is waited for, `on_wait(message)`
  told (default: stderr); with `wait=False` the experiment is refused, before any
  run starts, with `locks.RunLocked` naming the run and its holder. `command`:
  the command line the runs' lock files name (default: this process's).

  `progress(episodes done, total episodes, {task: current figure})` is called
  about twice a second (the figure: gate passes or return over the latest 1,000
  episodes of the task's unfinished runs, averaged over them); `on_finished(job)` when a run finishes.
  """
  if executor not in EXECUTORS:
    raise ValueError(f"unknown executor {executor!r}; valid executors: {list(EXECUTORS)}")
  if workers is not None and workers < 1:
    raise ValueError(f"workers must be a positive number of processes, got {workers}")
  if checkpoint_every < 1:
    raise ValueError(f"checkpoint_every must be a positive number of episodes, got "
                     f"{checkpoint_every}")
  root = folder(experiment, out, quick)
  all_jobs = jobs(experiment, out, quick)
  for job in all_jobs:             # a finished run of another length is not this one
    if runs.is_finished(job[3]):
      done = runs.read_metrics(job[3])["episodes"]
      if done != job[2]:
        raise ValueError(f"{job[3]} holds a finished run of {done} episodes, but "
                         f"{experiment['path'].name} asks for {job[2]}; use another --out")
  todo = [job for job in all_jobs if not runs.is_finished(job[3])]
  if todo:
    _write_level_files(experiment, root)
  on_wait = on_wait or (lambda message: print(message, file=sys.stderr, flush=True))
  for job in todo:
    holder = locks.holder_if_locked(pathlib.Path(job[3]))
    if holder is not None and not wait:
      raise locks.RunLocked(f"run {job[3]} is held by {holder}; nothing was started (wait for "
                            f"that command to finish, or run again without --no-wait to wait "
                            f"for it)")
    if holder is not None and executor == "ray":     # a Ray worker's stderr is not shown
      on_wait(f"run {job[3]} is held by {holder}; waiting for it")
  episodes = experiment["quick_episodes"] if quick else experiment["episodes"]
  options = {"checkpoint_every": checkpoint_every, "wait": wait,
             "command": command or locks.command_line(),
             "greedy_at": tuple(p for p in experiment.get("greedy_at", ()) if p < episodes)}
  # never more processes than runs to do, nor (without a cluster) than cores here
  workers = cores.pool_size(workers, len(todo), address if executor == "ray" else None)
  poll = _Poller(all_jobs, progress)
  on_finished = on_finished or (lambda job: None)
  start = time.perf_counter()
  if todo:
    if executor == "ray":
      _run_ray(todo, workers, options, poll, on_finished, address)
    else:
      _run_processes(todo, workers, options, poll, on_finished)
  results = {}
  for task in experiment["task_files"]:
    results[task.path.stem] = [runs.read_metrics(job[3]) for job in all_jobs
                               if job[0] == task_path(experiment, task, root)]
  return results, root, time.perf_counter() - start


def load_records(root, task_name, runs, name="record"):
  """The stored records (`name`: "record", or "greedy" for the greedy episodes) of
  a task's runs: `runs` is a list of seeds, or a count (seeds 0..runs-1)."""
  runs = range(runs) if isinstance(runs, int) else runs
  return [np.load(pathlib.Path(root) / task_name / f"seed{seed}" / f"{name}.npy",
                  allow_pickle=False) for seed in runs]
