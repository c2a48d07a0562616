"""`hpg-mj reproduce reference`: where the flat deep RL that users bring
stands beside the paper's learners, as one sample-efficiency figure per world and
one "Reference scores" table.

The runs are those of the reference experiment files (tasks/experiments/
reference_*.toml), each measured greedily on the fixed 1,000 starts (SPEC section
7) at its `greedy_at` points and at its end (`runs`, greedy_curve). Made from
whatever runs have finished under OUT, so that it says what was run:

    OUT/reference/reference_ship.png, .csv   greedy gate pass rate and J against
                                             control steps trained (log axis)
    OUT/reference/reference_taxi.png, .csv   greedy return against primitive steps
    OUT/reference/table.md                   the "Reference scores" table
    OUT/reference/REPORT.md                  the table, the budgets run, the figures
    OUT/reference/runs.jsonl                 each finished run's metrics.json, a line
                                             each: all the figures and table need

Each curve and cell is the mean over runs with its 95% bootstrap interval
(`stats`); normalized scores are 0 for the random policy and 100 for the best
known (SPEC section 7.1, `bounds`).
"""
import json
import pathlib

import numpy as np

from hpg_mj.experiments import bounds
from hpg_mj.experiments import figures
from hpg_mj.experiments import runner
from hpg_mj.experiments import runs
from hpg_mj.experiments import stats

# Per world: its experiments (shipped names), the figure's panels (greedy metric,
# axis label) and the table's greedy scores, each also normalized.
WORLDS = {
    "ship": {"experiments": ("reference_ship_hierarchy", "reference_ship_option_critic",
                             "reference_ship_ppo", "reference_ship_sac",
                             "reference_ship_ppo_jax", "reference_ship_sac_jax"),
             "title": "Ship steering: greedy scores against control steps trained",
             "panels": (("gate_pass_rate", "gate pass rate, greedy"),
                        ("J", "J (MushroomRL rewards), greedy")),
             "scores": (("gate_pass_rate", "gate pass rate", 3), ("J", "J", 2)),
             "steps": ("control_steps", "control steps")},
    "taxi": {"experiments": ("reference_taxi_hierarchy", "reference_taxi_option_critic",
                             "reference_taxi", "reference_taxi_ppo_jax",
                             "reference_taxi_dqn_jax"),
             "title": "Taxi-fuel: greedy return against primitive steps trained",
             "panels": (("mean_return", "mean return, greedy"),),
             "scores": (("mean_return", "return", 3),),
             "steps": ("primitive_steps", "primitive steps")},
}
EXPERIMENTS = tuple(name for world in WORLDS.values() for name in world["experiments"])


def folder(out, quick=False):
  """Where the reference run writes under `out` (reference/, or reference_quick/)."""
  return pathlib.Path(out) / ("reference_quick" if quick else "reference")


def read_earlier(path):
  """{(task file stem, seed): metrics} of an earlier report's runs.jsonl (`write`)."""
  path = pathlib.Path(path)
  if not path.is_file():
    raise ValueError(f"--earlier {path}: no such file; give the runs.jsonl of an earlier "
                     "`hpg-mj reproduce reference` (for example figures/reference/runs.jsonl)")
  earlier = {}
  for number, line in enumerate(path.read_text().splitlines(), 1):
    if not line.strip():
      continue
    try:
      run = json.loads(line)
      key = (run.pop("task"), int(run["seed"]))
    except (ValueError, KeyError, TypeError) as error:
      raise ValueError(f"--earlier {path}, line {number}: not a run of runs.jsonl (a JSON "
                       f"object with its task and seed): {error}") from None
    earlier[key] = run
  return earlier


