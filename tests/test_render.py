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


@pytest.mark.parametrize("domain", ["ship_harbour", "ship_goal"])
def test_a_ladder_task_is_filmed_at_its_level_by_the_planners_helmsman(tmp_path, capsys, domain):
  """`hpg-mj render --domain ship_harbour --task hard`: the ladder's domains, their
  levels as tasks, the scripted helmsman the planners' (`cli_render.LadderPilot`)."""
  from hpg_mj import cli
  out = tmp_path / f"{domain}.gif"
  assert cli.main(["render", "--domain", domain, "--task", "hard", "--seed", "1", "--out",
                   str(out), "--width", "160", "--height", "128", "--max-steps", "12"]) == 0
  assert capsys.readouterr().out.startswith(f"wrote {out} (")
  _check_frames([np.asarray(f)[..., :3] for f in imageio.mimread(out)])
  assert cli.main(["render", "--domain", domain, "--task", "steer", "--out",
                   str(tmp_path / "x.gif")]) == 2
  assert capsys.readouterr().err == (f"hpg-mj render: error: --task 'steer': the task of "
                                     f"{domain} is its level; valid: easy, medium, hard\n")
  with pytest.raises(SystemExit):
    cli.main(["render", "--level", "hard", "--out", str(tmp_path / "z.gif")])
  assert capsys.readouterr().err == (
      "hpg-mj render: error: --level hard: --domain ship has no levels; the ladder's domains "
      "have them: ship_current, ship_goal, ship_regatta, ship_harbour (see hpg-mj render "
      "--help)\n")
  with pytest.raises(SystemExit):         # a newcomer's: two levels, read as one muddle
    cli.main(["render", "--domain", domain, "--task", "easy", "--level", "hard"])
  assert capsys.readouterr().err == (
      f"hpg-mj render: error: --level hard and --task easy both name the level of {domain}; "
      "give one of them (see hpg-mj render --help)\n")
  with pytest.raises(ValueError, match=r"the scripted helmsman of ship_goal is the planners'"):
    video.render_task("ship_goal", "easy", out=tmp_path / "y.gif")


def test_a_users_own_policy_is_filmed_as_hpg_mj_evaluate_scores_it(tmp_path, capsys):
  """`hpg-mj render --policy path/file.py:name`: the user's function (or an object
  with `predict`), loaded and checked as `hpg-mj evaluate --policy` does, on a
  benchmark task; elsewhere, or a policy that does not load, one line."""
  from hpg_mj import cli
  (tmp_path / "mine.py").write_text(
      "import numpy as np\n"
      "def hard_left(obs):\n"
      "  return np.array([15.0])\n"
      "def ahead(obs):\n"
      "  return 0.0\n"
      "class Model:\n"
      "  def predict(self, obs, deterministic=True):\n"
      "    return np.full((len(obs['observation']), 1), -15.0), None\n"
      "model = Model()\n")
  out = tmp_path / "left.gif"
  assert cli.main(["render", "--policy", f"{tmp_path / 'mine.py'}:hard_left", "--seed", "2",
                   "--backend", "analytic", "--max-steps", "9", "--width", "160",
                   "--height", "128", "--stride", "3", "--out", str(out)]) == 0
  assert capsys.readouterr().out.startswith(f"wrote {out} (")
  frames = [np.asarray(f)[..., :3] for f in imageio.mimread(out)]
  _check_frames(frames)
  # --seed 1000000 + i films the start `hpg-mj evaluate` scores as its start i (on the
  # steering ship a start drawn as the agents draw theirs, not reset(seed=S))
  from hpg_mj import benchmark
  steps = benchmark.evaluate(lambda obs: 0.0, "ship", 2, progress=False).record["steps"]
  assert cli.main(["render", "--policy", f"{tmp_path / 'mine.py'}:ahead", "--seed", "1000001",
                   "--backend", "analytic", "--width", "32", "--height", "32", "--stride",
                   "100", "--out", str(tmp_path / "ahead.gif")]) == 0
  assert f": {int(steps[1])} steps, return" in capsys.readouterr().out
  assert cli.main(["render", "--policy", f"{tmp_path / 'mine.py'}:model", "--domain",
                   "ship_goal", "--level", "easy", "--max-steps", "3", "--out",
                   str(tmp_path / "model.gif")]) == 0      # SB3's predict, on a batch of 1
  capsys.readouterr()
  assert cli.main(["render", "--policy", f"{tmp_path / 'mine.py'}:Model", "--domain",
                   "ship_goal", "--out", str(tmp_path / "class.gif")]) == 2   # the class
  assert capsys.readouterr().err == ("hpg-mj render: error: policy is the class Model, not an "
                                     "object of it; pass one: Model()\n")
  assert cli.main(["render", "--policy", f"{tmp_path / 'mine.py'}:hard_left", "--task",
                   "patrol", "--out", str(tmp_path / "p.gif")]) == 2
  assert "a policy of your own is filmed on the benchmark's tasks" in capsys.readouterr().err
  with pytest.raises(SystemExit):
    cli.main(["render", "--policy", "clever", "--out", str(tmp_path / "c.gif")])
  assert "give scripted, random, or your own policy as module:name" in capsys.readouterr().err


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
  # bench envs: each ladder task's three rows (dm_control, the analytic batch, the MuJoCo
  # batch) over the steering task's same row (SPEC section 11's bound of one half).
  assert out.count(" the steering task's, interleaved)") == 12


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


