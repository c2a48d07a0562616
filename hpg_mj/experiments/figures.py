"""The figures an experiment file declares ([[figure]] tables), drawn from stored
run records, and a REPORT.md that sets our numbers beside the paper's statements.

A "curve" figure plots one metric per block of 1,000 episodes (`METRICS`) against
episodes or against primitive/control steps: the mean over runs, with its 95%
bootstrap confidence band (`hpg_mj.experiments.stats`), the paper's stated value
drawn in when the file gives one, and the data beside the PNG as CSV; its title
says the runs x episodes, the seeds, what the band is, and a quick protocol says
it is quick. The legend names the learners as the paper does ([task] label). A
"greedy_curve" figure plots a greedy metric on the fixed starts at each of the
experiment's `greedy_at` points against the control (primitive) steps trained, on a
log axis (the sample-efficiency figures of `hpg_mj.experiments.reference`). A
"trajectories" figure (Figure 12) sails a run's final agent from given starts on
the MuJoCo ship (`experiments.fig12`); an "options" figure draws where an
option-critic's learned options begin and end on the field (`experiments.options_map`).

Records have named fields (`Agent.record_fields`): a metric is drawn for every
task whose agent records the fields it needs; every record has "steps".
"""
import pathlib
import re

import numpy as np


BLOCK = 1000   # episodes per point


def _blocks(values, weights=None):
  n = len(values) // BLOCK
  v = values[:n * BLOCK].reshape(n, BLOCK)
  if weights is None:
    return v.mean(axis=1)
  w = weights[:n * BLOCK].reshape(n, BLOCK)
  with np.errstate(invalid="ignore", divide="ignore"):
    return v.sum(axis=1) / w.sum(axis=1)


# metric -> (the record fields it needs, its per-block values); a task has a metric
# when its agent's record has those fields.
METRICS = {
    "gate_passes": (("passed",), lambda r: _blocks(r["passed"]) * BLOCK),
    "steps_to_gate": (("passed", "steps"),
                      lambda r: _blocks(r["steps"] * r["passed"], r["passed"])),
    "calls_per_episode": (("calls",), lambda r: _blocks(r["calls"])),
    "diagonal_successes": (("diagonal_successes", "diagonal_runs"),
                           lambda r: _blocks(r["diagonal_successes"], r["diagonal_runs"]) * BLOCK),
    "straight_successes": (("straight_successes", "straight_runs"),
                           lambda r: _blocks(r["straight_successes"], r["straight_runs"]) * BLOCK),
    "mean_return": (("return",), lambda r: _blocks(r["return"])),
    # Records whose rows are sums over 1,000 control steps (hpg_mj.agents.sb3): per
    # block of rows, over the episodes that ended in it.
    "gate_fraction": (("gates", "episodes"), lambda r: _blocks(r["gates"], r["episodes"])),
    "return_per_episode": (("return_sum", "episodes"),
                           lambda r: _blocks(r["return_sum"], r["episodes"])),
}
X_AXES = ("episodes", "steps")
REFERENCES = ("optimal",)


def has_metric(task, metric):
  """Whether the agent of `task` (a task file) records the fields curve `metric` reads."""
  from hpg_mj import agents
  return set(METRICS[metric][0]) <= set(agents.lookup(task.kind).record_fields)


def check_curve(fig, tasks):
  """Why a curve figure cannot be drawn from these tasks, or None."""
  if fig["metric"] not in METRICS:
    return f"metric = {fig['metric']!r}; allowed: {sorted(METRICS)}"
  if fig["x"] not in X_AXES:
    return f"x = {fig['x']!r}; allowed: {list(X_AXES)}"
  if fig.get("reference", REFERENCES[0]) not in REFERENCES:
    return f"reference = {fig['reference']!r}; allowed: {list(REFERENCES)}"
  if fig.get("better", "higher") not in ("higher", "lower"):
    return f"better = {fig['better']!r}; allowed: ['higher', 'lower']"
  if "reference" in fig and fig["metric"] != "mean_return":
    return "reference = 'optimal' needs metric = 'mean_return' (the taxi's exact optimum)"
  if not any(has_metric(t, fig["metric"]) for t in tasks):
    return (f"metric {fig['metric']!r} needs the record fields {list(METRICS[fig['metric']][0])}; "
            f"none of {[t.path.stem for t in tasks]} has them")
  return None


