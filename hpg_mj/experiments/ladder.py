"""`hpg-mj reproduce ladder`: the task ladder's reference table (SPEC section 11), every
reference learner on every task and level, normalized against the task's bounds, and
whether each level leaves headroom.

The runs are those of the ladder's experiment files (tasks/experiments/ladder_*.toml:
each learner's task file at every level, `levels`), each measured greedily at its end
on the level's fixed 1,000 starts (SPEC section 7). Made from whatever runs have
finished under OUT, so that it says what was run:

    OUT/ladder/ladder.png, .csv   per task, the normalized score at each level, a bar
                                  per learner with its 95% interval
    OUT/ladder/REPORT.md          per task: the table (normalized scores, the success
                                  rate, the runs), who leads at each level and whether
                                  the lead is distinguishable; the headroom checks
    OUT/ladder/runs.jsonl         each finished run's metrics.json, a line each

A cell is the mean over runs with its 95% bootstrap interval (`stats`); normalized: 0
the random policy, 100 the best known (`bounds`). The headroom checks: at `easy` a
hierarchy reaches >= 90, at `hard` no learner reaches 70 (else the level is not hard).
"""
import pathlib

import numpy as np

from hpg_mj.experiments import bounds
from hpg_mj.experiments import figures
from hpg_mj.experiments import reference
from hpg_mj.experiments import runner
from hpg_mj.experiments import runs
from hpg_mj.experiments import stats

# Per task: its experiments, and the scores (each normalized) its table gives, the first
# the one the figure, the leads and the headroom checks read.
TASKS = {
    "ship_current": ("ladder_current", "ladder_current_ppo_jax", "ladder_current_sac_jax"),
    "ship_goal": ("ladder_goal", "ladder_goal_ppo_jax", "ladder_goal_sac_jax"),
    "ship_regatta": ("ladder_regatta", "ladder_regatta_ppo_jax", "ladder_regatta_sac_jax"),
    "ship_harbour": ("ladder_harbour", "ladder_harbour_waypoints", "ladder_harbour_ppo_jax",
                     "ladder_harbour_sac_jax"),
}
EXPERIMENTS = tuple(name for names in TASKS.values() for name in names)
LEVELS = bounds.LEVELS
EASY_AT_LEAST, HARD_BELOW = 90.0, 70.0     # the headroom checks' bounds (normalized)
# The learners that count as hierarchies for the easy check (their agents' kinds): the
# designed ones (Figure 3's carried to each task, the regatta's waypoints).
HIERARCHY_KINDS = ("ship_ladder_hybrid", "ship_ladder_waypoints")
# The order of every task's table and figure (by agent kind; another kind after these):
# the designed hierarchies, flat PGRL, the learned hierarchy, the deep learners.
ORDER = ("ship_ladder_hybrid", "ship_ladder_waypoints", "ship_ladder_flat_pg",
         "ship_ladder_option_critic", "ladder_ppo_jax", "ladder_sac_jax")


def scores(task):
  """The task's scores, each normalized (`bounds.SCORES`), the success rate first: the
  gate pass rate, then J; the regatta's finish rate, then its mean return. The figure,
  the leads and the headroom checks read the first, the score the issue's bounds speak
  in (the steering hybrid's "89 normalized" is its gate rate; its J is 59)."""
  return tuple(reversed(bounds.SCORES[bounds.bounds_key(task, LEVELS[0])]))


def folder(out, quick=False):
  """Where the ladder's report is written under `out` (ladder/, or ladder_quick/)."""
  return pathlib.Path(out) / ("ladder_quick" if quick else "ladder")


def shipped():
  """{task: [its experiments, loaded]} of `TASKS` (those whose files are shipped)."""
  files = runner.shipped_experiments()
  return {task: [runner.load_experiment(name) for name in names if name in files]
          for task, names in TASKS.items()}


def collect(out, quick=False, experiments=None, earlier=None):
  """{task: [{"experiment", "learner" (its task file's stem), "label", "kind", "runs":
  {level: [each finished run's metrics]}}]} over `experiments` ({task: [experiments,
  loaded]}, each with `levels`; default `shipped()`); a learner with no finished run
  has empty lists. One entry a task file: where experiments run its levels apart (a
  level redrawn on fresh seeds), their runs meet there ("experiment": the first's).
  `earlier` (`reference.read_earlier`): an earlier report's runs, each taken for a
  seed whose run is not finished under OUT (a run under OUT wins), so that held-out
  runs finished and committed piece by piece make one table."""
  earlier = earlier or {}
  found = {}
  for task, loaded in (shipped() if experiments is None else experiments).items():
    learners = {}              # a learner's levels may be run by different experiments
    for experiment in loaded:
      root = runner.folder(experiment, out, quick)
      for variant in experiment["task_files"]:
        level = variant.section("environment")["level"]
        stem = variant.path.stem[:-len(level) - 1]       # "<file>_<level>"
        entry = learners.setdefault(stem, {"experiment": experiment["name"], "learner": stem,
                                           "label": variant.name.rsplit(", ", 1)[0],
                                           "kind": variant.kind,
                                           "runs": {lv: [] for lv in LEVELS}})
        for seed in runner.seeds(experiment, quick):
          run = root / variant.path.stem / f"seed{seed}"
          if runs.is_finished(run):
            entry["runs"][level].append(runs.read_metrics(run))
          elif (variant.path.stem, seed) in earlier:
            entry["runs"][level].append(earlier[(variant.path.stem, seed)])
    found[task] = list(learners.values())
    found[task].sort(key=lambda e: ORDER.index(e["kind"]) if e["kind"] in ORDER else len(ORDER))
  return found


