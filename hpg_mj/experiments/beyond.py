"""`hpg-mj reproduce beyond`: SPEC section 8's continuing ship task, the results the
paper left out ("we do not include the results for space reasons").

For each reported seed (never a tuning seed, SPEC section 7) the average-reward
agent of tasks/ship_patrol_average_reward.toml learns from scratch; after every
block of hours its greedy policy sails a few evaluation hours. After training it
is compared (`ShipPatrol.final_metrics`) with the episodic hybrid of
tasks/ship_hybrid.toml, trained on its own protocol with the same seed and sailed
greedily on the continuing task, and with the scripted figure-eight helmsman, all
over the same hours from the same start. Writes beyond_patrol.png with its CSV,
beyond_patrol_final.csv and REPORT.md ('Beyond the paper').

The report's other two parts (SPEC section 8):
* the route past the paper's (tasks/ship_hybrid_beyond.toml): each seed's agent
  trained on its file's protocol, then evaluated greedily from 1,000 fixed starts
  (`route_starts`): gate passes, control steps to the gate, J and calls, against
  the 220-step bar and the ~205-step straight line (beyond_route.png, .csv);
* the more expressive low-level policy: the stand-alone diagonal and straight
  subtasks with the paper's sigma = 1 and with the learned exploration width, their
  online success per 1,000 calls with 95% bootstrap bands and their final greedy
  success (subtask_width.png, .csv).
`scripts/beyond_route.py` and `scripts/subtask_width.py` run the same measurements
on any seeds, with more detail. The seeds run on `workers` processes (default: one
per core); each seed's numbers are the same on any number of them.
"""
import concurrent.futures
import json
import pathlib
import time

import numpy as np

from hpg_mj import _stack
from hpg_mj.experiments import cores

TASK = "ship_patrol_average_reward"
# Drawn fresh when the root's planning was designed, declared before the design's
# first run on them; 100-119 were looked at while the design before was chosen.
SEEDS = tuple(range(10001, 10021))
# (seeds, training hours, block hours, greedy hours per point, hybrid episodes (0:
# its file's), final evaluation hours)
FULL = (SEEDS, 2500, 125, 10, 0, 100)
QUICK = (SEEDS[:2], 750, 75, 5, 10000, 20)

ROUTE_TASK = "ship_hybrid_beyond"
HELD_OUT = tuple(range(100, 120))       # 20 seeds outside the tuning seeds 0-9
# (seeds, episodes: None for the task file's protocol)
ROUTE_FULL = (HELD_OUT, None)
ROUTE_QUICK = (HELD_OUT[:2], 20000)
ROUTE_BAR = 220.0                       # the route's target: <= 220 control steps, gate >= 0.95
STRAIGHT_LINE = 205.0                   # SPEC section 2: ~205 steps over uniform starts
# (seeds, calls per run); the greedy success is over 1,000 fixed local starts
SUBTASK_FULL = (HELD_OUT, 15000)
SUBTASK_QUICK = (HELD_OUT[:3], 3000)
# Which seeds each part's design looked at (SPEC section 7: reported seeds are others).
LOOKED_AT = {
    "patrol": "tuning seeds 0-9 (every configuration) and, for the diagnosis only, 4004 "
              "and 5004 (the unseen seeds that had shown the failure); the design before it "
              "also 100-119, 4001-4009 and 5000-5009",
    "route": "tuning seeds 0-3, and 100-119 once before the last choice (200,000 against "
             "300,000 episodes)",
    "subtasks": "seed 0 (the step size and clip) and seed 100 (the width's measurement)"}
# What the continuing task's report said before the root planned (the design before: 50 m
# cells everywhere, no planning).
PATROL_HISTORY = (
    "History: the design before (50 m cells everywhere, no planning) was reported on seeds "
    "100-119, which were looked at while its design and settings were chosen: greedy root "
    "188.8 [168.1, 209.4], episodic hybrid 150.4 [118.0, 179.0], paired +38.4 [+5.3, "
    "+73.3], ahead on 16 of 20. On 19 seeds no one had looked at (4001-4009, "
    "5000-5009) it gave +5.3 [-26.5, +37.8], ahead on 11 of 19 (not distinguishable), and "
    "its greedy root passed 0 an hour on seed 4004 and 115 on 4003, below the helmsman. "
    "Why, and the fix: README.md and patrol_diagnosis.txt.")