def protocol_line(protocol):
  """'20 runs x 50,000 episodes (seeds 100-119)', and ', QUICK protocol' for --quick."""
  if not protocol:
    return ""
  seeds = protocol["seeds"]
  text = (f"{len(seeds)} runs x {protocol['episodes']:,} episodes (seeds {seeds[0]}-"
          f"{seeds[-1]})")
  return text + (", QUICK protocol (not the paper's)" if protocol.get("quick") else "")


BAND = "band: 95% bootstrap CI of the mean over runs"


def draw_curve(root, fig, tasks, records_by_task, optimal=None, protocol=None):
  """Writes <name>.png and <name>.csv; returns {task stem: {"label", "final" (each
  run's last block), "reached" (each run's primitive steps to 95% of the optimum,
  NaN if never), "passed" (each run's fraction of its last block's episodes that
  passed the gate, for steps_to_gate)}}. The curve is the mean over runs, the band
  its 95% bootstrap confidence interval (`stats.band`)."""
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  from hpg_mj.experiments import stats
  from hpg_mj.worlds import taxi_values
  root = pathlib.Path(root)
  world = tasks[0].section("environment")["world"]
  plt.figure(figsize=(6.4, 4.4))
  columns, header, summary = [], [], {}
  for task in tasks:
    if not has_metric(task, fig["metric"]):
      continue
    name = task.path.stem
    records = records_by_task[name]
    data = np.array([METRICS[fig["metric"]][1](r) for r in records])
    if fig["x"] == "steps":
      x = np.mean([np.cumsum(r["steps"])[BLOCK - 1::BLOCK][:data.shape[1]] for r in records], axis=0)
    else:
      x = (np.arange(data.shape[1]) + 1.0) * BLOCK
    mean, low, high = stats.band(data)
    label = task.name
    entry = {"label": label, "final": data[:, -1]}
    columns += [x, mean, low, high]
    header += [f"{name}_x", f"{name}_mean", f"{name}_ci_low", f"{name}_ci_high"]
    if fig["metric"] == "steps_to_gate":
      # The mean is over the episodes that passed: say how many those were.
      passed = np.array([_blocks(r["passed"]) for r in records])
      entry["passed"] = passed[:, -1]
      columns.append(passed.mean(axis=0))
      header.append(f"{name}_fraction_passed")
      label += f" (last block: {100 * passed[:, -1].mean():.1f}% of episodes passed)"
    line, = plt.plot(x, mean, label=label)
    plt.fill_between(x, low, high, alpha=0.2, color=line.get_color(), linewidth=0)
    if fig.get("reference") == "optimal":
      entry["reached"] = np.array([taxi_values.steps_to_reach(r["return"], r["steps"], optimal,
                                                              window=BLOCK) for r in records])
    summary[name] = entry
  if fig.get("reference") == "optimal":
    plt.axhline(optimal, color="k", linestyle="--", linewidth=1, label="optimal (exact)")
    plt.ylim(max(-60.0, plt.ylim()[0]), optimal + 3)
  if "paper_value" in fig:
    plt.axhline(fig["paper_value"], color="k", linestyle="--", linewidth=1,
                label="paper (about)")
  plt.title(fig["title"] + ("\n" + protocol_line(protocol) + "\n" + BAND if protocol else ""),
            fontsize=8)
  plt.xlabel("episodes" if fig["x"] == "episodes" else
             ("primitive steps" if world == "taxi" else "control steps"))
  plt.ylabel(fig["ylabel"])
  plt.legend(fontsize=7)
  plt.tight_layout()
  plt.savefig(root / f"{fig['name']}.png", dpi=100)
  plt.close()
  n = min(len(c) for c in columns)
  np.savetxt(root / f"{fig['name']}.csv", np.column_stack([c[:n] for c in columns]),
             delimiter=",", header=",".join(header), comments="", fmt="%.6g")
  return summary


# greedy_curve figures: the greedy metrics of each world (SPEC sections 7, 7.1) whose
# value at each `greedy_at` point is drawn against the steps trained.
_SHIP_GREEDY = ("gate_pass_rate", "steps_to_gate", "J", "J_normalized",
                "gate_pass_rate_normalized")
