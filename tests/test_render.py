"""Headless videos: frames are drawn, not blank, and change; files are written."""
import pathlib

import gymnasium
import imageio.v2 as imageio
import numpy as np
import pytest

import hpg_mj  # noqa: F401
from hpg_mj.render import video
from hpg_mj.worlds import taxi_pilot


def _check_frames(frames):
  assert len(frames) >= 3
  for frame in frames:
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert frame.std() > 5.0                           # not blank
  assert any(np.abs(a.astype(int) - b).sum() > 0 for a, b in zip(frames, frames[1:]))


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_ship_clip_is_written_and_moves(tmp_path, suffix):
  path, summary = video.render_task("ship", "steer", policy="scripted", seed=3,
                                    out=tmp_path / f"clip{suffix}", width=160, height=128,
                                    max_steps=12, frame_every=3)
  assert summary["steps"] == 12
  frames = [np.asarray(f)[..., :3] for f in imageio.mimread(path)]
  _check_frames(frames)


def test_taxi_clip_is_written_and_moves(tmp_path):
  path, summary = video.render_task("taxi", "fuel", policy="scripted", seed=1,
                                    out=tmp_path / "taxi.mp4", width=160, height=160,
                                    max_steps=5)
  assert summary["steps"] == 5
  _check_frames([f for f in imageio.mimread(path)])


def test_random_policy_and_bad_arguments(tmp_path):
  with pytest.raises(ValueError, match=r"unknown policy 'clever'.*\['scripted', 'random'\]"):
    env = gymnasium.make("hpg_mj/ShipSteering-v0").unwrapped
    video.make_policy(env, "ship", "steer", "clever")
  with pytest.raises(ValueError, match="valid: .*ship/steer"):
    video.render_task("ship", "race", out=tmp_path / "x.mp4")
  with pytest.raises(ValueError, match=r"must end in \.mp4 or \.gif"):
    video.write_video([np.zeros((16, 16, 3), np.uint8)], tmp_path / "x.avi")


@pytest.mark.parametrize("fuel,env_id", [(True, "hpg_mj/TaxiFuel-v0"), (False, "hpg_mj/Taxi-v0")])
def test_scripted_taxi_always_delivers(fuel, env_id):
  env = gymnasium.make(env_id)
  pilot = taxi_pilot.TaxiPilot(fuel)
  for seed in range(100):
    obs, _ = env.reset(seed=seed)
    terminated = truncated = False
    total = 0
    while not (terminated or truncated):
      obs, reward, terminated, truncated, _ = env.step(pilot(obs))
      total += reward
    assert terminated and total >= 0, (seed, total)


def test_the_demo_runs_every_command_and_replaces_its_own_videos(tmp_path, capsys):
  """`hpg-mj demo` ends the README's main job (scripts/run.sh), which runs again over
  its own earlier videos."""
  from hpg_mj import cli
  videos = [pathlib.Path(argv[argv.index("--out") + 1])
            for argv in cli._demo_commands(tmp_path, 0.05) if argv[0] == "render"]
  for path in videos:
    path.write_bytes(b"an earlier demo's video")
  assert cli.main(["demo", "--out", str(tmp_path), "--seconds", "0.05"]) == 0
  for path in videos:
    _check_frames([np.asarray(f)[..., :3] for f in imageio.mimread(path)])
  out = capsys.readouterr().out
  assert "bounds (< 0.25 m" in out and "Gymnasium Taxi-v4" in out    # verify, bench envs


def test_the_main_job_writes_only_where_git_does_not_look():
  """scripts/run.sh (the README's main job) and `hpg-mj render` without --out write
  only to folders git ignores: a fresh clone's `git status` stays clean after them
  (the demo had written its video over the tracked videos/ship_steer_scripted.mp4)."""
  import shlex
  import shutil
  import subprocess

  from hpg_mj import cli
  root = pathlib.Path(__file__).resolve().parents[1]
  if shutil.which("git") is None or not (root / ".git").exists():
    pytest.skip("not a git checkout")
  parser, outputs = cli.build_parser(), []
  commands = [line.split("hpg-mj", 1)[1] for line in (root / "scripts" / "run.sh").read_text()
              .splitlines() if "/hpg-mj " in line and not line.lstrip().startswith("#")]
  assert [shlex.split(c)[0] for c in commands] == ["reproduce", "demo"]
  for command in commands:
    args = cli._parse(parser, [a for a in shlex.split(command) if a != "$@"])
    if args.command == "demo":
      outputs += [argv[argv.index("--out") + 1]
                  for argv in cli._demo_commands(args.out, 1.0) if "--out" in argv]
    else:
      outputs.append(f"{args.out}/fig6_quick/REPORT.md")
  defaults = cli._parse(parser, ["demo"])
  outputs += [argv[argv.index("--out") + 1]
              for argv in cli._demo_commands(defaults.out, 1.0) if "--out" in argv]
  outputs += [f"{cli.VIDEOS_OUT}/ship_steer_scripted.mp4", f"{cli.VIDEOS_OUT}/ship_hybrid.gif"]
  assert len(outputs) == 7
  for path in outputs:
    ignored = subprocess.run(["git", "check-ignore", "-q", path], cwd=root)
    assert ignored.returncode == 0, f"{path} is tracked or not ignored by git"
