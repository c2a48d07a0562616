"""The `hpg-mj` command line."""
import argparse
import sys

from hpg_mj.cli_experiments import (FIGURE_EXPERIMENTS, _cmd_reproduce, _cmd_run,  # noqa: F401
                                    _cmd_tune)
from hpg_mj.cli_render import VIDEOS_OUT, _check_render_args, _cmd_render
from hpg_mj.cli_types import _Parser, _at_least, _positive_seconds, _render_policy, _seed


# `hpg-mj verify` of the task ladder: the check (hpg_mj.verify_ladder), its header and
# the bounds its `passed` holds.
LADDER_CHECKS = {
    "current": ("verify_current", "ship in a current: {starts} random starts x {controls} "
                "random controls per level, against the continuous ODE (largest position and "
                "heading errors)", "< 0.25 m, < 0.25 deg, <= half the Euler error"),
    "goal": ("verify_goal", "goal-conditioned ship: {starts} episodes per level of the "
             "scripted helmsman on the analytic ship, its turning rates replayed on the MuJoCo "
             "ship", "< 1.5 m apart, the gate's geoms at the rule's, >= 95% same ends, "
             "rangefinders within 1e-6 m of the rays"),
    "regatta": ("verify_regatta", "regatta: {starts} courses per level sailed by the scripted "
                "helmsman on the analytic ship, its turning rates replayed on the MuJoCo and "
                "the continuous ship", "MuJoCo < 0.25 m, < 0.25 deg, <= half the Euler error, "
                "its course's geoms at the rule's, >= 95% the continuous ship's gates and ends"),
    "harbour": ("verify_harbour", "harbour: {starts} episodes per level of the steering "
                "helmsman (blind to the obstacles) on the analytic ship, its turning rates "
                "replayed on the MuJoCo ship", "< 1.5 m apart, >= 95% same ends, "
                "rangefinders within 1e-9 m of the closed form, obstacle geoms at the rule's"),
}


def _cmd_verify(args):
  from hpg_mj import verify
  from hpg_mj import verify_ladder
  if args.what == "golden":
    print(f"golden trajectories from {verify.golden_dir()}, replayed against "
          f"{verify.golden_versions()}", flush=True)
    checks = verify.verify_golden()
    for check in checks:
      print("  " + check.line(), flush=True)
    failed = [c for c in checks if not c.passed]
    print(f"  {len(checks) - len(failed)} of {len(checks)} passed" + (
        f"; FAILED: {', '.join(f'{c.task} {c.path}' for c in failed)}" if failed else ""))
    return 1 if failed else 0
  if args.what in LADDER_CHECKS:
    name, header, bounds = LADDER_CHECKS[args.what]
    check = getattr(verify_ladder, name)
    results = (check(controls=args.controls, starts=args.starts, seed=args.seed)
               if args.what == "current" else check(episodes=args.starts, seed=args.seed))
    print(header.format(starts=args.starts, controls=args.controls))
    for result in results:
      print(result.line())
    ok = all(result.passed for result in results)
    print(f"  bounds ({bounds}):", "met" if ok else "NOT MET")
    return 0 if ok else 1
  if args.what != "ship":
    raise SystemExit(f"hpg-mj verify: unknown check {args.what!r}; valid: ship, current, goal, "
                     "regatta, harbour, golden")
  result = verify.verify_ship(controls=args.controls, starts=args.starts, seed=args.seed)
  print("\n".join(result.lines()))
  # SPEC section 1: within 0.25 m and 0.25 deg, and at most half the Euler model's error.
  ok = (result.mujoco_position_m < verify.POSITION_BOUND_M
        and result.mujoco_heading_deg < verify.HEADING_BOUND_DEG
        and result.mujoco_position_m <= 0.5 * result.euler_position_m)
  print("  bounds (< 0.25 m, < 0.25 deg, <= half the Euler error):", "met" if ok else "NOT MET")
  return 0 if ok else 1



def _cmd_doctor(args):
  from hpg_mj import doctor
  return 1 if doctor.run() else 0


def _cmd_bench(args):
  from hpg_mj import bench
  if args.what == "envs":
    print(bench.format_rows(bench.bench_envs(min_seconds=args.seconds or 1.0)))
  elif args.what == "train":
    seconds = 2.0 if args.seconds is None else args.seconds
    if args.set and not args.task:
      raise ValueError("bench train --set sets keys of the --task files; give them with --task")
    if args.json:
      from hpg_mj import agents
      tasks = args.task or list(agents.shipped_tasks().values())
      import json
      rows = bench.bench_rounds(tasks, seconds, args.rounds, args.set)
      for row in rows[1:] if args.task else ():    # as the plain table's last lines
        row["first_over_this"] = (rows[0]["steps_per_second"] / row["steps_per_second"]
                                  if row["steps_per_second"] else None)
        row["first"] = rows[0]["task"]
      print(json.dumps(rows, indent=2))
    else:
      rows = bench.bench_train(min_seconds=seconds, tasks=args.task, rounds=args.rounds,
                               assignments=args.set)
      print(bench.format_rows(rows))
      for name, _, rate in rows[1:] if args.task else ():
        print(f"{rows[0][0].split(',')[0]} / {name.split(',')[0]}: {rows[0][2] / rate:.2f}x")
  else:
    _bench_experiments(args)
  return 0


