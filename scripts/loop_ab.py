"""A loop of this checkout against another's, interleaved: the step-by-step path
through an environment, or the fused training (or evaluation) loop, in-process.

  git worktree add /tmp/ref 9793641
  .venv/bin/python scripts/loop_ab.py --reference /tmp/ref --path dm_control
  .venv/bin/python scripts/loop_ab.py --reference /tmp/ref --path mujoco
  .venv/bin/python scripts/loop_ab.py --reference /tmp/ref --path train --task taxi_fuel_hpg \\
      --episodes 5000

Each checkout runs in one process of its own, both pinned to the same core, its agent
built from the same task and seed, warmed up (its numba cache loaded or compiled), and
then asked in turn for a batch: `--episodes` episodes of `agent.run_stepwise(env, n)`
(`--path dm_control`: `suite.load("ship", "steer")`; `mujoco` or `analytic`: the
Gymnasium ship on that backend), or of `agent.train(n)` / `agent.evaluate(n)` (`--path
train`, `evaluate`: the fused loop, without start-up). Both agents run the same
episodes (the same seed; the golden records hold the paths bit for bit), and each
batch is timed in its process; the ratio of each pair of adjacent batches (this
checkout's speed over the reference's) sees the same minute of this machine, whose
speed drifts by tens of percent within minutes. Printed: the median ratio and its
quartiles over `--batches` pairs, and each side's median speed. Stop other work on the
machine meanwhile.
"""
import argparse
import os
import pathlib
import statistics
import subprocess
import sys

HERE = pathlib.Path(__file__).resolve().parents[1]
PATHS = ("dm_control", "mujoco", "analytic", "train", "evaluate")
_WORKER = """
import sys, time
from hpg_mj import agents
path, task = sys.argv[1], sys.argv[2]
agent = agents.build(agents.load_task(task), seed=0)
if path in ("train", "evaluate"):
  def batch(n):
    return getattr(agent, path)(n)["steps"].sum()
  agent.train(10)
else:
  if path == "dm_control":
    from hpg_mj import suite
    env = suite.load("ship", "steer")
  else:
    import gymnasium
    env = gymnasium.make("hpg_mj/ShipSteering-v0", backend=path)
  def batch(n):
    return agent.run_stepwise(env, n)["steps"].sum()
  batch(3)
print("ready", flush=True)
for line in sys.stdin:
  start = time.perf_counter()
  steps = batch(int(line))
  print(steps / (time.perf_counter() - start), flush=True)
"""


def _start(checkout, path, task, core):
  env = dict(os.environ, PYTHONPATH=str(checkout))
  # cwd: `python -c` puts the working directory first on sys.path (first_compile_ab.py).
  process = subprocess.Popen([sys.executable, "-c", _WORKER, path, task], env=env,
                             cwd=str(checkout), text=True, stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE,
                             preexec_fn=lambda: os.sched_setaffinity(0, {core}))
  if process.stdout.readline().strip() != "ready":
    raise SystemExit(f"{checkout}: the worker did not start (its error is above)")
  return process


def _batch(process, episodes):
  process.stdin.write(f"{episodes}\n")
  process.stdin.flush()
  return float(process.stdout.readline())


def main(argv=None):
  parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  parser.add_argument("--reference", required=True, type=pathlib.Path,
                      help="the other checkout (a git worktree)")
  parser.add_argument("--path", choices=PATHS, default="dm_control")
  parser.add_argument("--task", default="ship_hybrid", help="a shipped task file's name")
  parser.add_argument("--episodes", type=int, default=5, help="episodes per batch")
  parser.add_argument("--batches", type=int, default=30, help="batches per checkout")
  parser.add_argument("--core", type=int, default=max(os.sched_getaffinity(0)))
  args = parser.parse_args(argv)
  if not (args.reference / "hpg_mj").is_dir():
    parser.error(f"--reference {args.reference}: not a checkout (no hpg_mj/ in it)")
  ours = _start(HERE, args.path, args.task, args.core)
  theirs = _start(args.reference, args.path, args.task, args.core)
  mine, reference, ratios = [], [], []
  for i in range(args.batches):
    first, second = (ours, theirs) if i % 2 == 0 else (theirs, ours)
    a, b = _batch(first, args.episodes), _batch(second, args.episodes)
    x, y = (a, b) if first is ours else (b, a)
    mine.append(x)
    reference.append(y)
    ratios.append(x / y)
  for process in (ours, theirs):
    process.stdin.close()
    process.wait()
  q1, _, q3 = statistics.quantiles(ratios, n=4)
  print(f"{args.path} {args.task}: this checkout x{statistics.median(ratios):.2f} "
        f"[quartiles x{q1:.2f}, x{q3:.2f}] of {args.reference} over {args.batches} pairs "
        f"of {args.episodes}-episode batches; steps/s, median: "
        f"{statistics.median(mine):,.0f} against {statistics.median(reference):,.0f}")


if __name__ == "__main__":
  main()
