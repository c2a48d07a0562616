"""A task file's tuning (SPEC section 7) as resumable runs of `hpg-mj run`: writes,
into OUT, one task file per configuration `hpg-mj tune` would try (the same
`[tuning]` budget and draw, `hpg_mj.experiments.tuning.candidates`) and an experiment
file running each on the task's tuning seeds for `[tuning] episodes`; then

    nice -n 19 hpg-mj run OUT/tuning_<task>.toml --out OUT/runs --workers 1

trains them with checkpoints (a killed command resumes when run again), and

    python scripts/tuning_runs.py --summary OUT/runs/tuning_<task>

prints each configuration's mean `[tuning] score` over the seeds finished so far;
with `--task NAME --json FILE` it also writes the tuning's record (each
configuration's changes, its runs' scores and greedy gate rates, their mean), the
form of figures/tuning/*.json.
For long learners such as the SB3 reference agents (`hpg-mj tune` keeps its runs
in memory, so a 10 M-step tuning could not survive a restart). `--seeds N` runs
the first N of the task's tuning seeds only (the same N for every learner compared,
so that their tuning budgets stay equal); the experiment file says so.

    python scripts/tuning_runs.py ship_ppo taxi_fuel_dqn --out runs/tuning
"""
import argparse
import json
import pathlib
import re
import sys

import numpy as np

from hpg_mj import agents
from hpg_mj import taskfile
from hpg_mj.experiments import tuning

# Greedy, at the runs' end: the taxi's and the regatta's mean return, every other ship
# task's J (the ladder's among them).
FIGURE_METRICS = {"taxi": "mean_return", "ship_regatta": "mean_return"}


def with_changes(text, changes, path):
  """The task file's text with `changes` ({section: {key: value}}) written in."""
  for section, keys in changes.items():
    match = re.search(rf"^\[{re.escape(section)}\][^\n]*\n(.*?)(?=^\[|\Z)", text, re.M | re.S)
    if match is None:
      raise ValueError(f"{path}: has no [{section}] section to tune")
    body = match.group(1)
    for key, value in keys.items():
      body, n = re.subn(rf"^{re.escape(key)}\s*=.*$", f"{key} = {value!r}  # tuning candidate",
                        body, count=1, flags=re.M)
      if n != 1:
        raise ValueError(f"{path}: [{section}] has no line {key} = ...")
    text = text[:match.start(1)] + body + text[match.end(1):]
  return text


def write(name, out, n_seeds=None):
  """Writes the task's configurations and their experiment file into `out`; runs
  the first `n_seeds` tuning seeds (default all)."""
  task = agents.load_task(name)
  out = pathlib.Path(out).resolve()
  out.mkdir(parents=True, exist_ok=True)
  text = task.path.read_text()
  paths = []
  for k, changes in enumerate(tuning.candidates(task, task.tuning["budget"])):
    path = out / f"{task.path.stem}_tune{k}.toml"
    variant = re.sub(r"^\[tuning\]", f"# candidate {k}: {tuning.describe(changes)}\n[tuning]",
                     with_changes(text, changes, task.path), count=1, flags=re.M)
    taskfile.loads(variant, path, agents._Registry)    # refused here if malformed
    path.write_text(variant)
    paths.append(path)
  seeds = sorted(task.tuning_seeds)
  if seeds != list(range(seeds[0], seeds[0] + len(seeds))):
    raise ValueError(f"{task.path}: tuning seeds {seeds} are not consecutive")
  if n_seeds is not None:
    if not 1 <= n_seeds <= len(seeds):
      raise ValueError(f"--seeds {n_seeds}: {task.path} has {len(seeds)} tuning seeds; "
                       f"allowed: 1..{len(seeds)}")
    seeds = seeds[:n_seeds]
  world = task.section("environment")["world"]
  experiment = out / f"tuning_{task.path.stem}.toml"
  experiment.write_text(f'''# The tuning of {task.path.name} ({len(paths)} configurations x seeds
# {seeds[0]}-{seeds[-1]}), written by scripts/tuning_runs.py. Not for publication.
[experiment]
name = "tuning_{task.path.stem}"
description = "tuning of {task.path.stem}"
tasks = {json.dumps([str(p) for p in paths])}
runs = {len(seeds)}
episodes = {task.tuning["episodes"]}
quick_runs = 1
quick_episodes = {task.tuning["episodes"]}
first_seed = {seeds[0]}
tuning = true

[[figure]]
name = "tuning_{task.path.stem}"
kind = "greedy_curve"
metric = "{FIGURE_METRICS.get(world, 'J')}"
title = "tuning of {task.path.stem}"
ylabel = "{FIGURE_METRICS.get(world, 'J')}, greedy"
paper = "none: tuning"
''')
  return experiment