# The learned width's step size and clip, chosen on seed 0 (scripts/subtask_width.py).
WIDTH_VARIANTS = {"paper (sigma = 1)": {},
                  "learned width": {"width_alpha": 0.003, "sigma_low": 0.25,
                                    "sigma_high": 1.0}}


def run(out, quick=False, progress=None, protocols=None, workers=None):
  """Trains and measures the three parts; returns the report's path. `progress`
  receives a line of text per finished seed; `protocols` (for tests) replaces
  the (patrol, route, subtask) protocols; `workers`: processes (None: one per core)."""
  patrol, route, subtask = protocols or ((QUICK, ROUTE_QUICK, SUBTASK_QUICK) if quick
                                         else (FULL, ROUTE_FULL, SUBTASK_FULL))
  say = progress or (lambda line: None)
  root = pathlib.Path(out) / ("beyond_quick" if quick else "beyond")
  root.mkdir(parents=True, exist_ok=True)
  workers = cores.pool_size(workers, None)     # at most the cores here (_in_order: the seeds)
  lines = _patrol(root, patrol, quick, say, workers)
  lines += _route(root, route, say, workers)
  lines += _subtasks(root, subtask, say, workers)
  (root / "REPORT.md").write_text("\n".join(lines))
  return root / "REPORT.md"


def _in_order(fn, items, workers):
  """fn(*item) for every item, yielded in the items' order; on up to `workers`
  processes (one: in this one)."""
  if workers <= 1 or len(items) <= 1:
    for item in items:
      yield fn(*item)
    return
  with concurrent.futures.ProcessPoolExecutor(max_workers=min(workers, len(items))) as pool:
    for future in [pool.submit(_stack.roomy, fn, *item) for item in items]:
      yield future.result()