GREEDY_METRICS = {"ship": _SHIP_GREEDY, "ship_current": _SHIP_GREEDY, "ship_goal": _SHIP_GREEDY,
                  "ship_harbour": _SHIP_GREEDY,
                  "ship_regatta": ("finish_rate", "gates_passed", "steps_to_finish",
                                   "mean_return", "mean_return_normalized",
                                   "finish_rate_normalized"),
                  "taxi": ("mean_return", "mean_return_normalized")}
STEPS_KEYS = ("control_steps", "primitive_steps")   # a run's steps trained (metrics.json)


def check_greedy_curve(fig, tasks):
  """Why a greedy_curve figure cannot be drawn from these tasks, or None."""
  world = tasks[0].section("environment")["world"]
  if world not in GREEDY_METRICS:
    return f"the {world}'s runs have no greedy metrics to draw; allowed worlds: " \
        f"{sorted(GREEDY_METRICS)}"
  allowed = GREEDY_METRICS[world]
  if fig["metric"] not in allowed:
    return f"metric = {fig['metric']!r}; allowed for the {world}: {list(allowed)}"
  if fig.get("reference", REFERENCES[0]) not in REFERENCES:
    return f"reference = {fig['reference']!r}; allowed: {list(REFERENCES)}"
  if "reference" in fig and fig["metric"] != "mean_return":
    return "reference = 'optimal' needs metric = 'mean_return' (the taxi's exact optimum)"
  return None


def greedy_points(metrics):
  """A finished run's greedy curve (`runs`: {"episodes", "steps", greedy metrics...}
  per point); a run made without `greedy_at` has its end only."""
  if "greedy_curve" in metrics:
    return metrics["greedy_curve"]
  steps = next(metrics[k] for k in STEPS_KEYS if k in metrics)
  return [{"episodes": metrics["episodes"], "steps": steps, **metrics["greedy"]}]


def greedy_series(runs_metrics, metric):
  """(x: the mean over runs of the steps trained at each point, values: runs x points
  of `metric`, NaN where a run has none, e.g. steps to the gate with no pass)."""
  curves = [greedy_points(m) for m in runs_metrics]
  n = min(len(c) for c in curves)
  x = np.mean([[p["steps"] for p in c[:n]] for c in curves], axis=0)
  values = np.array([[np.nan if p.get(metric) is None else float(p[metric]) for p in c[:n]]
                     for c in curves])
  return x, values


def draw_greedy(root, name, title, panels, tasks, results, optimal=None):
  """Writes <name>.png and <name>.csv: one panel per (metric, ylabel) of `panels`,
  each task's greedy metric against the control (primitive) steps trained, log
  axis; the mean over its runs with the 95% bootstrap band (`stats.band`). Returns
  {task stem: {"label", "final" (each run's value at its end)}} of the first panel."""
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  from hpg_mj.experiments import stats
  root = pathlib.Path(root)
  world = tasks[0].section("environment")["world"]
  fig, axes = plt.subplots(1, len(panels), figsize=(6.4 * len(panels), 4.4), squeeze=False)
  columns, header, summary = [], [], {}
  for ax, (metric, ylabel) in zip(axes[0], panels):
    for task in tasks:
      stem = task.path.stem
      if not results.get(stem):
        continue
      x, values = greedy_series(results[stem], metric)
      mean, low, high = stats.band(values)
      line, = ax.plot(x, mean, marker="o", markersize=3, label=f"{task.name} ({len(values)} runs)")
      ax.fill_between(x, low, high, alpha=0.2, color=line.get_color(), linewidth=0)
      columns += [x, mean, low, high]
      header += [f"{stem}_{metric}_{k}" for k in ("steps", "mean", "ci_low", "ci_high")]
      if metric == panels[0][0]:
        summary[stem] = {"label": task.name, "final": values[:, -1]}
    if optimal is not None and metric == "mean_return":
      ax.axhline(optimal, color="k", linestyle="--", linewidth=1, label="optimal (exact)")
    ax.set_xscale("log")
    ax.set_xlabel("primitive steps trained" if world == "taxi" else "control steps trained")
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=7)
  fig.suptitle(title + "\ngreedy on the fixed 1,000 starts; " + BAND, fontsize=8)
  fig.tight_layout()
  fig.savefig(root / f"{name}.png", dpi=100)
  plt.close(fig)
  n = max(len(c) for c in columns)
  padded = [np.concatenate([c, np.full(n - len(c), np.nan)]) for c in columns]
  np.savetxt(root / f"{name}.csv", np.column_stack(padded), delimiter=",",
             header=",".join(header), comments="", fmt="%.6g")
  return summary


