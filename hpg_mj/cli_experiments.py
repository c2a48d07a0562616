"""`hpg-mj tune`, `run` and `reproduce`: the experiment files' commands (the
protocol of SPEC section 7), run and drawn into their reports."""
import argparse
import sys


def _cmd_tune(args):
  """`hpg-mj tune TASK ...`: every task's [tuning] grid with one budget (SPEC section 7)."""
  import json

  from hpg_mj import agents
  from hpg_mj.experiments import tuning
  tasks = [agents.load_task(t) for t in args.task_files]      # refused before any run
  if args.json:
    from hpg_mj import _paths
    _paths.check_file_out(args.json, "--json")
  seeds = None
  if args.seeds is not None:
    try:
      seeds = [int(v) for v in args.seeds.split(",")]
    except ValueError:
      raise ValueError(f"--seeds {args.seeds!r}: a comma-separated list of integers, e.g. "
                       f"0,1,2") from None
  out = []
  for task in tasks:
    tuning.grid(task)                                          # every task has a grid
  for task in tasks:
    def progress(k, changes, seed, value, seconds, name=task.path.stem):
      if not args.quiet:
        print(f"{name} #{k + 1} ({tuning.describe(changes)}) seed {seed}: {value:.6g} "
              f"({seconds:.1f} s)", file=sys.stderr, flush=True)
    result = tuning.tune(task, budget=args.budget, episodes=args.episodes, seeds=seeds,
                         progress=progress, workers=args.workers)
    out.append(result)
    print(f"{task.name} ({task.path.stem}): {len(result['results'])} configurations x "
          f"{len(result['seeds'])} seeds x {result['episodes']:,} episodes, score "
          f"{result['score']} ({result['better']} is better)")
    for r in result["results"]:
      mark = "  best" if r["changes"] == result["best"] else ""
      print(f"  {tuning.describe(r['changes'])}: mean {r['mean']:.6g}{mark}")
  if args.json:
    import pathlib
    pathlib.Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
  return 0


def _cmd_run(args):
  from hpg_mj.experiments import locks, runner
  experiment = runner.load_experiment(args.experiment_file)   # refused before any run
  from hpg_mj import _paths
  _paths.check_folder_out(runner.folder(experiment, args.out, args.quick))
  import importlib.util
  if args.executor == "ray" and importlib.util.find_spec("ray") is None:
    raise ValueError("--executor ray needs Ray, which is not installed here: pip install "
                     "'hpg_mj[ray]', or use --executor process")
  from tqdm import tqdm
  all_jobs = runner.jobs(experiment, args.out, args.quick)
  todo = runner.pending(experiment, args.out, args.quick)
  bar = tqdm(total=sum(job[2] for job in all_jobs), unit="ep", unit_scale=True,
             desc=f"{experiment['name']} ({len(todo)} of {len(all_jobs)} runs to go)",
             dynamic_ncols=True, disable=args.quiet or not sys.stderr.isatty())
  done = []

  from hpg_mj import agents
  shown = {t.path.stem: agents.lookup(t.kind).figure.replace("_pass_rate", "").replace(
      "mean_", "") for t in experiment["task_files"]}

  import os
  common = os.path.commonprefix(list(shown)) if len(shown) > 1 else ""
  cut = common.rfind("_") + 1           # "ship_hybrid", "ship_flat_pg" -> "hybrid", "flat_pg"

  def progress(episodes, _total, current):
    bar.update(episodes - bar.n)
    if current:     # e.g. "hybrid gate 0.812, flat_pg gate 0.403"
      bar.set_postfix_str(", ".join(f"{task[cut:]} {shown[task]} {v:.3f}"
                                    for task, v in current.items()))

  def finished(job):
    done.append(job)
    bar.set_description(f"{experiment['name']} ({len(todo) - len(done)} of {len(all_jobs)} "
                        f"runs to go)")
  try:
    results, root, wall = runner.run_experiment(
        experiment, args.out, quick=args.quick, workers=args.workers, progress=progress,
        on_finished=finished, executor=args.executor, address=args.address,
        checkpoint_every=args.checkpoint_every, wait=not args.no_wait,
        command=locks.command_line(), on_wait=lambda m: bar.write(m, file=sys.stderr))
  finally:
    bar.close()
  # Two commands on one folder: one at a time draws the figures and the report.
  with locks.hold(root, wait=not args.no_wait, what="experiment folder"):
    return _draw_and_report(args, experiment, results, root, wall, done)


