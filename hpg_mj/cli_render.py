"""`hpg-mj render`: a video of one episode of a task's scripted or trained agent, its
options checked before any frame is drawn."""
import sys


# Where `hpg-mj render` and `hpg-mj demo` write unless told (--out): under runs/,
# which git ignores, so that the main job leaves a clone's `git status` clean; the
# showcase media in videos/ are tracked and remade only on purpose (`--out videos`).
VIDEOS_OUT = "runs/videos"


def _video_out(args, default):
  """The video's path (--out, or `default`; .gif with --gif), checked before any
  frame is drawn."""
  import pathlib

  from hpg_mj import _paths
  from hpg_mj.render import video
  out = pathlib.Path(args.out or default)
  if args.gif and out.suffix.lower() != ".gif":
    out = out.with_suffix(".gif")
  _paths.check_file_out(out, "--out", video.VideoWriter.SUFFIXES)
  if args.out and out.is_file() and not args.force:   # the user's file is not replaced
    raise _paths.OutputRefused(f"--out {out} exists; give another name, or --force to "
                               "replace it")
  return out


def _cmd_render(args):
  from hpg_mj.render import video
  if getattr(args, "agent", None) is not None:
    return _render_agent(args)
  _check_frame_size(MODEL_FILES.get(args.domain, f"{args.domain}.xml"), args)
  own = args.policy not in ("scripted", "random")       # module:name, the user's
  named = args.policy.rsplit(":", 1)[-1] if own else args.policy
  args.out = _video_out(args, f"{VIDEOS_OUT}/{args.domain}_{args.task}_{named}."
                              f"{'gif' if args.gif else 'mp4'}")
  pilot, options = None, None
  if own:
    pilot = _user_pilot(args)
    options = _scored_start(pilot.task, args.seed)
  elif args.domain in video.LADDER_IDS and args.policy == "scripted":
    pilot = LadderPilot(args.domain, args.task)
  path, summary = video.render_task(args.domain, args.task, policy=args.policy, seed=args.seed,
                                    out=args.out, gif=args.gif, width=args.width,
                                    height=args.height, max_steps=args.max_steps,
                                    backend=args.backend,
                                    frame_every=getattr(args, "stride", None), pilot=pilot,
                                    options=options)
  event = summary["info"].get("event") if isinstance(summary["info"], dict) else None
  print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB): {summary['steps']} steps, "
        f"return {summary['return']:.1f}" + (f", ended by {event}" if event else ""))
  return 0


def _scored_start(task, seed):
  """The reset options that lay out the start `hpg-mj evaluate` draws from `seed` (its
  start i from 1000000 + i): on the steering ship and the taxi a start drawn as the
  agents draw theirs, which the environment's reset(seed=seed) is not; None on the
  ladder, whose start is reset(seed=seed) itself."""
  from hpg_mj import benchmark
  if task.name in benchmark.LADDER:
    return None
  return {"state": benchmark.fixed_starts(task, 1, seed=seed)[0]}


# The benchmark's task (`hpg_mj.benchmark.task_of`) of a filmed domain and task, where
# a user's policy can be scored (and so filmed) on it.
_BENCHMARK_TASKS = {("ship", "steer"): "ship", ("taxi", "fuel"): "taxi_fuel",
                    ("taxi", "classic"): "taxi"}


def _user_pilot(args):
  """`--policy module:name`: the user's policy, as `hpg-mj evaluate --policy` loads
  and checks it (`benchmark.Pilot`), on the benchmark's task of --domain/--task."""
  from hpg_mj import benchmark
  from hpg_mj.render import video
  if args.domain in video.LADDER_IDS:
    task = f"{args.domain}/{args.task}"
  elif (args.domain, args.task) in _BENCHMARK_TASKS:
    task = _BENCHMARK_TASKS[(args.domain, args.task)]
  else:
    raise ValueError(f"--policy {args.policy}: a policy of your own is filmed on the "
                     "benchmark's tasks (ship/steer, taxi/fuel, taxi/classic and the ladder's "
                     f"domains), not {args.domain}/{args.task}")
  return benchmark.Pilot(benchmark.load_policy(args.policy), task)


