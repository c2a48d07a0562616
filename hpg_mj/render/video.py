"""Videos of episodes: any hpg_mj Gymnasium task under a random or scripted policy."""
import pathlib

import imageio.v2 as imageio
import numpy as np

from hpg_mj.worlds import ship_core as core

POLICIES = ("scripted", "random")
# The continuing task's hour is 6,000 control steps; a video shows its first 10 minutes.
PATROL_VIDEO_STEPS = 1000


class ShipPilot:
  """The scripted helmsman of `ship_core.pilot_turn_rate` as a policy over observations."""

  def __init__(self, task):
    self.task = task
    self.phase = 0
    self.last = None

  def reset(self):
    """A new episode: the helmsman starts over."""
    self.phase = 0
    self.last = None

  def __call__(self, obs):
    if self.task == "patrol":     # the figure-eight helmsman (SPEC section 8)
      if self.last is not None and core.segment_crosses(*self.last[:2], *obs[:2],
                                                        *core.GATE.ravel()):
        self.phase = 0          # passed: swing round for the next pass
      self.last = np.array(obs, dtype=np.float64)
      x, y, self.phase = core.patrol_pilot_target(obs, self.phase)
    elif self.task == "steer":
      x, y, self.phase = core.gate_pilot_target(obs, self.phase)
    else:
      x, y = core.local_goal(1 if self.task == "diagonal" else 2)
    return np.array([core.pilot_turn_rate(obs, x, y)])


class RandomPolicy:
  """Uniform random actions from an action space."""

  def __init__(self, action_space):
    self.action_space = action_space

  def reset(self):
    """A new episode: nothing to reset."""

  def __call__(self, obs):
    return self.action_space.sample()


def make_policy(env, domain, task, policy):
  """The policy `policy` ("random" or "scripted") for task `task` of `domain`."""
  if policy == "random":
    return RandomPolicy(env.action_space)
  if policy != "scripted":
    raise ValueError(f"unknown policy {policy!r}; valid policies: {list(POLICIES)}")
  if domain in LADDER_IDS:
    raise ValueError(f"the scripted helmsman of {domain} is the planners' "
                     "(hpg_mj.planners.Helmsman; hpg-mj render gives it): pass it as pilot")
  if domain == "ship":
    return ShipPilot(task)
  from hpg_mj.worlds import taxi_pilot
  return taxi_pilot.TaxiPilot(fuel=(task == "fuel"))


def record_episode(env, policy, seed=0, max_steps=None, frame_every=1, hold_last=10,
                   options=None):
  """Runs one episode of a Gymnasium env with render_mode="rgb_array", from
  `reset(seed=seed, options=options)`.

  Returns (frames, summary) where summary has the return, the steps and the
  last `info`. Every `frame_every`-th step is drawn, and the last frame is
  repeated `hold_last` times so the ending can be seen.
  """
  if frame_every < 1:
    raise ValueError(f"frame_every must be >= 1, got {frame_every}")
  policy.reset()
  env.action_space.seed(seed)
  obs, info = env.reset(seed=seed, options=options)
  frames = [env.render()]
  total, steps = 0.0, 0
  terminated = truncated = False
  while not (terminated or truncated):
    obs, reward, terminated, truncated, info = env.step(policy(obs))
    total += reward
    steps += 1
    if steps % frame_every == 0 or terminated or truncated:
      frames.append(env.render())
    if max_steps is not None and steps >= max_steps:
      break
  frames.extend([frames[-1]] * hold_last)
  return frames, {"return": total, "steps": steps, "info": info,
                  "terminated": terminated, "truncated": truncated}


class VideoWriter:
  """Streams frames to an MP4 (H.264, through imageio's ffmpeg writer) or, for a .gif
  path, an animated GIF; use as a context manager, `append_data(frame)` per frame.

  The path is checked at once; the file is opened with the first frame (so `fps`
  may still be set until then). A failure inside the `with` removes the partial file.
  """

  SUFFIXES = (".mp4", ".gif")

  def __init__(self, path, fps=20):
    self.path = pathlib.Path(path)
    if self.path.suffix.lower() not in self.SUFFIXES:
      raise ValueError(f"video path {str(self.path)!r} must end in .mp4 or .gif")
    if not fps > 0:
      raise ValueError(f"fps must be a positive number of frames per second, got {fps!r}")
    self.fps = fps
    self.frames = 0
    self._writer = None

  def _open(self):
    self.path.parent.mkdir(parents=True, exist_ok=True)
    if self.path.suffix.lower() == ".gif":
      return imageio.get_writer(self.path, mode="I", duration=1000.0 / self.fps, loop=0)
    return imageio.get_writer(self.path, fps=self.fps, codec="libx264", quality=6,
                              macro_block_size=16, pixelformat="yuv420p")

  def append_data(self, frame):
    """Adds one RGB frame, opening the file at the first."""
    if self._writer is None:
      self._writer = self._open()
    self._writer.append_data(np.asarray(frame))
    self.frames += 1

  def close(self):
    """Finishes the file."""
    if self._writer is not None:
      self._writer.close()
      self._writer = None

  def __enter__(self):
    return self

  def __exit__(self, kind, error, traceback):
    self.close()
    if kind is not None:
      self.path.unlink(missing_ok=True)
    elif self.frames == 0:
      raise ValueError("no frames to write")