def normalized(task, runs_, score):
  """Each run's greedy `score`, normalized against the task's bounds at the run's level
  (as its metrics hold it)."""
  return [m["greedy"].get(f"{score}_normalized", np.nan) for m in runs_]


def _summary(values):
  return stats.summary([np.nan if v is None else v for v in values]) if values else None


def read_added(*paths):
  """{task: [entries, as `collect`'s, "kind" "yours"]} of methods of one's own, scored
  beside the table (`hpg-mj reproduce ladder --add FILE`, one or more): a JSON line a
  run, `benchmark.evaluate`'s metrics (official, at a task of the ladder and a level)
  with the method's "label" and the run's "seed" (not a tuning seed of the ladder's
  task files), each (task, label, level, seed) once over the files. A bad line is
  refused naming it."""
  import json
  tuning = sorted({seed for loaded in shipped().values() for e in loaded
                   for t in e["task_files"] for seed in t.tuning_seeds})
  found, seen = {}, set()
  lines = []
  for path in map(pathlib.Path, paths):
    if not path.is_file():
      raise ValueError(f"--add {path}: no such file; give a JSON line per run: "
                       "{\"label\": ..., \"seed\": ..., **benchmark.evaluate(...).metrics}")
    lines += [(path, number, line)
              for number, line in enumerate(path.read_text().splitlines(), 1) if line.strip()]
  for path, number, line in lines:
    where = f"--add {path}, line {number}"
    try:
      run = json.loads(line)
      label, seed, task, level = run["label"], run["seed"], run["task"], run["level"]
    except (ValueError, KeyError, TypeError) as error:
      raise ValueError(f"{where}: not a run (a JSON object of benchmark.evaluate's metrics "
                       f"with label and seed): {error!r}") from None
    if task not in TASKS or level not in LEVELS:
      raise ValueError(f"{where}: task {task!r} at level {level!r}; allowed: a task of "
                       f"{list(TASKS)} at {list(LEVELS)}")
    if not isinstance(label, str) or not label.strip() or not isinstance(seed, int):
      raise ValueError(f"{where}: label {label!r} and seed {seed!r}; allowed: a name and "
                       "an integer")
    if run.get("official") is not True:
      raise ValueError(f"{where}: not official (official = {run.get('official')!r}): a "
                       "score beside the table is made on the level's 1,000 fixed starts "
                       "with the task's own step cap (benchmark.evaluate's defaults)")
    if seed in tuning:
      raise ValueError(f"{where}: seed {seed} is a tuning seed of the ladder's task files "
                       f"({figures.seed_list(tuning)}); a claim beside the table comes from seeds "
                       "drawn after the design was fixed (the table's: 1000-1009)")
    if (task, label, level, seed) in seen:
      raise ValueError(f"{where}: {label!r} on {task} at {level} seed {seed} is given twice")
    seen.add((task, label, level, seed))
    entries = found.setdefault(task, {})
    entry = entries.setdefault(label, {"experiment": None, "learner": label,
                                       "label": f"{label} (yours)",
                                       "kind": "yours", "runs": {lv: [] for lv in LEVELS}})
    entry["runs"][level].append({"seed": seed, "greedy": run})
  return {task: list(entries.values()) for task, entries in found.items()}


def against_best(task, entries, entry):
  """The report's line for a method of one's own: at each level, the best reference
  learner (not one's own) and whether the two 95% intervals are apart."""
  score = scores(task)[0]
  parts = []
  for level in LEVELS:
    mine = _summary(normalized(task, entry["runs"][level], score))
    others = [(e["label"], _summary(normalized(task, e["runs"][level], score)))
              for e in entries if e["kind"] != "yours" and e["runs"][level]]
    if mine is None or not others:
      continue
    label, best = max(others, key=lambda pair: pair[1]["mean"])
    side = "ahead of" if mine["mean"] > best["mean"] else "behind"
    parts.append(f"{level}: {stats.format_summary(mine, 1, iqm=False)}, {side} {label} "
                 f"({stats.format_summary(best, 1, iqm=False)}), " +
                 ("distinguishable (the intervals are apart)" if stats.separated(mine, best)
                  else "not distinguishable (the intervals overlap)"))
  return (f"- {entry['label']}, against the best reference learner: "
          + ("; ".join(parts) if parts else "no level in common") + ".")