def _render_agent(args):
  """`hpg-mj render --agent DIR`: a greedy episode streamed to the video file."""
  import time

  from tqdm import tqdm

  from hpg_mj import agents
  from hpg_mj.experiments import videos
  if args.out is not None:
    out = _video_out(args, None)         # before the agent is loaded, as without --agent
  agent, _, _ = agents.load(args.agent)
  env = agent.make_env("gymnasium", backend=args.backend)     # which model draws it
  model_file = getattr(env.unwrapped, "model_file", None)
  env.close()
  if model_file is not None:
    _check_frame_size(model_file, args)
  if args.out is None:                   # a user's kind may be "module:Class"
    name = agent.name.replace(":", ".")
    out = _video_out(args, f"{VIDEOS_OUT}/{name}.{'gif' if args.gif else 'mp4'}")
  bar = tqdm(total=None, unit="step", desc=f"filming {agent.name}", dynamic_ncols=True,
             disable=args.quiet or not sys.stderr.isatty())

  def progress(done, total):
    bar.total = total
    bar.update(done - bar.n)
  start = time.perf_counter()
  try:
    path, record = videos.render_agent(agent, out, seed=args.seed, width=args.width,
                                       height=args.height, backend=args.backend,
                                       max_frames=args.max_frames, stride=args.stride,
                                       progress=progress)
  finally:
    bar.close()
  summary = agent.metrics(record)
  print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB) in {time.perf_counter() - start:.1f} s:"
        f" a greedy episode of {args.agent}, {int(record['steps'][0])} steps, return "
        f"{summary['mean_return']:.1f}"
        + (f", gate passed: {bool(summary['gate_pass_rate'])}" if "gate_pass_rate" in summary
           else ""))
  return 0


def _check_frame_size(model_file, args):
  """Refuses --width or --height beyond the model's offscreen buffer before any
  frame is drawn, in the options' names (MuJoCo's refusal, from the render worker,
  read as a missing OpenGL library)."""
  from hpg_mj import _assets
  _assets.check_frame_size(model_file, args.width, args.height, options=("--width", "--height"))


# The MJCF a domain draws with, where it is not "<domain>.xml" (the goal's ship is the
# steering task's, its gate moved).
MODEL_FILES = {"ship_goal": "ship.xml"}


class LadderPilot:
  """The scripted helmsman of a ladder task at a level (`planners.Helmsman`, a batched
  policy), one observation at a time, as `render_task` drives a pilot."""

  def __init__(self, domain, level):
    from hpg_mj import planners
    if level not in ("easy", "medium", "hard"):
      raise ValueError(f"--task {level!r}: the task of {domain} is its level; valid: easy, "
                       "medium, hard")
    self.helmsman = planners.Helmsman(domain, level)

  def reset(self):
    """A new episode: the helmsman keeps nothing between steps."""

  def __call__(self, obs):
    import numpy as np
    batch = ({key: np.asarray(value)[None] for key, value in obs.items()}
             if isinstance(obs, dict) else np.asarray(obs)[None])
    return np.asarray(self.helmsman(batch), dtype=np.float64).reshape(-1)[:1]


# `hpg-mj render` options that film a task's scripted or random policy, not an agent.
RENDER_TASK_ONLY = ("domain", "task", "level", "policy", "max_steps")
RENDER_AGENT_ONLY = ("max_frames",)


def _check_render_args(parser, args):
  """Refuses the options that do not apply (with or without --agent); fills defaults."""
  def flag(name):
    return "--" + name.replace("_", "-")

  def error(message):                # as the subcommands' own: "hpg-mj render: error: ..."
    parser.exit(2, f"{parser.prog} render: error: {message} (see {parser.prog} render "
                   "--help)\n")
  if args.agent is not None:
    given = [flag(n) for n in RENDER_TASK_ONLY if getattr(args, n) is not None]
    if given:
      error(f"{', '.join(given)} cannot be used with --agent (the agent's own "
                   "task and greedy policy are filmed); with --agent use --seed, --out, --gif, "
                   "--width, --height, --backend, --stride, --max-frames, --quiet")
    args.width = args.width or videos_defaults()[0]
    args.height = args.height or videos_defaults()[1]
    args.max_frames = args.max_frames if args.max_frames is not None else videos_defaults()[2]
  else:
    given = [flag(n) for n in RENDER_AGENT_ONLY if getattr(args, n) is not None]
    if given:
      error(f"{', '.join(given)} only applies with --agent")
    args.domain = args.domain or "ship"
    if args.level is not None:
      from hpg_mj.render import video
      if args.domain not in video.LADDER_IDS:
        error(f"--level {args.level}: --domain {args.domain} has no levels; the ladder's "
              "domains have them: ship_current, ship_goal, ship_regatta, ship_harbour")
      if args.task not in (None, args.level):
        error(f"--level {args.level} and --task {args.task} both name the level of "
              f"{args.domain}; give one of them")
      args.task = args.level
    args.task = args.task or {"ship": "steer", "taxi": "fuel"}.get(args.domain, "easy")
    args.policy = args.policy or "scripted"
    args.width = args.width or 640
    args.height = args.height or 480
  for name in ("width", "height", "stride", "max_frames"):
    value = getattr(args, name)
    if value is not None and value < 1:
      error(f"{flag(name)} must be a positive integer, got {value}")


def videos_defaults():
  """The default width and height in pixels and frames at most of `hpg-mj render
  videos`."""
  from hpg_mj.experiments import videos
  return videos.DEFAULT_WIDTH, videos.DEFAULT_HEIGHT, videos.DEFAULT_MAX_FRAMES