# (what, shipped experiments, --quick, the limit in seconds, 20 runs per learner)
EXPERIMENT_BENCHES = (("Figure 6, full protocol", ("fig6",), False, 60),
                      ("Figures 7-11, full protocol", ("fig7_11",), False, 360),
                      ("reproduce all --quick", ("fig6", "fig7_11", "fig12"), True, 120))


def _bench_experiments(args):
  """Times the paper's protocols from scratch, in a temporary folder, on all cores."""
  import contextlib
  import io
  import tempfile
  import time

  from hpg_mj.experiments import cores
  print(f"{'':<28}  {'seconds':>8}  {'limit':>6}   ({cores.available()} cores, "
        f"{args.workers or cores.available()} workers)", flush=True)
  for label, names, quick, limit in EXPERIMENT_BENCHES:
    with tempfile.TemporaryDirectory() as out:
      start = time.perf_counter()
      for name in names:
        with contextlib.redirect_stdout(io.StringIO()):
          rc = _cmd_run(build_parser().parse_args(
              ["run", name, "--out", out, "--quiet"] + (["--quick"] if quick else [])
              + (["--workers", str(args.workers)] if args.workers else [])))
        if rc:
          raise RuntimeError(f"bench experiments: {name} failed")
      seconds = time.perf_counter() - start
    print(f"{label:<28}  {seconds:>8.1f}  {limit:>6}", flush=True)


def _progress_bar(total, quiet, label):
  """A tqdm bar (episodes per second and the current figure), silent off a terminal.
  While numba compiles (the first run after an install; numba caches the result)
  the bar says so, and off a terminal one line on stderr does."""
  import contextlib

  from tqdm import tqdm
  disable = quiet or not sys.stderr.isatty()
  bar = tqdm(total=total, unit="ep", desc=label, disable=disable, dynamic_ncols=True)
  told = []

  def compiling(name):
    if name is None:
      bar.set_description(label)
    elif disable and not quiet and not told:
      told.append(name)
      print(f"{label}: compiling its loop (from {name}); numba caches it for the next runs",
            file=sys.stderr, flush=True)
    else:
      bar.set_description(f"{label} (compiling {name}, cached for the next runs)")

  def update(done, _total, summary):
    bar.update(done - bar.n)
    bar.set_postfix({k: f"{v:.3f}" for k, v in summary.items()})
  return bar, update, _compile_listener(compiling) if not quiet else contextlib.nullcontext()


def _compile_listener(callback):
  """A context in which `callback(function name)` is called when numba starts
  compiling (not loading from its cache) an outermost function, and
  `callback(None)` when it is done."""
  import contextlib

  from numba.core import event

  class Listener(event.Listener):
    depth = 0

    def on_start(self, ev):
      self.depth += 1
      if self.depth == 1:
        function = ev.data["dispatcher"].py_func
        callback(f"{function.__module__.rsplit('.', 1)[-1]}.{function.__qualname__}")

    def on_end(self, ev):
      self.depth -= 1
      if self.depth == 0:
        callback(None)

  @contextlib.contextmanager
  def listening():
    listener = Listener()
    event.register("numba:compile", listener)
    try:
      yield
    finally:
      event.unregister("numba:compile", listener)
  return listening()


def _compile_timer(callback, agent=None):
  """A context after which `callback(seconds)` is told the time numba and XLA (for an
  `agent` that learns in JAX) spent compiling in it (`hpg_mj._compiling.timer`)."""
  from hpg_mj import _compiling
  return _compiling.timer(callback, _compiling.uses_jax(agent))


def _print_metrics(metrics, as_json):
  import json
  if as_json:
    print(json.dumps(metrics))
  else:
    for key, value in metrics.items():
      print(f"{key}: {value}")