def draw_trajectories(root, fig, agent, quick=False):
  """A trajectories figure from a trained hybrid; returns fig12.draw's summary. Its
  films are `width` x `height` (640 x 480) with a frame every `frame_every` (2)
  control steps, or with `quick` the figure's `quick_width`, `quick_height` and
  `quick_frame_every` where it gives them (a software renderer's time grows with the
  frames and the pixels)."""
  import json

  from hpg_mj.experiments import fig12
  root = pathlib.Path(root)
  size = {k: fig.get(k, v) for k, v in (("width", 640), ("height", 480), ("frame_every", 2))}
  if quick:
    size = {k: fig.get(f"quick_{k}", v) for k, v in size.items()}
  summary = fig12.draw(agent, root, starts=[tuple(s) for s in fig["starts"]],
                       video=fig["video"], name=fig["name"], title=fig["title"], **size)
  (root / f"{fig['name']}.json").write_text(json.dumps(summary, indent=2) + "\n")
  return summary


def draw_options(root, fig, agent):
  """An options figure from a trained option-critic (`options_map.draw`); its summary
  also in <name>.json."""
  import json

  from hpg_mj.experiments import options_map
  root = pathlib.Path(root)
  summary = options_map.draw(agent, root, [tuple(s) for s in fig["starts"]], fig["name"],
                             fig["title"])
  (root / f"{fig['name']}.json").write_text(json.dumps(summary, indent=2) + "\n")
  return summary


def options_lines(fig, summary):
  """What an options figure shows (`draw_options`' summary), a line each."""
  lines = [f"  - seed {fig['seed']}'s final agent, greedy on the analytic ship, from "
           f"({s['start'][0]:.0f}, {s['start'][1]:.0f}): "
           f"{'passed' if s['passed'] else 'missed'} the gate in {s['steps']} control steps, "
           f"{s['calls']} option calls" for s in summary["starts"]]
  return lines + [f"  - {option}: {s['calls']} calls, {s['mean_steps']:.1f} control steps "
                  f"each; on average begun at ({s['began'][0]:.0f}, {s['began'][1]:.0f}), "
                  f"ended at ({s['ended'][0]:.0f}, {s['ended'][1]:.0f})"
                  for option, s in summary["options"].items()]


# (metrics.json key, what the report calls it, digits); "greedy." reads the greedy
# evaluation on the fixed starts (SPEC section 7).
_SHIP_ROWS = (("gate_pass_rate", "gate pass rate, online", 3),
              ("steps_to_gate", "control steps to the gate, online", 1),
              ("J", "J (MushroomRL rewards), online", 1),
              ("J_normalized", "J, online, normalized (0 random, 100 best known)", 1),
              ("gate_pass_rate_normalized",
               "gate pass rate, online, normalized (0 random, 100 best known)", 1),
              ("greedy.gate_pass_rate", "gate pass rate, greedy", 3),
              ("greedy.steps_to_gate", "control steps to the gate, greedy", 1),
              ("greedy.J", "J (MushroomRL rewards), greedy", 1),
              ("greedy.J_normalized", "J, greedy, normalized (0 random, 100 best known)", 1),
              ("greedy.gate_pass_rate_normalized",
               "gate pass rate, greedy, normalized (0 random, 100 best known)", 1),
              ("calls_per_episode", "low-level calls per episode, online", 2),
              ("diagonal_success_rate", "diagonal subtask success, online", 3),
              ("straight_success_rate", "straight subtask success, online", 3))
_TAXI_ROWS = (("mean_return", "mean return, online", 3),
              ("mean_return_normalized",
               "mean return, online, normalized (0 random, 100 best known)", 1),
              ("greedy.mean_return", "mean return, greedy", 3),
              ("greedy.mean_return_normalized",
               "mean return, greedy, normalized (0 random, 100 best known)", 1))


def _value(run, key):
  for part in key.split("."):
    run = run.get(part) if isinstance(run, dict) else None
  return np.nan if run is None else float(run)


