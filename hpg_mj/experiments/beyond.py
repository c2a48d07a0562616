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
"""
import json
import pathlib
import time

import numpy as np

TASK = "ship_patrol_average_reward"
SEEDS = (100, 101, 102, 103, 104)       # outside the tuning seeds 0-9
# (seeds, training hours, block hours, greedy hours per point, hybrid episodes (0:
# its file's), final evaluation hours)
FULL = (SEEDS, 2500, 125, 10, 0, 100)
QUICK = (SEEDS[:2], 750, 75, 5, 10000, 20)


def run(out, quick=False, progress=None):
  """Trains and measures every seed; returns the report's path."""
  from hpg_mj import agents
  seeds, hours, block, probe_hours, episodic_episodes, eval_hours = QUICK if quick else FULL
  root = pathlib.Path(out) / ("beyond_quick" if quick else "beyond")
  root.mkdir(parents=True, exist_ok=True)
  task = agents.load_task(TASK)
  curves, finals = [], []
  for seed in seeds:
    start = time.perf_counter()
    agent = agents.build(task, seed=seed)
    online, greedy = [], []
    for _ in range(hours // block):
      record = agent.train(block)
      online.append(agent.metrics(record)["gates_per_hour"])
      greedy.append(agent.metrics(agent.evaluation(probe_hours))["gates_per_hour"])
    agent.config = _with_comparison(agent.config, episodic_episodes, eval_hours)
    final = agent.final_metrics(record)
    final.update({"seed": seed, "training_hours": hours,
                  "online_gates_per_hour": online[-1],
                  "wall_seconds": round(time.perf_counter() - start, 1)})
    curves.append((online, greedy))
    finals.append(final)
    (root / f"seed{seed}.json").write_text(json.dumps(final, indent=1))
    if progress is not None:
      progress(seed, final)
  x = (np.arange(hours // block) + 1.0) * block
  _draw(root, x, curves, finals)
  return _report(root, task, seeds, hours, finals, quick)


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
  plt.title("Continuing ship task: gate passes per hour of sailing")
  plt.xlabel("training hours (6,000 control steps each)")
  plt.ylabel("gate passes per hour")
  plt.legend(fontsize=8)
  plt.tight_layout()
  plt.savefig(root / "beyond_patrol.png", dpi=100)
  plt.close()
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


def _mean_ci(values, rng_seed=0, n_boot=2000):
  """Mean and a 95% bootstrap interval (SPEC section 7)."""
  v = np.asarray(values, dtype=np.float64)
  rng = np.random.default_rng(rng_seed)
  boots = rng.choice(v, (n_boot, len(v))).mean(axis=1)
  return float(v.mean()), float(np.percentile(boots, 2.5)), float(np.percentile(boots, 97.5))


def _report(root, task, seeds, hours, finals, quick):
  def row(label, key):
    values = [f[key] for f in finals if f.get(key) is not None]
    if not values:
      return f"| {label} | - | - |"
    mean, low, high = _mean_ci(values)
    return (f"| {label} | {mean:.1f} [{low:.1f}, {high:.1f}] | "
            f"{', '.join(f'{v:.1f}' for v in values)} |")
  episodic_note = finals[0].get("episodic_episodes")
  lines = [
      "# Beyond the paper: the continuing ship task (SPEC section 8)", "",
      "The paper (section 6) names a hierarchy with a continuing root whose performance is "
      "the average reward, and leaves its results out. Here: `ship/patrol` / "
      "`hpg_mj/ShipPatrol-v0`, the gate passed again and again, leaving the field costs "
      f"{task.config.environment.out_of_bounds_reward:g} and restarts the ship. The root is "
      "average-reward SMDP Q-learning (R-learning, Schwartz 1993, in the SMDP form of "
      "Ghavamzadeh & Mahadevan 2001/2002) over the hybrid's 8 directions; its state is the "
      "50 m cell" + (f" and the heading in {task.config.root.heading_sectors} sectors"
                     if task.config.root.heading_sectors > 1 else "") + "; "
      "the diagonal and straight subtasks are learned by Eq. 3 from scratch in the same run.",
      "",
      f"Protocol: {hours:,} training hours ({hours * 6000:,} control steps) per run, seeds "
      f"{', '.join(map(str, seeds))} (tuning seeds {list(task.tuning_seeds)} never reported)"
      + (", --quick" if quick else "") + f". Each policy then sails "
      f"{finals[0]['evaluation_hours']} greedy hours from one seeded start. The episodic "
      f"hybrid is tasks/ship_hybrid.toml's agent trained for {episodic_note:,} episodes "
      "with the run's seed and sailed greedily on the continuing task.", "",
      "| gate passes per hour (mean [95% bootstrap CI]) | value | per seed |",
      "|---|---|---|",
      row("average-reward root, greedy", "greedy_gates_per_hour"),
      row("average-reward root, online (last block, exploring)", "online_gates_per_hour"),
      row("episodic hybrid, greedy on the continuing task", "episodic_gates_per_hour"),
      row("scripted figure-eight helmsman", "scripted_gates_per_hour"), "",
      "![continuing ship task](beyond_patrol.png)", "",
      "Data: beyond_patrol.csv (curves), beyond_patrol_final.csv and seed*.json (final "
      "numbers).", ""]
  (root / "REPORT.md").write_text("\n".join(lines))
  return root / "REPORT.md"