def collect(out, quick=False, names=None, earlier=None):
  """{world: [{"experiment", "task" (task file), "runs" (each finished run's
  metrics, by seed)}]} over the reference experiments (`names`: a subset) whose
  runs are under OUT; a learner with no finished run has an empty list. `earlier`
  (`read_earlier`): the metrics of an earlier report's runs, each taken for a seed of
  the experiment whose run is not finished under OUT (a run under OUT wins)."""
  found = {}
  earlier = earlier or {}
  for world, spec in WORLDS.items():
    for name in spec["experiments"]:
      if names is not None and name not in names:
        continue
      experiment = runner.load_experiment(name)
      root = runner.folder(experiment, out, quick)
      for task in experiment["task_files"]:
        done = []
        for seed in runner.seeds(experiment, quick):
          run = root / task.path.stem / f"seed{seed}"
          if runs.is_finished(run):
            done.append(runs.read_metrics(run))
          elif (task.path.stem, seed) in earlier:
            done.append(earlier[(task.path.stem, seed)])
        found.setdefault(world, []).append({"experiment": experiment, "task": task,
                                            "runs": done})
  return found


def _benchmark_task(task):
  """The benchmark task of SPEC 7.1 a task file acts on: its bounds' name."""
  env = task.section("environment")
  return "ship" if env["world"] == "ship" else ("taxi_fuel" if env.get("fuel") else "taxi")


def _budget(entry, quick):
  """What the learner's runs were: 'n of N runs (seeds a-b), E episodes each'."""
  from hpg_mj import agents
  experiment, done = entry["experiment"], entry["runs"]
  declared = experiment["quick_runs" if quick else "runs"]
  rows = agents.lookup(entry["task"].kind).record_steps
  unit = f"record rows of {rows:,} steps" if rows else "episodes"
  seeds = sorted(m["seed"] for m in done)
  which = f"seed {seeds[0]}" if len(seeds) == 1 else f"seeds {seeds[0]}-{seeds[-1]}"
  lengths = " or ".join(f"{n:,}" for n in sorted({m["episodes"] for m in done}))
  return f"{len(done)} of {declared} runs ({which}), {lengths} {unit} each"


def _cell(values, digits):
  return stats.format_summary(stats.summary(values), digits, iqm=False)


def table(world, entries, quick=False):
  """The world's "Reference scores" table (markdown lines): per learner, each
  greedy score raw and normalized with its 95% interval, the steps trained per
  run, the training wall-clock per run, the runs."""
  spec = WORLDS[world]
  steps_key, steps_name = spec["steps"]
  head = ["learner", "experiment"]
  for _, name, _ in spec["scores"]:
    head += [f"{name}, greedy", f"{name}, normalized"]
  head += [f"{steps_name} per run (M)", "wall-clock per run (s)", "runs"]
  lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
  for entry in entries:
    done = entry["runs"]
    cells = [entry["task"].name, f"`{entry['experiment']['name']}`"]
    bench = _benchmark_task(entry["task"])
    for key, _, digits in spec["scores"]:
      raw = [m["greedy"].get(key) for m in done]
      normalized = [bounds.normalized(bench, m["greedy"]).get(f"{key}_normalized")
                    for m in done]
      cells += [_cell([np.nan if v is None else v for v in raw], digits),
                _cell([np.nan if v is None else v for v in normalized], 1)]
    cells += [_cell([m[steps_key] / 1e6 for m in done], 3),
              _cell([m["wall_seconds"] for m in done], 1),
              _budget(entry, quick) if done else "**not run here**"]
    lines.append("| " + " | ".join(cells) + " |")
  return lines


def _bounds_line(world):
  published = bounds.bounds()["tasks"]
  name = "ship" if world == "ship" else "taxi_fuel"
  if name not in published:
    return "No bounds are published here (hpg_mj/benchmark_bounds.json is missing)."
  entry = published[name]
  return (f"Normalized: 0 = the random policy, 100 = the best known ({entry['best_is']}); on "
          f"the same fixed starts: " + "; ".join(
              f"{score} random {entry['random'][score]:.3f}, best {entry['best'][score]:.3f}"
              for score in entry["scores"]) + " (SPEC section 7.1).")