def _draw_and_report(args, experiment, results, root, wall, done):
  """The experiment's figures and REPORT.md from its runs' results; `done` the runs
  this command trained (from the start, or resumed from a checkpoint)."""
  from hpg_mj import agents
  from hpg_mj.experiments import figures, runner, runs
  seeds = runner.seeds(experiment, args.quick)
  records = {task: runner.load_records(root, task, seeds) for task in results}
  protocol = {"seeds": seeds, "quick": args.quick,
              "episodes": experiment["quick_episodes"] if args.quick else experiment["episodes"]}
  optimal = next(iter(results.values()))[0].get("optimal_mean_return")
  drawn = {}
  for fig in experiment["figures"]:
    if fig["kind"] == "curve":
      drawn[fig["name"]] = figures.draw_curve(root, fig, experiment["task_files"], records,
                                              optimal, protocol)
      continue
    if fig["kind"] == "greedy_curve":
      drawn[fig["name"]] = figures.draw_greedy(
          root, fig["name"], f"{fig['title']}\n{figures.protocol_line(protocol)}",
          [(fig["metric"], fig["ylabel"])], experiment["task_files"], results,
          optimal if fig.get("reference") == "optimal" else None)
      continue
    agent, _, _ = agents.load(root / fig["task"] / f"seed{fig['seed']}" / "agent")
    if fig["kind"] == "options":
      drawn[fig["name"]] = figures.draw_options(root, fig, agent)
      continue
    drawn[fig["name"]] = figures.draw_trajectories(root, fig, agent, args.quick)
    for s in drawn[fig["name"]]:
      print(f"{fig['name']}: from {tuple(s['start'])}: "
            f"{'passed' if s['passed'] else 'missed'} the gate in {s['steps']} control "
            f"steps, {s['calls']} calls ({' '.join(s['decisions'])})")
  figures.write_report(root, experiment, results, drawn, protocol)
  resumed = sum(runs.resumed(job[3]) for job in done)
  trained = ", ".join([f"{len(done) - resumed} new"] * (len(done) > resumed or not done) +
                      [f"{resumed} resumed"] * (resumed > 0))
  n = sum(len(r) for r in results.values())
  print(f"{experiment['name']}: {n} run{'s' if n != 1 else ''} ({trained}, {wall:.1f} s); "
        f"{', '.join(drawn)} and REPORT.md in {root}")
  return 0


FIGURE_EXPERIMENTS = {"fig6": "fig6", "fig7": "fig7_11", "fig8": "fig7_11", "fig9": "fig7_11",
                      "fig10": "fig7_11", "fig11": "fig7_11", "fig12": "fig12"}


def _cmd_reproduce(args):
  """The paper's figures from the shipped experiment files; `beyond`: SPEC
  section 8's continuing task (hpg_mj.experiments.beyond)."""
  from hpg_mj import _paths
  _paths.check_folder_out(args.out)
  if args.earlier and args.figure not in ("reference", "ladder"):
    raise ValueError(f"--earlier completes `reproduce reference` or `reproduce ladder` with an "
                     f"earlier report's runs; {args.figure!r} reruns its experiments (allowed: "
                     f"reproduce reference --earlier {args.earlier}, or ladder)")
  if getattr(args, "add", None) and args.figure != "ladder":
    raise ValueError(f"--add sets a method of one's own beside the ladder's table; "
                     f"{args.figure!r} has none (allowed: reproduce ladder --add FILE)")
  if args.figure == "beyond":
    return _reproduce_beyond(args)
  if args.figure == "reference":
    return _reproduce_reference(args)
  if args.figure == "ladder":
    return _reproduce_ladder(args)
  if args.existing:
    raise ValueError("--existing draws `reproduce reference` and `reproduce ladder` from the "
                     "runs found; the paper's figures rerun their experiments (allowed: "
                     "reproduce reference --existing, reproduce ladder --existing)")
  if args.figure == "all":
    names = list(dict.fromkeys(FIGURE_EXPERIMENTS.values()))
  elif args.figure in FIGURE_EXPERIMENTS:
    names = [FIGURE_EXPERIMENTS[args.figure]]
  else:
    raise ValueError(f"unknown figure {args.figure!r}; valid: all, "
                     f"{', '.join(FIGURE_EXPERIMENTS)}, beyond, reference, ladder")
  rc = 0
  for name in names:
    rc |= _cmd_run(argparse.Namespace(**{**vars(args), "experiment_file": name}))
  from hpg_mj.experiments import figures
  folders = [name + ("_quick" if args.quick else "") for name in names]
  print(f"reproduce: every figure beside the paper in "
        f"{figures.write_combined_report(args.out, folders)}")
  return rc