def test_a_frame_larger_than_the_offscreen_buffer_is_refused_up_front(tmp_path, capsys):
  """`hpg-mj render --width 5000` had failed in the render worker, after trying every
  OpenGL backend, with advice to install OSMesa; the size is refused first, naming
  the option, the value and the model's limit."""
  from hpg_mj import _assets, cli
  from hpg_mj.envs import taxi
  assert _assets.offscreen_buffer("ship.xml") == (1280, 960)      # assets/ship.xml
  assert taxi.TaxiEnv._MAX_FRAME == _assets.offscreen_buffer("taxi.xml")
  for argv, option, value, name, limit in (
      (["--width", "5000", "--height", "5000"], "--width", 5000, "ship.xml", 1280),
      (["--height", "961"], "--height", 961, "ship.xml", 960),
      (["--domain", "taxi", "--width", "1281"], "--width", 1281, "taxi.xml", 1280)):
    out = tmp_path / "clip.mp4"
    assert cli.main(["render", "--out", str(out)] + argv) == 2
    attribute = "offwidth" if option == "--width" else "offheight"
    assert capsys.readouterr().err == (
        f"hpg-mj render: error: {option} {value} is more than the {name} model's offscreen "
        f"buffer holds (its <visual><global {attribute}>); allowed: at most {limit} pixels\n")
    assert not out.exists()
  with pytest.raises(ValueError, match=r"ShipSteering\(steer, backend=analytic\): height 1000 "
                     r"is more than the ship.xml model's .* at most 960 pixels"):
    gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic", render_mode="rgb_array",
                   height=1000)
  gymnasium.make("hpg_mj/ShipSteering-v0", height=1000)    # no frames: no limit


def test_an_agents_video_larger_than_the_buffer_is_refused_before_its_episode(tmp_path, capsys):
  from hpg_mj import cli
  assert cli.main(["train", "taxi_fuel_flat_q", "--episodes", "5", "--quiet",
                   "--out", str(tmp_path / "agent")]) == 0
  capsys.readouterr()
  assert cli.main(["render", "--agent", str(tmp_path / "agent"), "--height", "5000",
                   "--out", str(tmp_path / "a.mp4"), "--quiet"]) == 2
  assert capsys.readouterr().err == (
      "hpg-mj render: error: --height 5000 is more than the taxi.xml model's offscreen buffer "
      "holds (its <visual><global offheight>); allowed: at most 960 pixels\n")
  assert not (tmp_path / "a.mp4").exists()