def _cmd_train(args):
  import os
  import pathlib
  import shutil
  import time

  import numpy as np

  from hpg_mj import agents
  from hpg_mj import storage
  from hpg_mj.agents import window
  from hpg_mj.experiments import bounds
  if args.resume is not None:
    agent, earlier, out = _resumed(args)
    task, seed, episodes = agent.task, agent.seed, args.episodes
  elif args.task_file is None:
    raise ValueError("give a task file (or a shipped one's name), or --resume AGENT_DIR "
                     "--episodes N to train a saved agent further")
  else:
    task = agents.load_task(args.task_file, args.set)
    seed = task.protocol.seed if args.seed is None else args.seed
    episodes = task.protocol.episodes if args.episodes is None else args.episodes
    out = pathlib.Path(args.out) if args.out else \
        pathlib.Path("runs") / f"{task.path.stem}-seed{seed}"
    storage.check_out(out, args.force)      # refused before training, not after
    agent, earlier = agents.build(task, seed), None
  # Named as the task names itself, as given: its [task] label, else its file's name.
  bar, update, compiling = _progress_bar(episodes, args.quiet or args.json, task.name)
  compile_seconds = []
  try:
    with compiling, _compile_timer(compile_seconds.append, agent):
      start = time.perf_counter()
      record, _ = agents.train_further(agent, episodes, args.backend, update)
      wall = time.perf_counter() - start
  finally:
    bar.close()
  if earlier is not None:              # the saved record, then these episodes'
    record = np.concatenate([earlier, record])
  compiled = sum(compile_seconds, 0.0)
  metrics = agent.metrics(record)
  metrics.update(window.described(agent, len(record)))   # the rows the metrics are over
  metrics.update(bounds.normalized(bounds.task_name(agent), metrics))   # SPEC section 7.1
  metrics.update(agent.final_metrics(record))    # e.g. a continuing agent's comparisons
  # A ladder level's time limit closes episodes before a larger max_steps: the one in force.
  limit = getattr(getattr(agent.config, "environment", None), "episode_steps", None)
  if limit is not None:
    metrics["max_steps"] = limit
  level = (bounds.task_name(agent) or "").partition("/")[2]      # the level it learned at
  if level:
    metrics["level"] = level
  if isinstance(metrics.get("greedy"), dict):    # a greedy measure: normalized too (7.1)
    metrics["greedy"].update(bounds.normalized(bounds.task_name(agent), metrics["greedy"]))
  metrics.update({"task": str(task.path), "seed": seed, "episodes": len(record),
                  "backend": args.backend or agent.backend,
                  # wall = compile + train: numba's and XLA's compiling (numba's 0 once
                  # cached) apart, so that a speed is computed from train_seconds
                  "wall_seconds": round(wall, 3), "compile_seconds": round(compiled, 3),
                  "train_seconds": round(wall - compiled, 3)})
  if earlier is not None:              # `episodes` is the whole record's; these added to it
    metrics.update({"resumed_from": len(earlier), "episodes_added": len(record) - len(earlier)})
  if earlier is None:
    agents.save(agent, out, record, {"metrics": metrics})
  else:                                # the folder replaced only once the new one is whole
    fresh = out.with_name(f"{out.name}.resumed-{os.getpid()}")
    agents.save(agent, fresh, record, {"metrics": metrics})
    old = out.with_name(f"{out.name}.before-{os.getpid()}")
    os.replace(out, old)
    os.replace(fresh, out)
    shutil.rmtree(old)
  metrics["agent_dir"] = str(out)
  _print_metrics(metrics, args.json)
  if not args.json and not args.quiet and any(k.endswith("_normalized") for k in metrics):
    print(f"(the scores above are online: {metrics.get('online_window', 'training')}, "
          f"exploring and learning; the benchmark's score, greedy on the fixed starts: "
          f"hpg-mj evaluate {out})")
  return 0


def _resumed(args):
  """(the agent saved in --resume's folder, its record, the folder) for `hpg-mj train
  --resume`: refuses what the saved agent already fixes (its task file, seed, folder)."""
  import pathlib

  from hpg_mj import agents
  for given, value in (("task file", args.task_file), ("--set", args.set or None),
                       ("--seed", args.seed), ("--out", args.out),
                       ("--force", args.force or None)):
    if value is not None:
      raise ValueError(f"--resume takes no {given}: the saved agent goes on with its own task "
                       "file and generator, into its own folder" + (
                           "; to go on with keys set (a curriculum: environment.level=hard), "
                           "from Python: agents.rebuilt(agent, ['environment.level=hard'])"
                           ".train(n)" if given == "--set" else ""))
  if args.episodes is None:
    raise ValueError("--resume: give --episodes N, the episodes to train further")
  agent, record, _ = agents.load(args.resume)
  if record is None:
    raise ValueError(f"--resume {args.resume}: the folder holds no training record")
  return agent, record, pathlib.Path(args.resume)


