"""Videos of trained agents: one greedy episode through the agent's Gymnasium
environment, its frames streamed to the encoder (any agent: only the agent
interface is used).

A frame costs ~10,000 times a control step (it is drawn by the render worker,
SPEC section 9), so the episode is sailed twice from the same seed: once
without pictures to learn its length, then again drawing only the frames kept,
every `stride`-th step, so that a long episode still makes a short video
(`max_frames`). Nothing is held in memory but the frame being written.
"""
import math

from hpg_mj.hierarchy import executor

DEFAULT_WIDTH, DEFAULT_HEIGHT = 320, 240   # a frame ~4x cheaper than 640 x 480
DEFAULT_MAX_FRAMES = 200                   # 10 s of video at 20 frames per second
HOLD_LAST = 10                             # the last frame is held so the end is seen


class _CountingAdapter(executor.GymAdapter):
  """A Gymnasium adapter that counts the steps of the episode (the dry run)."""

  def __init__(self, env):
    super().__init__(env)
    self.steps = 0

  def step(self, action):
    self.steps += 1
    return super().step(action)


class _StreamingAdapter(executor.GymAdapter):
  """A Gymnasium adapter that renders every `stride`-th step, and the last, straight
  into `writer`; `progress(steps)` is told after each step."""

  def __init__(self, env, writer, stride, progress):
    super().__init__(env)
    self.writer, self.stride, self.progress = writer, stride, progress
    self.steps = 0
    self.frames = 0
    self._last = None

  def _frame(self):
    self._last = self.env.render()
    self.writer.append_data(self._last)
    self.frames += 1

  def reset(self, start=None):
    obs = super().reset(start)
    self.steps = 0
    self._frame()
    return obs

  def step(self, action):
    step = super().step(action)
    self.steps += 1
    if self.steps % self.stride == 0 or step.terminated or step.truncated:
      self._frame()
    self.progress(self.steps)
    return step

  def hold(self, count):
    for _ in range(count):
      self.writer.append_data(self._last)
    self.frames += count


def frame_stride(steps, max_frames):
  """The smallest stride that films a `steps`-step episode in at most `max_frames`
  frames (the first, every stride-th step, the last, and the held ending)."""
  if max_frames < HOLD_LAST + 2:
    raise ValueError(f"max_frames must be at least {HOLD_LAST + 2} (the first and last "
                     f"frames and {HOLD_LAST} held at the end), got {max_frames}")
  return max(1, math.ceil(steps / (max_frames - HOLD_LAST - 1)))


def render_agent(agent, path, seed=0, width=DEFAULT_WIDTH, height=DEFAULT_HEIGHT, fps=None,
                 backend="mujoco", max_frames=DEFAULT_MAX_FRAMES, stride=None, progress=None):
  """A video of one greedy episode of `agent`; returns (path, the episode's record).

  `stride`: film every stride-th control step (default: the smallest that keeps
  the video within `max_frames` frames). `progress(done, total)` is told of the
  steps filmed. The file is written as the episode runs (see `video.VideoWriter`).
  """
  from hpg_mj.render import video
  if stride is not None and (not isinstance(stride, int) or stride < 1):
    raise ValueError(f"stride must be a positive integer number of steps, got {stride!r}")
  writer = video.VideoWriter(path, fps=fps or 20)   # checks the path before any work

  # The dry run: the same episode (same seed, greedy), without pictures.
  agent.set_seed(seed)
  env = agent.make_env("gymnasium", backend=backend)
  try:
    counter = _CountingAdapter(env.unwrapped)
    agent.run_stepwise(counter, 1, learn=False)
  finally:
    env.close()
  total = counter.steps
  stride = stride or frame_stride(total, max_frames)

  agent.set_seed(seed)
  env = agent.make_env("gymnasium", backend=backend, render_mode="rgb_array", width=width,
                       height=height)
  if fps is None:
    writer.fps = env.metadata.get("render_fps", 20)
  streaming = _StreamingAdapter(env.unwrapped, writer, stride,
                                lambda done: progress and progress(done, total))
  try:
    with writer:
      record = agent.run_stepwise(streaming, 1, learn=False)
      streaming.hold(HOLD_LAST)
  finally:
    env.close()
  if streaming.steps != total:
    raise RuntimeError(f"render_agent: the filmed episode took {streaming.steps} steps, the "
                       f"dry run {total}: the agent's greedy episode is not reproducible "
                       "from its seed")
  return writer.path, record
