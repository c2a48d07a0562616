"""Videos of trained agents: one greedy episode through the agent's Gymnasium
environment on the MuJoCo world, rendered frame by frame (any agent: only the
agent interface is used)."""
from hpg_mj.hierarchy import executor


class _RecordingAdapter(executor.GymAdapter):
  """A Gymnasium adapter that also keeps a rendered frame of every step."""

  def __init__(self, env):
    super().__init__(env)
    self.frames = []

  def reset(self, start=None):
    obs = super().reset(start)
    self.frames = [self.env.render()]
    return obs

  def step(self, action):
    step = super().step(action)
    self.frames.append(self.env.render())
    return step


def render_agent(agent, path, seed=0, width=640, height=480, fps=None):
  """A video of one greedy episode of `agent`; returns (path, the episode's record)."""
  from hpg_mj.render import video
  agent.set_seed(seed)
  env = agent.make_env("gymnasium", backend="mujoco", render_mode="rgb_array", width=width,
                       height=height)
  fps = fps or env.metadata.get("render_fps", 20)
  adapter = _RecordingAdapter(env.unwrapped)
  try:
    record = agent.run_stepwise(adapter, 1, learn=False)
  finally:
    env.close()
  frames = adapter.frames[::2] if len(adapter.frames) > 400 else adapter.frames
  frames = frames + [frames[-1]] * 10
  return video.write_video(frames, path, fps=fps), record