def _cmd_evaluate(args):
  import time

  from hpg_mj import agents
  from hpg_mj import benchmark
  from hpg_mj.experiments import bounds
  if args.agent_dir is None:
    if args.policy is None or args.policy in agents.POLICIES:
      raise ValueError("give a saved agent folder, or --policy module:function to score a "
                       "policy of your own")
    return _evaluate_policy(args)
  policy = args.policy or "greedy"
  if policy not in agents.POLICIES:
    raise ValueError(f"--policy {policy!r} with a saved agent: allowed {list(agents.POLICIES)} "
                     "(module:function scores a policy without an agent folder)")
  for flag, value in (("--task", args.task), ("--max-steps", args.max_steps),
                      ("--batched", args.batched or None)):
    if value is not None:
      raise ValueError(f"{flag} is for --policy; a saved agent runs its own task file")
  agent, _, meta = agents.load(args.agent_dir)
  trained = (bounds.task_name(agent) or "").partition("/")[2]     # a ladder task's level
  if args.level is not None:       # its policy at another level of its ladder task
    agent = benchmark.at_level(agent, args.level)
  backend = args.backend or agent.backend
  start = time.perf_counter()
  if args.seed is None:      # SPEC section 7: the fixed seeded start set of every report
    record = agent.evaluate_fixed(args.episodes, backend, policy=policy)
    starts = f"fixed set (start i from seed {agents.base.GREEDY_SEED} + i)"
    if "/" in (bounds.task_name(agent) or ""):      # a ladder task's: the benchmark's
      starts = f"fixed set (start i: the environment's reset(seed={agents.base.GREEDY_SEED} + i))"
  else:
    agent.set_seed(args.seed)
    record = agent.evaluate(args.episodes, backend, policy=policy)
    starts = f"drawn from seed {args.seed}"
  metrics = agent.metrics(record)
  from hpg_mj.agents import window
  # SPEC section 7.1: every score also normalized (none for a subtask or the patrol)
  name = bounds.task_name(agent)          # the benchmark task it acts on, if any
  metrics.update(bounds.normalized(name, metrics))
  if name is not None:
    task, _, level = name.partition("/")
    metrics = {"task": task, **({"level": level} if level else {}),
               **({"trained_level": trained} if trained else {}), **metrics,
               "official": bool(args.seed is None and policy == "greedy" and
                                args.episodes == agents.base.GREEDY_STARTS and
                                benchmark.task_of(agent).standard)}
  metrics.update({"agent_dir": str(args.agent_dir), "episodes": args.episodes,
                  "evaluation_window": window.evaluated(agent, len(record)),
                  "backend": backend, "policy": policy, "starts": starts,
                  "wall_seconds": round(time.perf_counter() - start, 3)})
  _print_metrics(metrics, args.json)
  return 0


def _evaluate_policy(args):
  """`hpg-mj evaluate --policy module:function`: `hpg_mj.benchmark.evaluate`."""
  import time

  from hpg_mj import benchmark
  if args.seed is not None:
    raise ValueError("--seed is for a saved agent; --policy runs the fixed starts of the "
                     "reports (SPEC section 7)")
  task = _benchmark_task(args.task, args.level)
  policy = benchmark.load_policy(args.policy)
  start = time.perf_counter()
  result = benchmark.evaluate(policy, task, args.episodes, args.max_steps,
                              batched=True if args.batched else None, num_envs=args.num_envs,
                              backend=args.backend or "analytic",
                              progress=False if args.quiet or args.json else None)
  metrics = dict(result.metrics)
  seed = benchmark.base.GREEDY_SEED
  starts = (f"fixed set (start i: the environment's reset(seed={seed} + i))"
            if result.task.name in benchmark.LADDER
            else f"fixed set (start i from seed {seed} + i)")
  metrics.update({"policy": args.policy, "backend": args.backend or "analytic",
                  "starts": starts,
                  "wall_seconds": round(time.perf_counter() - start, 3)})
  _print_metrics(metrics, args.json)
  return 0


def _benchmark_task(task, level):
  """`hpg-mj evaluate --policy`'s --task and --level as a benchmark task, or a one-line
  error naming the option and what it allows."""
  from hpg_mj import benchmark
  named = "the default task, ship" if task is None else f"--task {task}"
  task = "ship" if task is None else task
  if "/" in task and task.split("/", 1)[0] in benchmark.LADDER:    # ship_goal/hard
    if level is not None:
      raise ValueError(f"--task {task!r} names its level; give --level only with a bare "
                       "task name")
    task, level = task.split("/", 1)
  if task not in benchmark.TASKS + benchmark.LADDER:
    raise ValueError(f"--task {task!r} is not a task; allowed: "
                     f"{', '.join(benchmark.TASKS + benchmark.LADDER)}")
  if level is not None and task not in benchmark.LADDER:
    raise ValueError(f"--level is for the ladder's tasks ({', '.join(benchmark.LADDER)}), "
                     f"not {named}")
  if task in benchmark.LADDER:
    level = benchmark.LEVELS[0] if level is None else level
    if level not in benchmark.LEVELS:
      raise ValueError(f"--level {level!r} is not a level; allowed: "
                       f"{', '.join(benchmark.LEVELS)}")
    return benchmark.task_of(task, level=level)
  return task


