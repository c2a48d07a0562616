"""Agent videos (hpg_mj.experiments.videos, `hpg-mj render --agent`): streamed, bounded
in length by a frame stride, with progress, and options that do not apply refused."""
import math

import imageio.v2 as imageio
import numpy as np
import pytest

from hpg_mj import agents
from hpg_mj import cli
from hpg_mj.experiments import videos
from hpg_mj.render import video


def _filmed(steps, stride):
  """Frames of a filmed episode: the start, every stride-th step, the last, the hold."""
  return 1 + math.ceil(steps / stride) + videos.HOLD_LAST


def test_frame_stride_is_the_smallest_that_fits():
  for max_frames in (12, 50, 200):
    for steps in list(range(1, 400)) + [432, 4999, 5000]:
      stride = videos.frame_stride(steps, max_frames)
      assert _filmed(steps, stride) <= max_frames, (steps, max_frames)
      if stride > 1:
        assert _filmed(steps, stride - 1) > max_frames, (steps, max_frames)
  assert videos.frame_stride(432, 200) == 3
  with pytest.raises(ValueError, match="max_frames must be at least 12"):
    videos.frame_stride(100, 11)


def test_render_agent_streams_a_bounded_video(tmp_path):
  agent = agents.build(agents.load_task("ship_hybrid"), seed=0)
  agent.train(50, "analytic")
  seen = []
  path, record = videos.render_agent(agent, tmp_path / "a.mp4", seed=1, width=96, height=80,
                                     max_frames=16, progress=lambda d, t: seen.append((d, t)))
  steps = int(record["steps"][0])
  stride = videos.frame_stride(steps, 16)
  frames = imageio.mimread(path)
  assert stride >= 4 and len(frames) == _filmed(steps, stride) <= 16
  assert frames[0].shape == (80, 96, 3) and np.asarray(frames[0]).std() > 5
  # Progress: every step, out of the dry run's count.
  assert seen == [(i, steps) for i in range(1, steps + 1)]
  # The same seed films the same episode; another stride, another number of frames.
  # (An MP4: a GIF writer merges identical frames.)
  path, again = videos.render_agent(agent, tmp_path / "b.mp4", seed=1, width=96, height=80,
                                    stride=stride // 2)
  np.testing.assert_array_equal(again, record)
  assert len(imageio.mimread(path)) == _filmed(steps, stride // 2)


def test_video_writer_checks_and_cleans_up(tmp_path):
  with pytest.raises(ValueError, match=r"must end in \.mp4 or \.gif"):
    video.VideoWriter(tmp_path / "x.avi")
  with pytest.raises(ValueError, match="fps must be a positive number"):
    video.VideoWriter(tmp_path / "x.mp4", fps=0)
  path = tmp_path / "partial.mp4"
  with pytest.raises(RuntimeError, match="boom"):
    with video.VideoWriter(path) as writer:
      writer.append_data(np.zeros((16, 16, 3), np.uint8))
      raise RuntimeError("boom")
  assert not path.exists()
  with pytest.raises(ValueError, match="no frames to write"):
    with video.VideoWriter(tmp_path / "empty.mp4"):
      pass


@pytest.mark.parametrize("extra, named", [
    (["--task", "diagonal"], "--task"), (["--policy", "random"], "--policy"),
    (["--domain", "taxi"], "--domain"), (["--max-steps", "50"], "--max-steps"),
    (["--task", "steer", "--policy", "scripted"], "--task, --policy"),
])
def test_render_refuses_task_options_with_an_agent(capsys, extra, named):
  with pytest.raises(SystemExit) as exit_info:
    cli.main(["render", "--agent", "some/agent", *extra])
  assert exit_info.value.code == 2
  err = capsys.readouterr().err
  assert f"{named} cannot be used with --agent" in err and "--max-frames" in err


@pytest.mark.parametrize("argv, message", [
    (["render", "--max-frames", "50"], "--max-frames only applies with --agent"),
    (["render", "--agent", "a", "--stride", "0"], "--stride must be a positive integer, got 0"),
    (["render", "--width", "-3"], "--width: -3 is out of range; allowed: >= 16"),
])
def test_render_refuses_options_that_do_not_apply(capsys, argv, message):
  with pytest.raises(SystemExit):
    cli.main(argv)
  err = capsys.readouterr().err
  assert message in err and err.startswith("hpg-mj render: error: ")


def test_quick_trajectory_films_use_the_quick_size(monkeypatch, tmp_path):
  from hpg_mj.experiments import figures, fig12, runner
  seen = []
  monkeypatch.setattr(fig12, "draw", lambda agent, root, **kw: seen.append(
      (kw["width"], kw["height"], kw["frame_every"])) or [])
  fig = next(f for f in runner.load_experiment("fig12")["figures"] if f["kind"] == "trajectories")
  assert (fig["quick_width"], fig["quick_height"], fig["quick_frame_every"]) == (320, 240, 4)
  figures.draw_trajectories(tmp_path, fig, None, quick=True)
  figures.draw_trajectories(tmp_path, fig, None)
  assert seen == [(320, 240, 4), (640, 480, 2)]