def _table(experiment, results, rows):
  from hpg_mj.experiments import stats
  tasks = [t for t in experiment["task_files"] if t.path.stem in results]
  lines = ["| measure | " + " | ".join(t.name for t in tasks) + " |",
           "|---" * (len(tasks) + 1) + "|"]
  for key, what, digits in rows:
    cells = [stats.summary([_value(m, key) for m in results[t.path.stem]]) for t in tasks]
    if all(c["n"] == 0 for c in cells):
      continue
    lines.append(f"| {what} | " + " | ".join(stats.format_summary(c, digits) for c in cells)
                 + " |")
  return lines


def _ordering(fig, summary, labels, n_runs):
  """What the report says about a figure's ordering: ours by the mean, and the
  paper's only where the 95% intervals of neighbours in the paper's order separate."""
  from hpg_mj.experiments import stats
  if fig.get("reference") == "optimal":
    values = {t: v["reached"] for t, v in summary.items()}
    lower, how = True, "primitive steps to 95% of the optimum, fewest first"
  else:
    values = {t: v["final"] for t, v in summary.items()}
    lower = fig.get("better", "higher") == "lower"
    how = "the last block, " + ("lowest first" if lower else "highest first")
  cis = {t: stats.summary(v) for t, v in values.items()}
  order = sorted(cis, key=lambda t: (np.isnan(cis[t]["mean"]),
                                     cis[t]["mean"] if lower else -cis[t]["mean"]))
  text = f" Ours ({how}): " + ", ".join(labels[t] for t in order) + "."
  if "paper_order" in fig:
    paper = [t for t in fig["paper_order"] if t in cis]
    pairs = list(zip(paper, paper[1:]))
  else:
    covered = fig.get("paper_tasks", order)
    pairs = [(fig["paper_best"], t) for t in order if t != fig["paper_best"] and t in covered]
  verdicts = []
  for a, b in pairs:
    ahead = cis[a]["mean"] < cis[b]["mean"] if lower else cis[a]["mean"] > cis[b]["mean"]
    if not stats.separated(cis[a], cis[b]):
      verdict = "not distinguishable (95% intervals overlap)"
    elif ahead:
      verdict = "as the paper (intervals separate)"
    else:
      verdict = "reversed (intervals separate)"
    verdicts.append((a, b, verdict))
  held = all(v == "as the paper (intervals separate)" for _, _, v in verdicts)
  text += " Against the paper's " + ("order" if "paper_order" in fig else "best") + ": " + \
      "; ".join(f"{labels[a]} ahead of {labels[b]}: {v}" for a, b, v in verdicts) + "."
  if held:
    text += " The paper's ordering holds."
  elif any(v.startswith("reversed") for _, _, v in verdicts):
    text += " The paper's ordering does **not** hold here: " + "; ".join(
        f"{labels[b]} is ahead of {labels[a]}" for a, b, v in verdicts
        if v.startswith("reversed")) + ", with separate 95% intervals."
  else:
    text += " The paper's ordering is **not** established here: " + "; ".join(
        f"{labels[a]} and {labels[b]} are not distinguishable" for a, b, v in verdicts
        if v.startswith("not")) + "."
  never = {t: int(np.isnan(values[t]).sum()) for t in values}
  if fig.get("reference") == "optimal" and any(never.values()):
    text += " Runs that never reached 95%: " + ", ".join(
        f"{labels[t]} {k} of {n_runs}" for t, k in never.items() if k) + \
        " (left out of those intervals)."
  return text


def _reached_cell(reached):
  """A report's cell of the runs' primitive steps to 95% of the optimum (NaN: never),
  in millions, over the runs that reach it, saying how many those are."""
  from hpg_mj.experiments import stats
  k, n = int(np.sum(~np.isnan(reached))), len(reached)
  if k == 0:
    return f"not reached (0 of {n} runs)"
  cell = stats.format_summary(stats.summary(reached / 1e6), 3)
  return cell if k == n else f"{cell} ({k} of {n} runs reach it)"