def _cmd_bounds(args):
  """`hpg-mj bounds`: SPEC section 7.1's reference scores, computed on the fixed starts."""
  import json
  import pathlib

  from hpg_mj import benchmark
  say = (lambda line: None) if args.quiet else (
      lambda line: print(line, file=sys.stderr, flush=True))
  for name in args.task or ():
    if name not in benchmark.KEYS:
      raise ValueError(f"--task {name!r} has no bounds; allowed: {', '.join(benchmark.KEYS)}")
  published = benchmark.compute_bounds(args.episodes, progress=False if args.quiet else None,
                                       say=say, tasks=args.task)
  print("\n".join(benchmark.format_bounds(published)))
  if args.out:
    out = pathlib.Path(args.out)
    if args.task and out.is_file():     # these tasks' bounds replace theirs in the file
      earlier = json.loads(out.read_text())
      if earlier.get("protocol") != published["protocol"]:
        raise ValueError(f"{out}: its bounds were computed under another protocol "
                         f"({earlier.get('protocol')}); recompute every task (no --task)")
      tasks = dict(earlier["tasks"], **published["tasks"])
      published["tasks"] = {name: tasks[name] for name in benchmark.KEYS if name in tasks}
    out.write_text(json.dumps(published, indent=1) + "\n")
    print(f"wrote {args.out}")
  return 0


def _demo_commands(out, seconds):
  """The commands `hpg-mj demo` runs, as a user would type them: videos of the
  scripted ship and taxi in `out` (the demo's own file names, replaced when it runs
  again; `hpg-mj demo --out videos` remakes the tracked showcase MP4 on purpose),
  the ship's verification and the environment benchmark."""
  import pathlib
  out = pathlib.Path(out)
  return [["render", "--domain", "ship", "--task", "steer", "--seed", "3", "--out",
           str(out / "ship_steer_scripted.mp4"), "--force"],
          ["render", "--domain", "taxi", "--task", "fuel", "--seed", "1", "--out",
           str(out / "taxi_fuel_scripted.mp4"), "--width", "480", "--height", "480", "--force"],
          ["verify", "ship"],
          ["bench", "envs", "--seconds", repr(seconds)]]


def _cmd_demo(args):
  """After the quick reproduction (scripts/run.sh): `_demo_commands`, each parsed and
  run as from the command line (so that it has every option's default)."""
  parser, rc = build_parser(), 0
  for argv in _demo_commands(args.out, args.seconds):
    command = _parse(parser, argv)
    rc |= command.func(command)
  return rc


def _add_run_options(p):
  """Options shared by `run` and `reproduce`."""
  from hpg_mj.experiments import runs
  p.add_argument("--quick", action="store_true", help="fewer runs and episodes")
  p.add_argument("--out", default="runs", help="output folder (one subfolder per experiment)")
  p.add_argument("--workers", type=_at_least(1), default=None,
                 help="processes (default and most: the cores here, and never more than "
                      "the runs to do; with --executor ray --address, the cluster's CPUs)")
  p.add_argument("--executor", choices=["process", "ray"], default="process",
                 help="a local process pool, or Ray (pip install 'hpg_mj[ray]')")
  p.add_argument("--address", default=None,
                 help="with --executor ray: a Ray cluster's address (default: a local Ray)")
  p.add_argument("--checkpoint-every", type=_at_least(1), default=runs.CHECKPOINT_EVERY,
                 metavar="N",
                 help=f"episodes between checkpoints (default {runs.CHECKPOINT_EVERY}; the SB3 "
                      "and JAX agents save more often on their own: docs/experiments.md)")
  p.add_argument("--quiet", action="store_true", help="no progress bar")
  p.add_argument("--no-wait", action="store_true",
                 help="refuse, rather than wait, when another command holds a run of the "
                      "experiment")