def patrol_seed(seed, hours, block, probe_hours, episodic_episodes, eval_hours):
  """One seed of the continuing task: (online and greedy gates per hour after every
  block, the final comparison's numbers)."""
  from hpg_mj import agents
  start = time.perf_counter()
  agent = agents.build(agents.load_task(TASK), seed=seed)
  online, greedy = [], []
  for _ in range(hours // block):
    record = agent.train(block)
    online.append(agent.metrics(record)["gates_per_hour"])
    greedy.append(agent.metrics(agent.evaluation(probe_hours))["gates_per_hour"])
  agent.config = _with_comparison(agent.config, episodic_episodes, eval_hours)
  final = agent.final_metrics(record)
  final.update({"seed": seed, "training_hours": hours, "online_gates_per_hour": online[-1],
                "wall_seconds": round(time.perf_counter() - start, 1)})
  return online, greedy, final


def _patrol(root, protocol, quick, say, workers=1):
  """The continuing task's part: trains every seed, draws, returns report lines."""
  from hpg_mj import agents
  seeds, hours, block, probe_hours, episodic_episodes, eval_hours = protocol
  task = agents.load_task(TASK)
  _refuse_tuning_seeds(task, seeds)
  curves, finals = [], []
  items = [(seed, hours, block, probe_hours, episodic_episodes, eval_hours) for seed in seeds]
  for seed, (online, greedy, final) in zip(seeds, _in_order(patrol_seed, items, workers)):
    curves.append((online, greedy))
    finals.append(final)
    (root / f"seed{seed}.json").write_text(json.dumps(final, indent=1))
    say(f"beyond: patrol seed {seed}: greedy {final['greedy_gates_per_hour']:.1f} gate "
        f"passes per hour, episodic hybrid "
        f"{final.get('episodic_gates_per_hour', float('nan')):.1f}, scripted "
        f"{final['scripted_gates_per_hour']:.1f} ({final['wall_seconds']} s)")
  x = (np.arange(hours // block) + 1.0) * block
  _draw(root, x, curves, finals)
  return _report(task, seeds, hours, finals, quick)


def route_starts(n=1000, seed=2026):
  """The route's fixed evaluation starts: uniform over the field, heading and
  turning rate (the same for every seed and every design)."""
  rs = np.random.default_rng(seed)
  return np.column_stack([rs.uniform(0, 1000, n), rs.uniform(0, 1000, n),
                          rs.uniform(-180, 180, n), rs.uniform(-15, 15, n)])


def route_seed(task, seed, episodes=None, starts=None):
  """One seed of the route: trains `task`'s agent (`episodes`: None for its file's
  protocol), then sails greedily from each of `starts` (`route_starts()`); returns
  (the agent, the greedy record, its numbers)."""
  from hpg_mj import agents
  starts = route_starts() if starts is None else starts
  agent, _, seconds = agents.train(task, episodes=episodes, seed=seed)
  record = agent.as_record(np.concatenate(
      [agent.compiled(1, False, False, start=s) for s in starts]))
  ok = record["passed"] > 0
  steps = float(record["steps"][ok].mean()) if ok.any() else float("nan")
  return agent, record, {"seed": seed, "gate_pass_rate": float(ok.mean()),
                         "steps_to_gate": steps,
                         "J": float(agent.j(record).mean()),
                         "calls": float(record["calls"].mean()),
                         "wall_seconds": round(seconds, 1)}


def route_numbers(seed, episodes):
  """`route_seed`'s numbers for the shipped route task (for a worker process)."""
  from hpg_mj import agents
  return route_seed(agents.load_task(ROUTE_TASK), seed, episodes)[2]


def _route(root, protocol, say, workers=1):
  from hpg_mj import agents
  from hpg_mj.experiments import stats
  seeds, episodes = protocol
  task = agents.load_task(ROUTE_TASK)
  _refuse_tuning_seeds(task, seeds)
  starts = route_starts()
  rows = []
  for r in _in_order(route_numbers, [(seed, episodes) for seed in seeds], workers):
    rows.append(r)
    say(f"beyond: route seed {r['seed']}: gate {r['gate_pass_rate']:.3f}, "
        f"{r['steps_to_gate']:.1f} control steps, J {r['J']:.2f} ({r['wall_seconds']} s)")
  keys = ("seed", "gate_pass_rate", "steps_to_gate", "J", "calls", "wall_seconds")
  (root / "beyond_route.csv").write_text(
      ",".join(keys) + "\n" + "".join(",".join(f"{r[k]:.6g}" for k in keys) + "\n"
                                       for r in rows))
  _draw_route(root, rows)
  summary = {k: stats.mean_ci([r[k] for r in rows]) for k in keys[1:5]}
  n_episodes = episodes or task.protocol.episodes

  def cell(key, digits):
    m, lo, hi = summary[key]
    return f"{m:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"
  met = (summary["gate_pass_rate"][0] >= 0.95 and summary["steps_to_gate"][0] <= ROUTE_BAR
         and summary["J"][0] > -87.3)
  return [
      "## A route past the paper's (tasks/ship_hybrid_beyond.toml)", "",
      "A Q(lambda) root that sees its cell and the heading's sector, through 16 offset "
      "tilings of them, and picks a point to steer to; one low-level subtask, aim, that steers to it with the paper's "
      "Gaussian-with-sigmoid CMAC policy learned by Eq. 3 (hpg_mj/agents/ship_beyond.py). "
      f"Each seed trains for {n_episodes:,} episodes, then sails greedily from the same "
      f"{len(starts):,} fixed starts. Seeds {seeds[0]}-{seeds[-1]} ({len(seeds)} runs; "
      f"tuning seeds {list(task.tuning_seeds)} never reported). Seeds looked at while "
      f"this design was chosen: {LOOKED_AT['route']}.", "",
      "| mean over seeds [95% bootstrap CI] | value | bar |", "|---|---|---|",
      f"| gate passes | {cell('gate_pass_rate', 3)} | >= 0.95 |",
      f"| control steps to the gate (over passes) | {cell('steps_to_gate', 1)} | <= "
      f"{ROUTE_BAR:g} (the paper ~220; straight line ~{STRAIGHT_LINE:g}) |",
      f"| J (gamma 0.99, MushroomRL's rewards) | {cell('J', 2)} | > -87.3 (best published "
      "hierarchy) |",
      f"| calls per episode | {cell('calls', 2)} | |", "",
      "All three bars met." if met else "Not every bar is met (see the table).", "",
      "![route](beyond_route.png)", "", "Data: beyond_route.csv (per seed).", ""]


def subtask_seed(task, seed, calls, options):
  """One seed of a stand-alone subtask: (online success per 1,000 calls, the final
  greedy success over 1,000 fixed local starts)."""
  from hpg_mj.hierarchy import ship_subtask
  run = ship_subtask.train_subtask(task, calls, seed, greedy_every=calls,
                                   greedy_episodes=1000, **options)
  return run["success"].reshape(-1, 1000).mean(axis=1), float(run["greedy"][-1])


def _subtasks(root, protocol, say, workers=1):
  from hpg_mj.hierarchy import ship_subtask
  from hpg_mj.experiments import stats
  seeds, calls = protocol
  rows = ["subtask,policy,calls,mean,ci_low,ci_high"]
  table = []
  curves = {}
  for task in ship_subtask.TASKS:
    for name, options in WIDTH_VARIANTS.items():
      runs = list(_in_order(subtask_seed, [(task, seed, calls, options) for seed in seeds],
                            workers))
      online = np.array([r[0] for r in runs])
      mean, low, high = stats.band(online)
      curves[task, name] = (mean, low, high)
      x = 1000 * np.arange(1, len(mean) + 1)
      rows += [f"{task},{name},{c},{m:.4f},{lo:.4f},{hi:.4f}"
               for c, m, lo, hi in zip(x, mean, low, high)]
      g = stats.mean_ci([r[1] for r in runs])
      table.append(f"| {task} | {name} | {mean[-1]:.3f} [{low[-1]:.3f}, {high[-1]:.3f}] | "
                   f"{g[0]:.3f} [{g[1]:.3f}, {g[2]:.3f}] |")
      say(f"beyond: ship/{task}, {name}: final online {mean[-1]:.3f}, greedy {g[0]:.3f} "
          f"({len(seeds)} seeds)")
  (root / "subtask_width.csv").write_text("\n".join(rows) + "\n")
  draw_subtasks(root, curves, len(seeds))
  return [
      "## A more expressive low-level policy: the learned exploration width", "",
      "The stand-alone `ship/diagonal` and `ship/straight` subtasks (each call a fresh "
      "start), learned by the shipped hybrid's low level (Eq. 3, discounted trace 0.99, "
      "baseline 0.3) with the paper's sigma = 1 and with a learned state-dependent width "
      "(hpg_mj/learners/policies.py, `gaussian_width_act`: log sigma linear over the "
      f"policy's tiles, clipped to [0.25, 1], step 0.003). {calls:,} calls per run, seeds "
      f"{seeds[0]}-{seeds[-1]} ({len(seeds)} runs). Seeds looked at while this design was "
      f"chosen: {LOOKED_AT['subtasks']}.", "",
      f"| subtask | policy | online success, last 1,000 calls | greedy success, 1,000 "
      f"starts |", "|---|---|---|---|", *table, "",
      "![subtasks](subtask_width.png)", "", "Data: subtask_width.csv (curves with bands).",
      ""]


def _refuse_tuning_seeds(task, seeds):
  tuned = sorted(set(seeds) & set(task.tuning_seeds))
  if tuned:
    raise ValueError(f"{task.path.name}: seeds {tuned} are tuning seeds "
                     f"{list(task.tuning_seeds)}; report only other seeds")


def _draw_route(root, rows):
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  seeds = [r["seed"] for r in rows]
  plt.figure(figsize=(6.4, 3.6))
  plt.plot(seeds, [r["steps_to_gate"] for r in rows], "o", label="greedy, 1,000 starts")
  plt.axhline(ROUTE_BAR, color="tab:red", linestyle=":", label=f"bar ({ROUTE_BAR:g})")
  plt.axhline(STRAIGHT_LINE, color="k", linestyle="--", linewidth=1,
              label=f"straight line (~{STRAIGHT_LINE:g})")
  _finish(plt, root / "beyond_route.png",
          f"Route past the paper's: control steps to the gate ({len(rows)} seeds)", "seed",
          "control steps to the gate")


def _finish(plt, path, title, xlabel, ylabel):
  """Titles, labels and legend of a one-panel figure, saved to `path` and closed."""
  plt.title(title)
  plt.xlabel(xlabel)
  plt.ylabel(ylabel)
  plt.legend(fontsize=8)
  plt.tight_layout()
  plt.savefig(path, dpi=100)
  plt.close()


def draw_subtasks(root, curves, n_seeds, name="subtask_width.png"):
  """The subtasks' online success curves with their bands, {(task, policy): (mean,
  low, high)}, into root / name."""
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  from hpg_mj.hierarchy import ship_subtask
  fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True)
  for ax, task in zip(axes, ship_subtask.TASKS):
    for policy in WIDTH_VARIANTS:
      mean, low, high = curves[task, policy]
      x = 1000 * np.arange(1, len(mean) + 1)
      ax.plot(x, mean, label=policy)
      ax.fill_between(x, low, high, alpha=0.25)
    ax.set_title(f"ship/{task} ({n_seeds} seeds x {1000 * len(mean):,} calls, 95% CI)")
    ax.set_xlabel("calls")
    ax.grid(alpha=0.3)
  axes[0].set_ylabel("successes per 1,000 calls (online)")
  axes[0].legend()
  fig.tight_layout()
  fig.savefig(root / name, dpi=110)
  plt.close(fig)


def _with_comparison(config, episodes, hours):
  import dataclasses
  return dataclasses.replace(config, comparison=dataclasses.replace(
      config.comparison, episodic_episodes=episodes, evaluation_hours=hours))


def _draw(root, x, curves, finals):
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  online = np.array([c[0] for c in curves])
  greedy = np.array([c[1] for c in curves])
  plt.figure(figsize=(6.4, 4.0))
  for data, label in ((greedy, "average-reward root, greedy"),
                      (online, "average-reward root, online (exploring)")):
    plt.plot(x, data.mean(axis=0), label=label)
    plt.fill_between(x, data.min(axis=0), data.max(axis=0), alpha=0.2)
  scripted = np.mean([f["scripted_gates_per_hour"] for f in finals])
  plt.axhline(scripted, color="k", linestyle="--", linewidth=1,
              label="scripted figure-eight helmsman")
  if all("episodic_gates_per_hour" in f for f in finals):
    episodic = np.mean([f["episodic_gates_per_hour"] for f in finals])
    plt.axhline(episodic, color="tab:red", linestyle=":", linewidth=1.5,
                label="episodic hybrid (trained), greedy")
  plt.axhline(30, color="grey", linewidth=0.8, label="30 passes / hour")
  _finish(plt, root / "beyond_patrol.png", "Continuing ship task: gate passes per hour of "
          "sailing", "training hours (6,000 control steps each)", "gate passes per hour")
  columns = [x, greedy.mean(axis=0), greedy.min(axis=0), greedy.max(axis=0),
             online.mean(axis=0), online.min(axis=0), online.max(axis=0)]
  np.savetxt(root / "beyond_patrol.csv", np.column_stack(columns), delimiter=",",
             header="hours,greedy_mean,greedy_min,greedy_max,online_mean,online_min,online_max",
             comments="", fmt="%.6g")
  keys = ["seed", "greedy_gates_per_hour", "episodic_gates_per_hour",
          "scripted_gates_per_hour", "online_gates_per_hour", "episodic_gate_pass_rate"]
  with open(root / "beyond_patrol_final.csv", "w") as f:
    f.write(",".join(keys) + "\n")
    for final in finals:
      f.write(",".join(f"{final.get(k, float('nan')):.6g}" if k != "seed" else str(final[k])
                       for k in keys) + "\n")


def _report(task, seeds, hours, finals, quick):
  """The continuing task's report lines."""
  from hpg_mj.experiments import stats

  def row(label, key):
    values = [f[key] for f in finals if f.get(key) is not None]
    if not values:
      return f"| {label} | - | - |"
    mean, low, high = stats.mean_ci(values)
    return (f"| {label} | {mean:.1f} [{low:.1f}, {high:.1f}] | "
            f"{', '.join(f'{v:.1f}' for v in values)} |")
  episodic_note = finals[0].get("episodic_episodes")
  root = task.config.root
  lines = [
      "# Beyond the paper (SPEC section 8)", "",
      "Three things the paper names and does not show: a continuing task with an "
      "average-reward root, a route better than its 8 whole legs, and a more expressive "
      "low-level policy. Every number is over seeds that were not tuned on; each part "
      "says which seeds were looked at while its design was chosen.", "",
      "## The continuing ship task: an average-reward root", "",
      "The paper (section 6) names a hierarchy with a continuing root whose performance is "
      "the average reward, and leaves its results out. Here: `ship/patrol` / "
      "`hpg_mj/ShipPatrol-v0`, the gate passed again and again, leaving the field costs "
      f"{task.config.environment.out_of_bounds_reward:g} and restarts the ship. The root is "
      "average-reward SMDP Q-learning (R-learning, Schwartz 1993, in the SMDP form of "
      "Ghavamzadeh & Mahadevan 2001/2002) over the hybrid's 8 directions; its state is the "
      "50 m cell" + (f" ({root.near_gate_cell_m:g} m within {root.near_gate_m:g} m of the "
                     "gate's centre)" if root.near_gate_m > 0 else "")
      + (f" and the heading in {root.heading_sectors} sectors" if root.heading_sectors > 1
         else "")
      + (f"; it plans (Dyna-Q over each state and direction's latest call, a sweep every "
         f"{root.planning_every} decisions)" if root.planning_every > 0 else "") + "; "
      "the diagonal and straight subtasks are learned by Eq. 3 from scratch in the same run.",
      "",
      f"Protocol: {hours:,} training hours ({hours * 6000:,} control steps) per run, seeds "
      f"{', '.join(map(str, seeds))} (tuning seeds {list(task.tuning_seeds)} never reported)"
      + (", --quick" if quick else "") + f"; seeds looked at while this design was chosen: "
      f"{LOOKED_AT['patrol']}. Each policy then sails "
      f"{finals[0]['evaluation_hours']} greedy hours from one seeded start. The episodic "
      f"hybrid is tasks/ship_hybrid.toml's agent trained for {episodic_note:,} episodes "
      "with the run's seed and sailed greedily on the continuing task.", "",
      "| gate passes per hour (mean [95% bootstrap CI]) | value | per seed |",
      "|---|---|---|",
      row("average-reward root, greedy", "greedy_gates_per_hour"),
      row("average-reward root, online (last block, exploring)", "online_gates_per_hour"),
      row("episodic hybrid, greedy on the continuing task", "episodic_gates_per_hour"),
      row("scripted figure-eight helmsman", "scripted_gates_per_hour"), "",
      _paired(finals), "", PATROL_HISTORY, "",
      "![continuing ship task](beyond_patrol.png)", "",
      "Data: beyond_patrol.csv (curves), beyond_patrol_final.csv and seed*.json (final "
      "numbers).", ""]
  return lines


def _paired(finals):
  """The paired difference average-reward root minus episodic hybrid, seed by seed,
  and whether its interval excludes 0 (only then is either called better)."""
  from hpg_mj.experiments import stats
  pairs = [(f["greedy_gates_per_hour"], f["episodic_gates_per_hour"]) for f in finals
           if f.get("episodic_gates_per_hour") is not None]
  if not pairs:
    return "No episodic comparison in this run."
  d = [a - b for a, b in pairs]
  mean, low, high = stats.mean_ci(d)
  wins = sum(v > 0 for v in d)
  verdict = ("the average-reward root passes the gate more often" if low > 0 else
             "the episodic hybrid passes the gate more often" if high < 0 else
             "the two cannot be told apart (the interval contains 0)")
  return (f"Paired by seed, average-reward root minus episodic hybrid: {mean:+.1f} "
          f"[{low:+.1f}, {high:+.1f}] gate passes per hour; the root is ahead on {wins} of "
          f"{len(d)} seeds: {verdict}.")