def write_report(root, experiment, results, drawn, protocol=None):
  """REPORT.md: the final metrics with 95% bootstrap intervals and IQMs, online and
  greedy, then per figure what the paper states beside what we measure.
  `drawn`: {figure name: draw_curve's or draw_trajectories' summary}."""
  from hpg_mj.agents import _ship
  from hpg_mj.experiments import stats
  root = pathlib.Path(root)
  n_runs = len(next(iter(results.values())))
  labels = {t.path.stem: t.name for t in experiment["task_files"]}
  described = f": {experiment['description']}" if experiment.get("description") else ""
  lines = [f"# {experiment['name']}{described}", ""]
  if protocol and experiment.get("tuning"):
    lines += [f"Protocol: {protocol_line(protocol)}. **Not for publication**: these runs may "
              "use the tasks' tuning seeds (`tuning = true`; SPEC section 7).", ""]
  elif protocol:
    lines += [f"Protocol: {protocol_line(protocol)}; the tasks' tuning seeds are not among "
              "them (SPEC section 7).", ""]
  lines += [f"{n_runs} run(s) per task. Each cell: the mean over runs [95% bootstrap "
            "confidence interval of the mean] and the interquartile mean (IQM). Online: the "
            "last 1,000 training episodes (exploring); greedy: the final agent, no "
            "exploration, no learning, on a fixed seeded set of 1,000 starts, the same "
            "for every run.", ""]
  taxi = all("optimal_mean_return" in runs[0] for runs in results.values())
  optimal = next(iter(results.values()))[0].get("optimal_mean_return")
  if taxi:
    lines += [f"Optimal mean return (value iteration): {optimal:.4f}.", ""]
    lines += _table(experiment, results, _TAXI_ROWS)
    reached = next((v for v in drawn.values() if isinstance(v, dict) and any(
        "reached" in e for e in v.values())), None)
    if reached:
      cells = [_reached_cell(reached[t]["reached"]) if t in reached else "-"
               for t in labels if t in results]
      lines.append("| million primitive steps to 95% of the optimum | " + " | ".join(cells)
                   + " |")
  else:
    lines += _table(experiment, results, _SHIP_ROWS)
    js = [t for t in results if not np.isnan(_value(results[t][0], "greedy.J"))]
    # MushroomRL's published J and the straight-line bound are the steering task's: a
    # ladder task's J compares with its own bounds (its normalized rows), not these.
    steering = all((t.section("environment") or {}).get("world", "ship") == "ship"
                   for t in experiment["task_files"])
    if js and steering:
      lines += ["", "J is the discounted return (gamma = 0.99) under MushroomRL's "
                "ShipSteering rewards (-1 per control step, 0 on the step that passes the "
                "gate, -100 on the step that leaves), so that it compares with published "
                "MushroomRL-based results: " + ", ".join(
                    f"{k} J ~ {v}" for k, v in _ship.PUBLISHED_J.items())
                + f"; the straight-line bound over uniform starts is "
                f"{_ship.straight_line_j():.1f} (a ship sailing straight at the gate from "
                "its start, `_ship.straight_line_j`). Ours, greedy: " + ", ".join(
                    f"{labels[t]} {stats.format_summary(stats.summary([_value(m, 'greedy.J') for m in results[t]]), 1)}"
                    for t in js) + "."]
  lines += ["", "## Against the paper", ""]
  for fig in experiment["figures"]:
    summary = drawn.get(fig["name"])
    if summary is None:
      continue
    head = f"- **{fig['name']}** ({fig['title']}): the paper: {fig['paper']}."
    if fig["kind"] == "options":
      lines += [head + " Ours:", *options_lines(fig, summary)]
      continue
    if fig["kind"] == "trajectories":
      lines.append(head + " Ours, on the MuJoCo ship:")
      for s in summary:
        lines.append(f"  - from ({s['start'][0]:.0f}, {s['start'][1]:.0f}): "
                     f"{'passed' if s['passed'] else 'missed'} the gate in {s['steps']} "
                     f"control steps, {s['calls']} calls ({' '.join(s['decisions'])})")
      continue
    ours = ", ".join(f"{v['label']} {stats.format_summary(stats.summary(v['final']))}"
                     for v in summary.values())
    line = head + (" Ours (greedy, the final agents): " if fig["kind"] == "greedy_curve" else
                   " Ours (last block of 1,000 episodes): ") + f"{ours}."
    if fig["metric"] == "steps_to_gate":
      line += " These means are over the episodes that passed the gate, which were " + \
          ", ".join(f"{v['label']} {100 * np.mean(v['passed']):.1f}%" for v in summary.values()) \
          + " of the last block's episodes."
    if "paper_value" in fig:
      off = [v["label"] for v in summary.values()
             if abs(np.mean(v["final"]) - fig["paper_value"]) > 0.1 * abs(fig["paper_value"])]
      if off:
        line += (f" We differ from the paper's {fig['paper_value']:g} by more than 10% "
                 f"({', '.join(off)}); see the README, 'Results'.")
    if "paper_order" in fig or "paper_best" in fig:
      line += _ordering(fig, summary, labels, n_runs)
      extra = [t for t in summary if t not in fig.get("paper_order", fig.get("paper_tasks",
                                                                              summary))]
      if extra:
        line += " (" + ", ".join(labels[t] for t in extra) + ": an extra curve, not in the " \
                "paper's comparison.)"
    lines.append(line)
  lines += provenance_lines(results)
  (root / "REPORT.md").write_text("\n".join(lines) + "\n")
  return root / "REPORT.md"