def build_parser():
  """The `hpg-mj` command line's argument parser, with every subcommand."""
  parser = _Parser(
      prog="hpg-mj", description="Hierarchical policy gradient benchmarks on MuJoCo.")
  parser.add_argument("--import", dest="imports", action="append", default=[],
                      metavar="MODULE",
                      help="import a module of your own first (a name such as "
                      "my_pkg.agents, searched in the current folder and on sys.path, or a "
                      ".py file) that registers agents with hpg_mj.agents.register; repeatable")
  sub = parser.add_subparsers(dest="command", required=True)

  p = sub.add_parser("verify", help="ship: the MuJoCo ship against the continuous ODE; "
                                    "current: both ships in each level's current, likewise; "
                                    "goal: the goal task's two ships, episode by episode "
                                    "(--starts episodes per level); "
                                    "regatta: the regatta's two ships, course by course "
                                    "(--starts courses per level); "
                                    "harbour: the harbour's two ships and rangefinders, "
                                    "episode by episode (--starts episodes per level); "
                                    "golden: every task's stored trajectory, replayed")
  p.add_argument("what",
                 choices=["ship", "current", "goal", "regatta", "harbour", "golden"])
  p.add_argument("--controls", type=_at_least(1), default=1000,
                 help="random 0.6 s controls per start")
  p.add_argument("--starts", type=_at_least(1), default=3, help="random starting states")
  p.add_argument("--seed", type=_seed, default=0)
  p.set_defaults(func=_cmd_verify)

  p = sub.add_parser("render", help="write a video of one episode (of a task's scripted or "
                     "random policy, or with --agent of a saved agent)")
  p.add_argument("--domain", choices=["ship", "taxi", "ship_current", "ship_goal",
                                      "ship_regatta", "ship_harbour"], default=None,
                 help="default ship")
  p.add_argument("--task", default=None,
                 help="ship: steer, diagonal, straight, patrol; taxi: fuel, classic; the "
                      "ladder's domains: a level, easy (default), medium, hard")
  p.add_argument("--level", default=None, choices=["easy", "medium", "hard"],
                 help="the ladder's domains: the level (as --task; `hpg-mj evaluate`'s name)")
  p.add_argument("--policy", type=_render_policy, default=None, metavar="POLICY",
                 help="scripted (default), random, or your own as `hpg-mj evaluate "
                 "--policy` takes it: module:name or path/file.py:name (a function obs -> "
                 "action, or an object with predict(obs, deterministic=True))")
  p.add_argument("--seed", type=_seed, default=0,
                 help="the episode: reset(seed=S); with --policy, the start `hpg-mj "
                      "evaluate` draws from seed S (its start i: S = 1000000 + i; on the "
                      "ladder that is reset(seed=S)). evaluate sails the analytic ship by "
                      "default: with --backend mujoco an episode may end a step apart")
  p.add_argument("--out", default=None, help="output path (.mp4 or .gif; default in "
                 f"{VIDEOS_OUT}/, named after the task or the agent)")
  p.add_argument("--gif", action="store_true", help="write an animated GIF instead of MP4")
  p.add_argument("--force", action="store_true", help="replace an existing --out file")
  p.add_argument("--width", type=_at_least(16), default=None,
                 help="pixels (default 640; with --agent 320)")
  p.add_argument("--height", type=_at_least(16), default=None,
                 help="pixels (default 480; with --agent 240)")
  p.add_argument("--max-steps", type=_at_least(1), default=None)
  p.add_argument("--backend", choices=["mujoco", "analytic"], default="mujoco")
  p.add_argument("--stride", type=int, default=None,
                 help="film every N-th control step (default: ship 2; with --agent the "
                 "smallest that fits --max-frames)")
  p.add_argument("--max-frames", type=int, default=None,
                 help="with --agent: the video's length bound in frames (default 200)")
  p.add_argument("--quiet", action="store_true", help="with --agent: no progress bar")
  p.add_argument("--agent", default=None,
                 help="a saved agent folder: film one greedy episode of it")
  p.set_defaults(func=_cmd_render)

  p = sub.add_parser("train", help="train the agent of a task file and save it")
  p.add_argument("task_file", nargs="?", default=None,
                 help="a task file, or the name of a shipped one (ship_hybrid, ...)")
  p.add_argument("--episodes", type=_at_least(1), default=None,
                 help="override [protocol] episodes (a continuing agent's: record rows, "
                 "hours for ship_patrol); with --resume, the episodes to train further")
  p.add_argument("--resume", default=None, metavar="AGENT_DIR",
                 help="train the agent saved in AGENT_DIR further (--episodes more), as a run "
                 "never stopped would, and save it there with its whole record")
  p.add_argument("--seed", type=_seed, default=None, help="override [protocol] seed")
  p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                 help="set a key of the task file, e.g. environment.level=hard (repeatable; "
                 "saved with the agent)")
  p.add_argument("--backend", choices=["analytic", "mujoco"], default=None)
  p.add_argument("--out", default=None, help="agent folder (default runs/<task>-seed<S>)")
  p.add_argument("--force", action="store_true",
                 help="replace the agent saved in the --out folder (refused without it)")
  p.add_argument("--json", action="store_true", help="print one JSON object of metrics")
  p.add_argument("--quiet", action="store_true", help="no progress bar")
  p.set_defaults(func=_cmd_train)

  p = sub.add_parser("run", help="run an experiment file: its tasks x seeds, figures, report")
  p.add_argument("experiment_file", help="an experiment file, or a shipped one's name (fig7_11)")
  _add_run_options(p)
  p.set_defaults(func=_cmd_run)

  p = sub.add_parser("tune", help="tune task files over their [tuning] grids, the same "
                     "budget for each, on their tuning seeds")
  p.add_argument("task_files", nargs="+", help="task files, or shipped names")
  p.add_argument("--budget", type=_at_least(1), default=None,
                 help="configurations per task (default: each file's [tuning] budget)")
  p.add_argument("--episodes", type=_at_least(1), default=None,
                 help="episodes per run (default: each file's [tuning] episodes)")
  p.add_argument("--seeds", default=None,
                 help="comma-separated tuning seeds (default: each file's tuning_seeds)")
  p.add_argument("--workers", type=_at_least(1), default=1,
                 help="runs at a time, each in its own process (default 1, at most the "
                      "cores here; the results do not depend on it)")
  p.add_argument("--json", default=None, help="write the results to this JSON file")
  p.add_argument("--quiet", action="store_true", help="no line per run on stderr")
  p.set_defaults(func=_cmd_tune)

  p = sub.add_parser("reproduce", help="the paper's figures from the shipped experiments")
  p.add_argument("figure", nargs="?", default="all",
                 help="all, fig6, fig7, ..., fig12, beyond (SPEC section 8), reference "
                      "(the reference scores and sample-efficiency figures), or ladder (the "
                      "task ladder's reference table, SPEC section 11)")
  _add_run_options(p)
  p.add_argument("--existing", action="store_true",
                 help="reference and ladder only: draw from the runs already finished "
                      "under --out, run nothing")
  p.add_argument("--earlier", metavar="RUNS_JSONL",
                 help="reference and ladder only: for each seed whose run is not finished "
                      "under --out, its metrics from an earlier report's runs.jsonl (for "
                      "example figures/reference/runs.jsonl)")
  p.add_argument("--add", metavar="JSONL", action="append",
                 help="ladder only: a method of one's own beside the reference learners, a "
                      "JSON line a run: benchmark.evaluate's metrics with its label and seed "
                      "(docs/results_ladder.md); may be given more than once")
  p.set_defaults(func=_cmd_reproduce)

  p = sub.add_parser("evaluate", help="score a saved agent, or any policy (--policy), on "
                     "the fixed starts of the reports without learning")
  p.add_argument("agent_dir", nargs="?", default=None, help="a saved agent folder")
  p.add_argument("--policy", default=None, metavar="MODULE:FUNCTION",
                 help="without an agent: a function obs -> action, or an object with "
                 "predict(obs, deterministic=True), as module:name or path/file.py:name "
                 "(hpg_mj.benchmark.evaluate); with an agent: greedy (default) or sampled")
  p.add_argument("--task", default=None, metavar="TASK",
                 help="with --policy: the task, one of ship, taxi_fuel, taxi, ship_current, "
                      "ship_goal, ship_regatta, ship_harbour (default ship)")
  p.add_argument("--level", default=None, metavar="LEVEL",
                 help="with --policy and a ladder task (ship_current, ship_goal, "
                      "ship_regatta, ship_harbour): easy (default), medium or hard; with a "
                      "saved ladder agent: score its policy at that level, not its own "
                      "(where the levels' spaces are the same)")
  p.add_argument("--batched", action="store_true",
                 help="with --policy: the function takes a batch of observations")
  p.add_argument("--max-steps", type=_at_least(1), default=None,
                 help="with --policy: a step cap (default the task's: ship 5000, taxi 200; "
                      "the current's, the regatta's and the harbour's hard levels 1000)")
  p.add_argument("--num-envs", type=_at_least(1), default=1000,
                 help="with --policy: episodes sailed side by side (default 1000)")
  p.add_argument("--episodes", type=_at_least(1), default=1000,
                 help="episodes to score (default 1000: the fixed start set of the reports; "
                      "a count other than 1000 is not an official score)")
  p.add_argument("--seed", type=_seed, default=None,
                 help="a saved agent: draw the starts from this seed (default: the fixed "
                      "seeded start set of the reports, SPEC section 7)")
  p.add_argument("--backend", choices=["analytic", "mujoco"], default=None)
  p.add_argument("--json", action="store_true")
  p.add_argument("--quiet", action="store_true", help="no progress bar")
  p.set_defaults(func=_cmd_evaluate)

  p = sub.add_parser("bounds", help="the random and best known scores of each task on the "
                     "fixed starts (SPEC section 7.1), as the package publishes them")
  p.add_argument("--out", default=None, help="write them as JSON here "
                 "(the package's: hpg_mj/benchmark_bounds.json)")
  p.add_argument("--episodes", type=_at_least(1), default=1000,
                 help="fixed starts (default 1000, the reports')")
  p.add_argument("--task", action="append", default=None, metavar="TASK",
                 help="only this task's bounds, as named in the file (ship, taxi_fuel, "
                      "taxi, ship_current/easy, ..., ship_harbour/hard; repeatable); with "
                      "--out they replace that task's in the file")
  p.add_argument("--quiet", action="store_true")
  p.set_defaults(func=_cmd_bounds)

  p = sub.add_parser("bench", help="print speed figures")
  p.add_argument("what", choices=["envs", "train", "experiments"],
                 help="environments, training loops, or the paper's protocols end to end")
  p.add_argument("--seconds", type=_positive_seconds, default=None,
                 help="measuring time per row (envs: 1 s, train: 2 s)")
  p.add_argument("--task", action="append", default=None, metavar="FILE",
                 help="train: this task file (a shipped name or a path; repeat for more) "
                      "instead of every shipped one")
  p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                 help="train with --task: set a key of every task file, as hpg-mj train "
                      "--set does (e.g. environment.level=hard; repeatable)")
  p.add_argument("--json", action="store_true",
                 help="train: a JSON list, an object per task file, compile seconds apart from "
                      "training seconds, the median round of --rounds whole and each "
                      "round's speed (with "
                      "--task, each after the first has first_over_this: the first's "
                      "speed over its own)")
  p.add_argument("--rounds", type=_at_least(1), default=1,
                 help="train with --task: interleaved rounds over the task files (the "
                      "median of each, and the first's speed over each other's)")
  p.add_argument("--workers", type=_at_least(1), default=None, help="experiments: processes")
  p.set_defaults(func=_cmd_bench)

  p = sub.add_parser("doctor", help="the renderer, versions and numba cache found here, "
                     "and what to do about each problem")
  p.set_defaults(func=_cmd_doctor)

  p = sub.add_parser("demo", help="the README's main job: videos, verification, benchmark")
  p.add_argument("--out", default=VIDEOS_OUT,
                 help=f"the videos' folder (default {VIDEOS_OUT}, not tracked by git; "
                      "--out videos remakes the repository's showcase videos on purpose)")
  p.add_argument("--seconds", type=_positive_seconds, default=1.0,
                 help="measuring time per row of the environment benchmark")
  p.set_defaults(func=_cmd_demo)
  return parser