def _options_sections(out, experiments, quick, root):
  """The options figures (`figures.draw_options`) drawn by these experiments under
  OUT, copied beside the report, with what they show."""
  import shutil
  lines = []
  for name in experiments:
    experiment = runner.load_experiment(name)
    here = runner.folder(experiment, out, quick)
    for fig in experiment["figures"]:
      summary = here / f"{fig['name']}.json"
      if fig["kind"] != "options" or not summary.is_file():
        continue
      shutil.copyfile(here / f"{fig['name']}.png", root / f"{fig['name']}.png")
      lines += [f"### {fig['title']}", "", f"![{fig['title']}]({fig['name']}.png)", "",
                f"`{fig['name']}.png` (experiment `{name}`): each control step coloured by the "
                "option that chose it; a dot where an option was called, a cross where it "
                "ended.", "", *figures.options_lines(fig, json.loads(summary.read_text())), ""]
  return lines


def write(out, quick=False, earlier=None):
  """Draws the figures and writes table.md, REPORT.md and runs.jsonl under
  OUT/reference (OUT/reference_quick with `quick`) from the finished runs (and
  `earlier`'s, `collect`); returns REPORT.md's path."""
  root = folder(out, quick)
  root.mkdir(parents=True, exist_ok=True)
  found = collect(out, quick, earlier=earlier)
  lines = ["# reference: Reference scores for the methods people bring", "",
           "Each learner trained on held-out seeds (those its row names; never a tuning seed), then "
           "measured greedily (no exploration, no learning) on the fixed seeded set of "
           "1,000 starts of every report (SPEC section 7). Each cell: the mean over runs "
           "[95% bootstrap confidence interval of the mean]. Wall-clock: training seconds "
           "of one run on one core of the machine named under Provenance (compiling "
           "included, the greedy measures not). **The budgets below are what was run**; "
           "each experiment file (tasks/experiments/) says what budget a reference "
           "deserves and why this machine ran less.", ""]
  if quick:
    lines += ["**QUICK protocol** (`--quick`): fewer runs and steps, not for publication.", ""]
  tables, made = [], {}
  for world, entries in found.items():
    spec = WORLDS[world]
    title = "Ship steering" if world == "ship" else "Taxi-fuel"
    part = ["", *table(world, entries, quick), "", _bounds_line(world), "",
            "Each learner's tuning (its task file's `[tuning] result`, SPEC section 7):", "",
            *[f"- {e['task'].name}: {(e['task'].tuning or {}).get('result', 'no [tuning]')}"
              for e in entries], ""]
    tables += [f"### {title}", *part]
    lines += [f"## {title}", *part]
    drawn = [e for e in entries if e["runs"]]
    if drawn:
      optimal = drawn[0]["runs"][0].get("optimal_mean_return")
      figures.draw_greedy(root, f"reference_{world}", spec["title"], spec["panels"],
                          [e["task"] for e in drawn],
                          {e["task"].path.stem: e["runs"] for e in drawn}, optimal)
      lines += [f"![{title}](reference_{world}.png)", "",
                f"`reference_{world}.png`: {spec['title']} (log axis), each learner's "
                "mean over its runs with the 95% bootstrap band; the x of a point is the "
                "mean over runs of the steps trained by then.", ""]
    lines += _options_sections(out, spec["experiments"], quick, root)
    for e in entries:
      made[e["task"].path.stem] = e["runs"]
  table_md = ["## Reference scores", "",
              "Greedy on the fixed 1,000 starts after training, on held-out seeds; mean "
              "[95% bootstrap CI]; made by `hpg-mj reproduce reference` "
              "(figures/reference/REPORT.md gives the budgets and how they were run).", "",
              *tables]
  (root / "table.md").write_text("\n".join(table_md).rstrip() + "\n")
  lines += figures.provenance_lines({k: v for k, v in made.items() if v})
  (root / "REPORT.md").write_text("\n".join(lines) + "\n")
  write_runs(root / "runs.jsonl", made)
  return root / "REPORT.md"


def write_runs(path, made):
  """runs.jsonl: each run's metrics, a line each, with its task's name ({name: [metrics
  of each run]}); `read_earlier` reads it back."""
  with open(path, "w") as f:
    for task, metrics in made.items():
      for m in metrics:
        f.write(json.dumps({"task": task, **m}) + "\n")