def leads(task, entries):
  """{level: (the leading learner's label, its summary, whether its interval lies above
  every other learner's)}, over the learners with runs at that level."""
  score = scores(task)[0]
  out = {}
  for level in LEVELS:
    ranked = sorted(((e["label"], _summary(normalized(task, e["runs"][level], score)))
                     for e in entries if e["runs"][level]),
                    key=lambda pair: -pair[1]["mean"])
    if ranked:
      label, best = ranked[0]
      out[level] = (label, best, all(stats.separated(best, s) and best["mean"] > s["mean"]
                                     for _, s in ranked[1:]) and len(ranked) > 1)
  return out


def helmsman(task, score=None):
  """The scripted helmsman's normalized `score` (None: `scores(task)[0]`) at each level,
  from SPEC section 7.1's bounds (a policy of the observation alone, not a learner); nan
  where none is published."""
  score, out = score or scores(task)[0], []
  for level in LEVELS:
    key = bounds.bounds_key(task, level)
    entry = bounds.bounds()["tasks"].get(key) or {}
    value = bounds.normalize(key, score, (entry.get("helmsman") or {}).get(score))
    out.append(np.nan if value is None else value)
  return out


def helmsman_line(task):
  """The report's line for scale: `helmsman(task)` at each level, each of the task's
  scores, as the table gives the learners'."""
  parts = []
  for score in scores(task):
    cells = [f"{level} {'-' if np.isnan(v) else f'{v:.1f}'}"
             for level, v in zip(LEVELS, helmsman(task, score))]
    parts.append(f"{', '.join(cells)} ({score}, normalized)")
  return (f"- for scale, not a learner: the scripted helmsman (`benchmark.ladder_helmsman`, a "
          f"policy of the observation alone, SPEC section 7.1) scores {'; '.join(parts)}.")


def headroom(task, entries):
  """The issue's two checks: (a hierarchy reaches >= 90 at easy, no reference learner
  reaches 70 at hard; a method of one's own, `read_added`, is not one), each None where
  its runs are missing; on the mean over runs."""
  score = scores(task)[0]

  def mean(entry, level):
    values = normalized(task, entry["runs"][level], score)
    return float(np.nanmean(values)) if values else None
  easy = [mean(e, "easy") for e in entries if e["kind"] in HIERARCHY_KINDS]
  easy = [v for v in easy if v is not None]
  hard = [v for v in (mean(e, "hard") for e in entries if e["kind"] != "yours")
          if v is not None]
  return (max(easy) >= EASY_AT_LEAST if easy else None,
          max(hard) < HARD_BELOW if hard else None)


def table(task, entries):
  """The task's table (markdown lines): per learner and level, each score normalized
  with its 95% interval, and its runs."""
  head = ["learner"] + [f"{level}: {s}, normalized" for level in LEVELS for s in scores(task)]
  head += ["runs (easy, medium, hard)"]
  lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
  for e in entries:
    cells = [e["label"]]
    for level in LEVELS:
      for score in scores(task):
        values = normalized(task, e["runs"][level], score)
        cells.append(stats.format_summary(_summary(values), 1, iqm=False) if values else "-")
    cells.append(", ".join(str(len(e["runs"][level])) for level in LEVELS))
    lines.append("| " + " | ".join(cells) + " |")
  return lines