def _check_workers(parser, args):
  """Refuses more --workers than the cores here (a mistyped count would start that
  many processes), except for a Ray cluster (--address), whose CPUs bound it; fewer
  runs to do than workers is no error (the pool is sized to the runs)."""
  from hpg_mj.experiments import cores
  requested = getattr(args, "workers", None)
  if requested is None or (getattr(args, "executor", None) == "ray" and args.address):
    return
  here = cores.available()
  if requested > here:
    cluster = (", or more on a Ray cluster (--executor ray --address ADDRESS)"
               if hasattr(args, "executor") else "")
    parser.exit(2, f"{parser.prog} {args.command}: error: --workers {requested} is more than "
                   f"the {here} cores this process may use; allowed: 1..{here}{cluster} (see "
                   f"{parser.prog} {args.command} --help)\n")


def _parse(parser, argv):
  """The command line's arguments, checked, with every default filled."""
  args = parser.parse_args(argv)
  if args.command == "render":
    _check_render_args(parser, args)
  _check_workers(parser, args)
  return args


def main(argv=None):
  """Runs `hpg-mj` with the arguments `argv` (the process's when None)."""
  import hpg_mj  # noqa: F401  (registers the Gymnasium ids)
  from hpg_mj import _stack
  from hpg_mj._render_worker import RenderingUnavailable
  args = _parse(build_parser(), argv)
  import warnings

  from hpg_mj import provenance
  shown = warnings.showwarning

  def show(message, category, *rest, **kwargs):   # a saved agent of another version
    if issubclass(category, provenance.VersionWarning):
      print(f"hpg-mj {args.command}: warning: {message}", file=sys.stderr)
    else:
      shown(message, category, *rest, **kwargs)
  warnings.showwarning = show
  try:
    from hpg_mj import agents
    for module in args.imports:          # a user's agents, registered before the command
      agents.import_module(module)
    return _stack.roomy(args.func, args)   # (numba compiles below it: `hpg_mj._stack`)
  except RenderingUnavailable as err:
    print(f"hpg-mj {args.command}: error: {err}", file=sys.stderr)
    return 2
  except (ValueError, OSError) as err:   # a user's file, option or path: one line
    print(f"hpg-mj {args.command}: error: {' '.join(str(err).split())}", file=sys.stderr)
    return 2
  except KeyboardInterrupt:
    again = (" (run the same command again to resume from the last checkpoints)"
             if args.command in ("run", "reproduce") else "")
    print(f"hpg-mj {args.command}: interrupted{again}", file=sys.stderr)
    return 130


if __name__ == "__main__":
  sys.exit(main())
