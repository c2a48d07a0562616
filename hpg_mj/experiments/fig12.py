"""Figure 12: the learned hybrid steering the MuJoCo ship from the paper's two
starting states, as a picture (path, gate, the root's decisions marked where each
low-level call began) and as an MP4 (SPEC section 6)."""
import pathlib

import numpy as np

from hpg_mj.worlds import ship_core as core

STARTS = ((700.0, 700.0, 100.0, 3.65), (750.0, 180.0, 80.0, 7.9))


def sail(agent, start):
  """One greedy episode of a ship agent from `start` on the MuJoCo ship: (path, the
  root's decisions as (x, y, direction) where each call began, record row)."""
  env = agent.make_env("gymnasium", backend="mujoco")
  path, decisions = [], []

  def on_call(call):
    if "direction" in call.args:           # a call of the root's (a compass direction)
      decisions.append((float(call.origin[0]), float(call.origin[1]),
                        int(call.args["direction"])))

  try:
    record = agent.run_stepwise(traced(env.unwrapped, path), 1, learn=False, start=start,
                                on_call=on_call)
  finally:
    env.close()
  return np.array(path), decisions, record[0]


def traced(env, path):
  """`env` (a Gymnasium environment) for the step-by-step path, appending every
  observation it gives to `path`."""
  from hpg_mj.hierarchy import executor

  class Tracing(executor.GymAdapter):
    def reset(self, start=None):
      obs = super().reset(start)
      path.append(np.array(obs))
      return obs

    def step(self, action):
      step = super().step(action)
      path.append(np.array(step.obs))
      return step

  return Tracing(env)


def draw(agent, out, video=True, width=640, height=480, starts=STARTS, name="fig12",
         title="Learned hybrid from the paper's two starts (dots: root decisions)",
         frame_every=2):
  """Writes <name>.png and, with `video`, <name>_<k>.mp4 for each start (a frame
  every `frame_every` control steps, and the last); returns a summary per start."""
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  out = pathlib.Path(out)
  out.mkdir(parents=True, exist_ok=True)
  fig, ax = plt.subplots(figsize=(6.0, 6.0))
  ax.plot([0, 1000, 1000, 0, 0], [0, 0, 1000, 1000, 0], color="firebrick", linewidth=1)
  ax.plot(core.GATE[:, 0], core.GATE[:, 1], color="goldenrod", linewidth=4, label="gate")
  summary = []
  scene = None
  if video:                  # one render worker for every film (each start costs ~1.4 s)
    from hpg_mj.render import scenes
    scene = scenes.ShipScene(width, height)
  try:
    for k, start in enumerate(starts):
      summary.append(_sail_and_draw(agent, ax, start, scene,
                                    out / f"{name}_{k}.mp4", frame_every))
  finally:
    if scene is not None:
      scene.close()
  ax.set_xlim(-20, 1020)
  ax.set_ylim(-20, 1020)
  ax.set_aspect("equal")
  ax.set_xlabel("x (m)")
  ax.set_ylabel("y (m)")
  ax.set_title(title)
  ax.legend(fontsize=7, loc="lower left")
  fig.tight_layout()
  fig.savefig(out / f"{name}.png", dpi=100)
  plt.close(fig)
  return summary


def _sail_and_draw(agent, ax, start, scene, film, frame_every):
  """Sails from `start`, draws the path and the root's decisions on `ax`, films it
  with `scene` (None: no film); returns the start's summary."""
  path, decisions, record = sail(agent, start)
  line, = ax.plot(path[:, 0], path[:, 1], linewidth=1.5,
                  label=f"from ({start[0]:.0f}, {start[1]:.0f}, {start[2]:.0f} deg, "
                        f"{start[3]} deg/s)")
  marks = np.array([(x, y) for x, y, _ in decisions])
  ax.scatter(marks[:, 0], marks[:, 1], color=line.get_color(), s=30, zorder=3)
  for x, y, d in decisions:
    ax.annotate(core.DIRECTIONS[d], (x, y), textcoords="offset points", xytext=(5, 5),
                fontsize=8)
  if scene is not None:
    _video(path, marks, film, scene, frame_every)
  return {"start": list(start), "steps": int(record["steps"]),
          "passed": bool(record["passed"]), "calls": len(decisions),
          "decisions": [core.DIRECTIONS[d] for _, _, d in decisions]}


def _video(path, marks, file, scene, frame_every):
  from hpg_mj.render import video
  frames = []
  for i in range(0, len(path), frame_every):
    seen = marks[:max(1, int(np.sum(_reached(path[:i + 1], marks))))]
    frames.append(scene.render(path[i], path[:i + 1, :2], marks=seen))
  frames.append(scene.render(path[-1], path[:, :2], marks=marks))
  frames += [frames[-1]] * 10
  video.write_video(frames, file, fps=max(1, 40 // frame_every))   # 10 control steps a second


def _reached(path, marks):
  """Which decision points the path has reached (within 0.5 m of a sailed position)."""
  return [np.min(np.hypot(*(path[:, :2] - m).T)) < 0.5 for m in marks]
