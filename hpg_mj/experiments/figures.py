"""The figures an experiment file declares ([[figure]] tables), drawn from stored
run records, and a REPORT.md that sets our numbers beside the paper's statements.

A "curve" figure plots one metric per block of 1,000 episodes (`METRICS`) against
episodes or against primitive/control steps: the mean over runs, with a band from
the lowest to the highest run, the paper's stated value drawn in when the file
gives one, and the data beside the PNG as CSV. A "trajectories" figure (Figure
12) sails a run's final agent from given starts on the MuJoCo ship
(`experiments.fig12`).

Records have named fields (`Agent.record_fields`): a metric is drawn for every
task whose agent records the fields it needs; every record has "steps".
"""
import pathlib

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
}
X_AXES = ("episodes", "steps")
REFERENCES = ("optimal",)


def _has(task, metric):
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
  if not any(_has(t, fig["metric"]) for t in tasks):
    return (f"metric {fig['metric']!r} needs the record fields {list(METRICS[fig['metric']][0])}; "
            f"none of {[t.path.stem for t in tasks]} has them")
  return None


def draw_curve(root, fig, tasks, records_by_task, optimal=None):
  """Writes <name>.png and <name>.csv; returns {task: (final block mean, steps to
  95% of the optimum or None, runs reaching it)}."""
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  from hpg_mj.worlds import taxi_values
  root = pathlib.Path(root)
  world = tasks[0].section("environment")["world"]
  plt.figure(figsize=(6.4, 4.0))
  columns, header, summary = [], [], {}
  for task in tasks:
    if not _has(task, fig["metric"]):
      continue
    name = task.path.stem
    records = records_by_task[name]
    data = np.array([METRICS[fig["metric"]][1](r) for r in records])
    if fig["x"] == "steps":
      x = np.mean([np.cumsum(r["steps"])[BLOCK - 1::BLOCK][:data.shape[1]] for r in records], axis=0)
    else:
      x = (np.arange(data.shape[1]) + 1.0) * BLOCK
    mean = np.nanmean(data, axis=0)
    low, high = np.nanmin(data, axis=0), np.nanmax(data, axis=0)
    plt.plot(x, mean, label=name)
    plt.fill_between(x, low, high, alpha=0.2)
    columns += [x, mean, low, high]
    header += [f"{name}_x", f"{name}_mean", f"{name}_min", f"{name}_max"]
    reached = []
    if fig.get("reference") == "optimal":
      threshold = taxi_values.performance_threshold(optimal, 0.95)
      for r in records:
        trailing = np.convolve(r["return"], np.ones(BLOCK) / BLOCK, mode="valid")
        hit = np.nonzero(trailing >= threshold)[0]
        reached.append(np.cumsum(r["steps"])[hit[0] + BLOCK - 1] if len(hit) else np.nan)
    hits = [v for v in reached if not np.isnan(v)]
    summary[name] = (float(mean[-1]), float(np.mean(hits)) if hits else None, len(hits))
  if fig.get("reference") == "optimal":
    plt.axhline(optimal, color="k", linestyle="--", linewidth=1, label="optimal (exact)")
    plt.ylim(max(-60.0, plt.ylim()[0]), optimal + 3)
  if "paper_value" in fig:
    plt.axhline(fig["paper_value"], color="k", linestyle="--", linewidth=1,
                label="paper (about)")
  plt.title(fig["title"])
  plt.xlabel("episodes" if fig["x"] == "episodes" else
             ("primitive steps" if world == "taxi" else "control steps"))
  plt.ylabel(fig["ylabel"])
  plt.legend(fontsize=8)
  plt.tight_layout()
  plt.savefig(root / f"{fig['name']}.png", dpi=100)
  plt.close()
  n = min(len(c) for c in columns)
  np.savetxt(root / f"{fig['name']}.csv", np.column_stack([c[:n] for c in columns]),
             delimiter=",", header=",".join(header), comments="", fmt="%.6g")
  return summary


def draw_trajectories(root, fig, agent):
  """A trajectories figure from a trained hybrid; returns fig12.draw's summary."""
  import json

  from hpg_mj.experiments import fig12
  root = pathlib.Path(root)
  summary = fig12.draw(agent, root, starts=[tuple(s) for s in fig["starts"]],
                       video=fig["video"], name=fig["name"], title=fig["title"],
                       width=fig.get("width", 640), height=fig.get("height", 480))
  (root / f"{fig['name']}.json").write_text(json.dumps(summary, indent=2) + "\n")
  return summary


_SHIP_COLUMNS = ("gate_pass_rate", "steps_to_gate", "calls_per_episode",
                 "diagonal_success_rate", "straight_success_rate")


def _mean(runs, key):
  values = [r.get(key) for r in runs if r.get(key) is not None]
  return float(np.mean(values)) if values else None