def _reproduce_beyond(args):
  """The continuing ship task's figures and REPORT.md, then OUT/REPORT.md with a
  'Beyond the paper' section (beside any reproduced figures already there)."""
  import pathlib

  from hpg_mj.experiments import beyond, figures

  def progress(line):
    if not args.quiet:
      print(line, flush=True)
  report = beyond.run(args.out, quick=args.quick, progress=progress, workers=args.workers)
  suffix = "_quick" if args.quick else ""
  names = [n + suffix for n in dict.fromkeys(FIGURE_EXPERIMENTS.values())
           if (pathlib.Path(args.out) / (n + suffix) / "REPORT.md").is_file()]
  combined = figures.write_combined_report(args.out, names + [report.parent.name])
  print(f"reproduce beyond: {report} and {combined}")
  return 0


def _reproduce_reference(args):
  """The reference sample-efficiency figures and "Reference scores" table
  (hpg_mj.experiments.reference): runs the reference experiments (resuming
  unfinished runs; with --existing none), draws them from the runs finished, then
  OUT/REPORT.md with a reference section beside the other reports there."""
  import pathlib

  from hpg_mj.experiments import figures, reference
  rc = 0
  if not args.existing:
    for name in reference.EXPERIMENTS:
      rc |= _cmd_run(argparse.Namespace(**{**vars(args), "experiment_file": name}))
  earlier = reference.read_earlier(args.earlier) if args.earlier else None
  report = reference.write(args.out, quick=args.quick, earlier=earlier)
  suffix = "_quick" if args.quick else ""
  names = [n + suffix for n in list(dict.fromkeys(FIGURE_EXPERIMENTS.values())) + ["beyond"]
           if (pathlib.Path(args.out) / (n + suffix) / "REPORT.md").is_file()]
  combined = figures.write_combined_report(args.out, names + [report.parent.name])
  print(f"reproduce reference: {report}, {report.parent / 'table.md'} and {combined}")
  return rc


def _reproduce_ladder(args):
  """The task ladder's reference table and figure (hpg_mj.experiments.ladder): runs the
  ladder's experiments (resuming unfinished runs; with --existing none; PPO's only where
  JAX is installed, `pip install 'hpg_mj[jax]'`), then writes them from the runs
  finished (and, with --earlier, an earlier report's runs for the seeds not finished
  here: figures/ladder/runs.jsonl keeps those already landed)."""
  import importlib.util

  from hpg_mj.experiments import ladder
  rc = 0
  if not args.existing:
    for name in ladder.EXPERIMENTS:
      if name.endswith("_jax") and importlib.util.find_spec("jax") is None:
        print(f"reproduce ladder: {name} skipped (needs JAX: pip install 'hpg_mj[jax]')")
        continue
      rc |= _cmd_run(argparse.Namespace(**{**vars(args), "experiment_file": name}))
  from hpg_mj.experiments import reference
  earlier = reference.read_earlier(args.earlier) if args.earlier else None
  added = ladder.read_added(*args.add) if args.add else None
  report = ladder.write(args.out, quick=args.quick, earlier=earlier, added=added)
  print(f"reproduce ladder: {report}")
  return rc
