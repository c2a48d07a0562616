"""The options a learned hierarchy found, drawn on the ship's field (an "options"
figure): a run's final option-critic agent sails greedily from given starts on the
analytic ship, and each control step of its path is coloured by the option that
chose it; a dot marks where each call of an option began, a cross where it ended
(its learned termination, or the episode's end). Returns, per option, its calls,
their mean length in control steps and the mean place where they began and ended,
so that the report can say in words what the picture shows."""
import pathlib

import numpy as np

from hpg_mj.worlds import ship_core as core


def sail(agent, start):
  """One greedy episode of a ship agent from `start` on the analytic ship: (path,
  [(option, first step, last step)], record row). Step i of the path goes from
  path[i] to path[i + 1]."""
  from hpg_mj.experiments import fig12
  env = agent.make_env("gymnasium", backend="analytic")
  path, calls = [], []

  def on_call(call):                    # told before the step the call takes first
    calls.append([call.node, len(path) - 1, None])

  try:
    record = agent.run_stepwise(fig12.traced(env.unwrapped, path), 1, learn=False,
                                start=start, on_call=on_call)
  finally:
    env.close()
  for k, call in enumerate(calls):
    call[2] = (calls[k + 1][1] if k + 1 < len(calls) else len(path) - 1)
  return np.array(path), [tuple(c) for c in calls], record[0]


def draw(agent, out, starts, name="options", title="The learned options"):
  """Writes <name>.png; returns {"starts": [per start: passed, steps, calls], "options":
  {option: calls, mean_steps, began (mean x, y), ended (mean x, y)}}."""
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  out = pathlib.Path(out)
  out.mkdir(parents=True, exist_ok=True)
  fig, ax = plt.subplots(figsize=(6.5, 6.0))
  ax.plot([0, core.FIELD_SIZE, core.FIELD_SIZE, 0, 0], [0, 0, core.FIELD_SIZE,
          core.FIELD_SIZE, 0], color="firebrick", linewidth=1)
  ax.plot(core.GATE[:, 0], core.GATE[:, 1], color="goldenrod", linewidth=4, label="gate")
  colours = plt.get_cmap("tab10")
  names = {}
  per_option = {}
  per_start = []
  for start in starts:
    path, calls, row = sail(agent, start)
    for option, first, last in calls:
      k = names.setdefault(option, len(names))
      colour = colours(k % 10)
      ax.plot(path[first:last + 1, 0], path[first:last + 1, 1], color=colour, linewidth=1.2)
      ax.plot(*path[first, :2], "o", color=colour, markersize=2.0)
      ax.plot(*path[last, :2], "x", color=colour, markersize=2.5)
      seen = per_option.setdefault(option, {"calls": 0, "steps": [], "began": [], "ended": []})
      seen["calls"] += 1
      seen["steps"].append(last - first)
      seen["began"].append(path[first, :2])
      seen["ended"].append(path[last, :2])
    per_start.append({"start": [float(v) for v in start], "passed": bool(row["passed"]),
                      "steps": int(row["steps"]), "calls": len(calls)})
  for option, k in names.items():
    s = per_option[option]
    ax.plot([], [], color=colours(k % 10),
            label=f"{option}: {s['calls']} calls, {np.mean(s['steps']):.1f} steps each")
  ax.set_xlim(-20, core.FIELD_SIZE + 20)
  ax.set_ylim(-20, core.FIELD_SIZE + 20)
  ax.set_aspect("equal")
  ax.set_xlabel("x (m)")
  ax.set_ylabel("y (m)")
  ax.set_title(f"{title}\n(dots: an option called, crosses: it ended)", fontsize=10)
  ax.legend(loc="upper left", fontsize=7)
  fig.tight_layout()
  fig.savefig(out / f"{name}.png", dpi=110)
  plt.close(fig)
  options = {option: {"calls": s["calls"], "mean_steps": float(np.mean(s["steps"])),
                      "began": [float(v) for v in np.mean(s["began"], axis=0)],
                      "ended": [float(v) for v in np.mean(s["ended"], axis=0)]}
             for option, s in sorted(per_option.items())}
  return {"starts": per_start, "options": options}