def write_report(root, experiment, results, drawn):
  """REPORT.md: the final metrics, then per figure what the paper states beside
  what we measure. `drawn`: {figure name: draw_curve's or draw_trajectories' summary}."""
  root = pathlib.Path(root)
  n_runs = len(next(iter(results.values())))
  lines = [f"# {experiment['name']}: {experiment['description']}", "",
           f"{n_runs} run(s) per task; numbers are means over runs of the last 1,000 "
           "episodes (figures: of the last block of 1,000).", ""]
  taxi = all("optimal_mean_return" in runs[0] for runs in results.values())
  optimal = next(iter(results.values()))[0].get("optimal_mean_return")
  if taxi:
    lines += [f"Optimal mean return (value iteration): {optimal:.4f}.", "",
              "| task | final mean return | % of optimal | primitive steps |", "|---|---|---|---|"]
    for task, runs in results.items():
      ret = _mean(runs, "mean_return")
      lines.append(f"| {task} | {ret:.3f} | {100 * ret / optimal:.1f}% | "
                   f"{_mean(runs, 'primitive_steps'):,.0f} |")
  else:
    lines += ["| task | " + " | ".join(c.replace("_", " ") for c in _SHIP_COLUMNS) + " |",
              "|---" * (len(_SHIP_COLUMNS) + 1) + "|"]
    for task, runs in results.items():
      cells = [_mean(runs, c) for c in _SHIP_COLUMNS]
      lines.append(f"| {task} | " + " | ".join("-" if v is None else f"{v:.3f}" for v in cells)
                   + " |")
  lines += ["", "## Against the paper", ""]
  for fig in experiment["figures"]:
    summary = drawn.get(fig["name"])
    if summary is None:
      continue
    head = f"- **{fig['name']}** ({fig['title']}): the paper: {fig['paper']}."
    if fig["kind"] == "trajectories":
      lines.append(head + " Ours, on the MuJoCo ship:")
      for s in summary:
        lines.append(f"  - from ({s['start'][0]:.0f}, {s['start'][1]:.0f}): "
                     f"{'passed' if s['passed'] else 'missed'} the gate in {s['steps']} "
                     f"control steps, {s['calls']} calls ({' '.join(s['decisions'])})")
      continue
    ours = ", ".join(f"{task} {v[0]:.3g}" for task, v in summary.items())
    line = head + f" Ours (last block): {ours}."
    if "paper_value" in fig:
      off = [t for t, v in summary.items()
             if abs(v[0] - fig["paper_value"]) > 0.1 * abs(fig["paper_value"])]
      if off:
        line += (f" We differ from the paper's {fig['paper_value']:g} by more than 10% "
                 f"({', '.join(off)}); see the README, 'Results'.")
    if fig.get("reference") == "optimal":
      line += " Primitive steps until the trailing 1,000-episode mean first reaches 95% of " \
              "the optimum: " + ", ".join(
                  f"{t} {'never' if v[1] is None else f'{v[1]:,.0f}'} ({v[2]} of {n_runs} runs)"
                  for t, v in summary.items()) + "."
    if "paper_order" in fig or "paper_best" in fig:
      if fig.get("reference") == "optimal":
        order = sorted(summary, key=lambda t: (summary[t][1] is None, summary[t][1] or 0.0))
        how = "by primitive steps to 95% of the optimum"
      elif fig.get("better", "higher") == "lower":
        order = sorted(summary, key=lambda t: summary[t][0])
        how = "by the last block, lowest first"
      else:
        order = sorted(summary, key=lambda t: -summary[t][0])
        how = "by the last block, highest first"
      if "paper_order" in fig:
        same = order == [t for t in fig["paper_order"] if t in summary]
        line += f" The paper's order: {', '.join(fig['paper_order'])}"
      else:
        same = order[0] == fig["paper_best"]
        line += f" The paper's best: {fig['paper_best']}"
      line += f"; ours ({how}): {', '.join(order)}" + (" (the same)." if same else " (we differ).")
    lines.append(line)
  lines += _provenance_lines(results)
  (root / "REPORT.md").write_text("\n".join(lines) + "\n")
  return root / "REPORT.md"


def _provenance_lines(results):
  """REPORT.md's last section: what made each run (their metrics.json), and this report."""
  from hpg_mj import provenance
  lines = ["", "## Provenance", "",
           f"This report: {provenance.markdown(provenance.collect())}.", ""]
  made_by = {}
  for task, runs in results.items():
    for m in runs:
      record = m.get("provenance") or {}
      made_by.setdefault(provenance.markdown(record) if record else
                         "not recorded (made before hpg_mj recorded provenance)", []).append(
          f"{task} seed {m.get('seed')}")
  for made, which in made_by.items():
    lines.append(f"- Runs made by {made}: " + (
        "all of them." if len(made_by) == 1 else ", ".join(which) + "."))
  lines += ["", "| task | task file SHA-256 | seeds |", "|---|---|---|"]
  for task, runs in results.items():
    shas = sorted({str((m.get("provenance") or {}).get("task_file_sha256")) for m in runs})
    lines.append(f"| {task} | {', '.join(shas)} | "
                 f"{', '.join(str(m.get('seed')) for m in runs)} |")
  return lines


def write_combined_report(out, names):
  """OUT/REPORT.md after `hpg-mj reproduce`: each experiment's REPORT.md in turn, so
  that one file sets every figure beside the paper."""
  out = pathlib.Path(out)
  lines = ["# Reproduction of Ghavamzadeh & Mahadevan (2003)", "",
           "Each section is the REPORT.md of one experiment folder below this one.", ""]
  for name in names:
    report = out / name / "REPORT.md"
    if report.is_file():
      text = report.read_text().splitlines()
      lines += ["#" + line if line.startswith("#") else line for line in text] + [""]
  (out / "REPORT.md").write_text("\n".join(lines))
  return out / "REPORT.md"