def summary(folder):
  folder = pathlib.Path(folder)
  for task_dir in sorted(p for p in folder.iterdir() if p.is_dir()):
    scores, score_name, none = [], None, 0
    for metrics in sorted(task_dir.glob("seed*/metrics.json")):
      data = json.loads(metrics.read_text())
      score_name = score_name or _score_name(data)
      if data[score_name] is None:       # no episode ended in the run's metric window
        none += 1
      else:
        scores.append(data[score_name])
    mean = f"{np.mean(scores):.4g}" if scores else "-"
    print(f"{task_dir.name}: {score_name or 'score'} mean {mean} over {len(scores)} seeds"
          + (f" ({none} more with none: no episode ended in its window)" if none else ""))


# The greedy success rate a record keeps beside the scores: the gate's, the regatta's
# course (the taxi's greedy metrics have neither: none is kept).
SUCCESS = ("gate_pass_rate", "finish_rate")


def record(name, folder, source):
  """The tuning's record of task `name` from its runs in `folder` (a `--summary` folder):
  {task, budget, episodes, seeds, score, better, source, results: [{changes, scores,
  mean, greedy_gate_pass_rate or greedy_finish_rate}]}, scores to 4 decimals (a run with none: null, left out
  of the mean), in the order of `tuning.candidates`."""
  task = agents.load_task(name)
  folder = pathlib.Path(folder)
  results, seeds = [], set()
  for k, changes in enumerate(tuning.candidates(task, task.tuning["budget"])):
    runs = sorted((folder / f"{task.path.stem}_tune{k}").glob("seed*/metrics.json"),
                  key=lambda p: int(p.parent.name[4:]))
    if not runs:
      raise ValueError(f"{folder}: no finished run of configuration {k} ({task.path.stem}_tune{k})")
    data = [json.loads(p.read_text()) for p in runs]
    seeds.update(int(p.parent.name[4:]) for p in runs)
    score = task.tuning["score"]
    scores = [None if d[score] is None else round(d[score], 4) for d in data]
    kept = [v for v in scores if v is not None]
    greedy = [d.get("greedy", {}) for d in data]
    success = next((k for k in SUCCESS if any(k in g for g in greedy)), None)
    results.append({"changes": changes, "scores": scores,
                    "mean": round(float(np.mean(kept)), 5) if kept else None,
                    **({f"greedy_{success}": [g.get(success) for g in greedy]}
                       if success else {})})
  return {"task": task.path.stem, "budget": task.tuning["budget"],
          "episodes": task.tuning["episodes"], "seeds": sorted(seeds),
          "score": task.tuning["score"], "better": task.tuning["better"], "source": source,
          "results": results}


def _score_name(metrics):
  """The SB3 task files' [tuning] score: the ship's J, the taxi's mean return."""
  return "J" if "J" in metrics else "mean_return"


def main(argv=None):
  parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
  parser.add_argument("tasks", nargs="*", help="task files or shipped names")
  parser.add_argument("--out", default="runs/tuning")
  parser.add_argument("--summary", help="a tuning experiment's output folder")
  parser.add_argument("--task", help="with --summary and --json: the tuned task file")
  parser.add_argument("--json", help="with --summary and --task: write the tuning's record here")
  parser.add_argument("--source", default="scripts/tuning_runs.py, then hpg-mj run",
                      help="with --json: how the runs were made, as the record says it")
  parser.add_argument("--seeds", type=int, default=None,
                      help="run the first N tuning seeds only (default: all)")
  args = parser.parse_args(argv)
  if args.summary:
    summary(args.summary)
    if args.json:
      if not args.task:
        parser.error("--json needs --task (the tuned task file)")
      out = pathlib.Path(args.json)
      out.write_text(json.dumps(record(args.task, args.summary, args.source), indent=1) + "\n")
      print(f"wrote {out}")
    return 0
  for name in args.tasks:
    print(write(name, args.out, args.seeds))
  return 0


if __name__ == "__main__":
  sys.exit(main())