def draw(root, found):
  """ladder.png (a panel per task: a bar per learner at each level, its 95% interval)
  and ladder.csv (the same numbers)."""
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  tasks = [t for t, entries in found.items() if any(any(e["runs"].values()) for e in entries)]
  if not tasks:
    return None
  fig, axes = plt.subplots(1, len(tasks), figsize=(4.2 * len(tasks), 4.4), squeeze=False)
  rows = ["task,level,learner,score,mean,low,high,runs"]
  for ax, task in zip(axes[0], tasks):
    entries = [e for e in found[task] if any(e["runs"].values())]
    score = scores(task)[0]
    width = 0.8 / max(len(entries), 1)
    for k, e in enumerate(entries):
      means, errors = [], [[], []]
      for level in LEVELS:
        s = _summary(normalized(task, e["runs"][level], score))
        if s is None or np.isnan(s["mean"]):
          means.append(np.nan)
          errors[0].append(0.0)
          errors[1].append(0.0)
          continue
        means.append(s["mean"])
        errors[0].append(s["mean"] - s["low"])
        errors[1].append(s["high"] - s["mean"])
        rows.append(f"{task},{level},{e['label']},{score}_normalized,{s['mean']:.4f},"
                    f"{s['low']:.4f},{s['high']:.4f},{s['n']}")
      x = np.arange(len(LEVELS)) - 0.4 + width * (k + 0.5)
      ax.bar(x, means, width, yerr=errors, capsize=2, label=e["label"])
    ax.plot(range(len(LEVELS)), helmsman(task), "k_", markersize=28, markeredgewidth=1.5,
            label="scripted helmsman (not a learner)")
    ax.axhline(100.0, color="k", lw=0.6, ls="--")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xticks(range(len(LEVELS)), LEVELS)
    ax.set_title(task)
    ax.set_ylabel(f"{score}, normalized (greedy)")
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2,
              frameon=False)
  fig.tight_layout()
  path = root / "ladder.png"
  fig.savefig(path, dpi=110)
  plt.close(fig)
  (root / "ladder.csv").write_text("\n".join(rows) + "\n")
  return path


def _verdict(value, yes, no):
  return "not run yet" if value is None else (yes if value else no)


def write(out, quick=False, experiments=None, earlier=None, added=None):
  """Draws the figure and writes REPORT.md and runs.jsonl under OUT/ladder (ladder_quick
  with `quick`) from the finished runs (`collect`, of `experiments`, completed by
  `earlier`'s), with `added` (`read_added`: methods of one's own, after the reference
  learners, each with its line against the best of them); returns REPORT.md's path."""
  root = folder(out, quick)
  root.mkdir(parents=True, exist_ok=True)
  found = collect(out, quick, experiments, earlier)
  for task, entries in (added or {}).items():
    found.setdefault(task, []).extend(entries)
  lines = ["# ladder: the task ladder's reference table", "",
           "Each learner trained on held-out seeds (never a tuning seed) at each level, then "
           "measured greedily on the level's fixed 1,000 starts (SPEC sections 7 and 11). "
           "Each cell: the mean over runs [95% bootstrap confidence interval of the mean], "
           "normalized: 0 the random policy, 100 the best known (SPEC section 7.1's table "
           "of the ladder's bounds).", ""]
  if quick:
    lines += ["**QUICK protocol** (`--quick`): fewer runs and episodes, not for "
              "publication.", ""]
  picture = draw(root, found)
  if picture is None:
    lines += [f"No run has finished under {out} yet: `hpg-mj reproduce ladder --out {out}` "
              "makes them (or `hpg-mj run ladder_<task> --out ...`, one experiment).", ""]
  if picture is not None:
    lines += ["![the ladder](ladder.png)", "", "`ladder.png`: per task, each learner's "
              f"greedy {', '.join(sorted({scores(t)[0] for t in found}))} normalized at "
              "each level, a bar with its 95% interval, and a black dash where the scripted "
              "helmsman stands (for scale; `ladder.csv`: the bars' numbers; "
              "`runs.jsonl`: every run's metrics, J among them).", ""]
  made = {}
  for task, entries in found.items():
    lines += [f"## {task}", "", *table(task, entries), ""]
    for level, (label, best, clear) in leads(task, entries).items():
      lines.append(f"- {level}: {label} leads ({stats.format_summary(best, 1, iqm=False)}); "
                   + ("its interval lies above every other learner's." if clear else
                      "not distinguishable from the next (their intervals overlap)."))
    easy, hard = headroom(task, entries)
    unrun = [e["label"] for e in entries if not e["runs"]["hard"] and e["kind"] != "yours"]
    lines += [f"- headroom ({scores(task)[0]}, normalized, the mean over runs): a hierarchy "
              f"reaches {EASY_AT_LEAST:.0f} at easy: {_verdict(easy, 'yes', 'no')}; no "
              f"learner reaches {HARD_BELOW:.0f} at hard: "
              f"{_verdict(hard, 'yes', 'no: the level is not hard enough')}"
              + (f" (of those run there; not yet run at hard: {', '.join(unrun)})"
                 if unrun and hard is not None else "")
              + ("; the checks are the reference learners', not yours"
                 if any(e["kind"] == "yours" for e in entries) else "") + "."]
    lines += [helmsman_line(task)]
    lines += [against_best(task, entries, e) for e in entries if e["kind"] == "yours"] + [""]
    for e in entries:
      for level in LEVELS:
        if e["runs"][level] and e["kind"] != "yours":
          made[f"{e['learner']}_{level}"] = e["runs"][level]
  lines += figures.provenance_lines(made)
  (root / "REPORT.md").write_text("\n".join(lines) + "\n")
  reference.write_runs(root / "runs.jsonl", made)
  return root / "REPORT.md"