def write_video(frames, path, fps=20):
  """Writes frames to an MP4 (H.264) or, for a .gif path, an animated GIF."""
  if not len(frames):
    raise ValueError("no frames to write")
  with VideoWriter(path, fps=fps) as writer:
    for frame in frames:
      writer.append_data(frame)
  return writer.path


# The task ladder's domains (SPEC section 11): their tasks are the levels.
LADDER_IDS = {"ship_current": "hpg_mj/ShipCurrent-v0", "ship_goal": "hpg_mj/ShipGoal-v0",
              "ship_regatta": "hpg_mj/ShipRegatta-v0", "ship_harbour": "hpg_mj/ShipHarbour-v0"}
LEVELS = ("easy", "medium", "hard")


def render_task(domain, task, policy="scripted", seed=0, out=None, gif=False, width=640,
                height=480, max_steps=None, backend="mujoco", fps=20, frame_every=None,
                pilot=None, options=None):
  """Renders one episode of a task to a video file; returns (path, summary).
  `out`: default `runs/videos/<domain>_<task>_<policy>.mp4` (or .gif), in a folder
  git ignores, never over the repository's showcase videos. A ladder domain's
  (`LADDER_IDS`) task is its level; its scripted `pilot` (a function of one
  observation, `hpg-mj render` gives the planners' helmsman) is the caller's.
  `pilot`, where given, is filmed (with `reset()` and a call per observation; `policy`
  then only names the file), else `policy` ("scripted" or "random"). `options`: the
  reset's (a start: {"state": ...})."""
  import gymnasium

  import hpg_mj  # noqa: F401  (registers the ids)
  ids = {("ship", "steer"): "hpg_mj/ShipSteering-v0",
         ("ship", "diagonal"): "hpg_mj/ShipSteeringDiagonal-v0",
         ("ship", "straight"): "hpg_mj/ShipSteeringStraight-v0",
         ("ship", "patrol"): "hpg_mj/ShipPatrol-v0",
         ("taxi", "fuel"): "hpg_mj/TaxiFuel-v0",
         ("taxi", "classic"): "hpg_mj/Taxi-v0"}
  kwargs = {"render_mode": "rgb_array", "width": width, "height": height}
  if domain in LADDER_IDS:
    if task not in LEVELS:
      raise ValueError(f"unknown level {task!r} of {domain}; valid: {list(LEVELS)}")
    env_id = LADDER_IDS[domain]
    kwargs["level"] = task
  elif (domain, task) in ids:
    env_id = ids[(domain, task)]
  else:
    raise ValueError(f"unknown domain/task {domain}/{task}; valid: "
                     f"{sorted(f'{d}/{t}' for d, t in ids)} and {sorted(LADDER_IDS)}/"
                     f"{'|'.join(LEVELS)}")
  if domain != "taxi":
    kwargs["backend"] = backend
  if task == "patrol" and max_steps is None:
    max_steps = PATROL_VIDEO_STEPS
  env = gymnasium.make(env_id, **kwargs).unwrapped
  try:
    if pilot is None:
      pilot = make_policy(env, domain, task, policy)
    if frame_every is None:
      frame_every = 1 if domain == "taxi" else 2
    frames, summary = record_episode(env, pilot, seed=seed, max_steps=max_steps,
                                     frame_every=frame_every, options=options)
  finally:
    env.close()
  if out is None:
    out = pathlib.Path("runs", "videos") / f"{domain}_{task}_{policy}.{'gif' if gif else 'mp4'}"
  out = pathlib.Path(out)
  if gif and out.suffix.lower() != ".gif":
    out = out.with_suffix(".gif")
  fps = 4 if domain == "taxi" else fps
  return write_video(frames, out, fps=fps), summary