def seed_list(seeds):
  """Seeds as a short text: sorted, each run of three or more consecutive ones as
  "first-last" ([1000, ..., 1009, 1011] -> "1000-1009, 1011")."""
  seeds, parts = sorted(int(s) for s in seeds), []
  i = 0
  while i < len(seeds):
    j = i
    while j + 1 < len(seeds) and seeds[j + 1] == seeds[j] + 1:
      j += 1
    parts += ([f"{seeds[i]}-{seeds[j]}"] if j - i >= 2 else
              [str(s) for s in seeds[i:j + 1]])
    i = j + 1
  return ", ".join(parts)


def provenance_lines(results):
  """REPORT.md's last section: what made each run (their metrics.json), and this report."""
  from hpg_mj import provenance
  lines = ["", "## Provenance", "",
           f"This report: {provenance.markdown(provenance.collect())}.", ""]
  made_by = {}
  for task, runs in results.items():
    for m in runs:
      record = m.get("provenance") or {}
      made = (provenance.markdown(record) if record else
              "not recorded (made before hpg_mj recorded provenance)")
      made_by.setdefault(made, {}).setdefault(task, []).append(m.get("seed"))
  for made, which in made_by.items():
    lines.append(f"- Runs made by {made}: " + (
        "all of them." if len(made_by) == 1 else
        "; ".join(f"{task} seeds {seed_list(seeds)}" for task, seeds in which.items()) + "."))
  lines += ["", "| task | task file SHA-256 | seeds |", "|---|---|---|"]
  for task, runs in results.items():
    shas = sorted({str((m.get("provenance") or {}).get("task_file_sha256")) for m in runs})
    lines.append(f"| {task} | {', '.join(shas)} | {seed_list(m.get('seed') for m in runs)} |")
  return lines


def report_section(out, name):
  """The lines OUT/<name>/REPORT.md gives OUT/REPORT.md: its headings one level down,
  its pictures' links through its folder."""
  report = pathlib.Path(out) / name / "REPORT.md"
  text = re.sub(r"(!\[[^\]]*\]\()(?![a-z]+://|/)", rf"\g<1>{name}/",
                report.read_text()).splitlines()
  return ["#" + line if line.startswith("#") else line for line in text] + [""]


def write_combined_report(out, names):
  """OUT/REPORT.md after `hpg-mj reproduce`: each experiment's REPORT.md in turn, so
  that one file sets every figure beside the paper."""
  out = pathlib.Path(out)
  lines = ["# Reproduction of Ghavamzadeh & Mahadevan (2003)", "",
           "Each section is the REPORT.md of one experiment folder below this one.", ""]
  for name in names:
    if (out / name / "REPORT.md").is_file():
      lines += report_section(out, name)
  (out / "REPORT.md").write_text("\n".join(lines))
  return out / "REPORT.md"


def replace_section(out, name, write=True):
  """OUT/REPORT.md with its section of experiment `name` made again from
  OUT/<name>/REPORT.md, the other sections as they are: for a report remade on its
  own (the reference's, from runs kept elsewhere), so that the combined report never
  keeps an older copy of it. Returns whether the section differed (`write=False`:
  only says so)."""
  path = pathlib.Path(out) / "REPORT.md"
  text = path.read_text()
  start = re.search(rf"^## {re.escape(name)}: ", text, re.M)
  if start is None:
    raise ValueError(f"{path} has no section of {name!r} (a heading '## {name}: ...')")
  end = re.compile(r"^## ", re.M).search(text, start.end())
  new = (text[:start.start()] + "\n".join(report_section(out, name)) +
         ("\n" + text[end.start():] if end else ""))
  if write and new != text:
    path.write_text(new)
  return new != text
