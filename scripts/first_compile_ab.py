"""The first train from an empty numba cache, this checkout against another, as CPU
seconds and their ratio: for each task and round, both checkouts compile at the same
time, each in its own process pinned to its own core, each with an empty
NUMBA_CACHE_DIR, and the cores are swapped every round (this machine's speed drifts
by tens of percent within minutes; two compiles at once see the same minute).

  git worktree add /tmp/ref 9793641
  .venv/bin/python scripts/first_compile_ab.py --reference /tmp/ref \\
      --tasks ship_hybrid taxi_fuel_hpg --rounds 6

A checkout runs from its source tree (PYTHONPATH), with this environment's
dependencies. What is timed: `agents.train(task, episodes=2, seed=0)` in a fresh
process (the import apart), which compiles everything a first train needs; with
`--whole`, the whole process of `hpg-mj train TASK --episodes 2` (start-up, import,
the train, its greedy evaluation and what it writes), the command a user runs first.
Stop other work on the machine meanwhile.
"""
import argparse
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile

HERE = pathlib.Path(__file__).resolve().parents[1]
_TIMED = """
import sys, time
from hpg_mj import agents
task = agents.load_task(sys.argv[1])
start = time.process_time()
agents.train(task, episodes=2, seed=0)
print(time.process_time() - start)
"""
_WHOLE = """
import sys, tempfile, time
from hpg_mj import cli
with tempfile.TemporaryDirectory() as out:
  cli.main(["train", sys.argv[1], "--episodes", sys.argv[2], "--out", out + "/first",
            "--force", "--quiet"])
print(time.process_time())
"""


def _start(checkout, task, core, program, cache, episodes="2"):
  env = dict(os.environ, PYTHONPATH=str(checkout), NUMBA_CACHE_DIR=cache, HPG_MJ_CACHE=cache)
  # cwd: `python -c` puts the working directory first on sys.path, ahead of PYTHONPATH;
  # from any other directory holding an hpg_mj (this checkout's root), both sides
  # would import that one.
  return subprocess.Popen([sys.executable, "-c", program, task, episodes], env=env, text=True,
                          cwd=str(checkout),
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          preexec_fn=lambda: os.sched_setaffinity(0, {core}))


def _seconds(process, checkout):
  out, err = process.communicate()
  if process.returncode != 0:
    raise SystemExit(f"{checkout}: the first train failed:\n{err[-2000:]}")
  return float(out.strip().splitlines()[-1])


def pair(task, reference, cores, program=_TIMED, episodes=2):
  """(reference's seconds, this checkout's seconds), compiled at the same time on
  `cores` (reference's first)."""
  with tempfile.TemporaryDirectory() as a, tempfile.TemporaryDirectory() as b:
    ref = _start(reference, task, cores[0], program, a, str(episodes))
    this = _start(HERE, task, cores[1], program, b, str(episodes))
    return _seconds(ref, reference), _seconds(this, HERE)


def main(argv=None):
  parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  parser.add_argument("--reference", required=True, type=pathlib.Path,
                      help="a checkout of the commit to compare with")
  parser.add_argument("--tasks", nargs="+", default=["ship_hybrid"],
                      help="shipped task names or task files")
  parser.add_argument("--rounds", type=int, default=6)
  parser.add_argument("--whole", action="store_true",
                      help="time the whole `hpg-mj train TASK --episodes 2` process")
  parser.add_argument("--episodes", type=int, default=2,
                      help="with --whole, the train's episodes (2,000: the shipped train's)")
  args = parser.parse_args(argv)
  if not (args.reference / "hpg_mj").is_dir():
    parser.error(f"--reference {args.reference}: no hpg_mj package there; give a checkout")
  if args.rounds < 1:
    parser.error(f"--rounds must be at least 1, got {args.rounds}")
  cores = sorted(os.sched_getaffinity(0))
  if len(cores) < 2:
    parser.error("needs two cores: the two compiles run at the same time")
  for task in args.tasks:
    ratios = []
    for r in range(args.rounds):
      pinned = (cores[0], cores[1]) if r % 2 == 0 else (cores[1], cores[0])
      ref, this = pair(task, args.reference, pinned, _WHOLE if args.whole else _TIMED,
                       args.episodes)
      ratios.append(this / ref)
      print(f"{task} round {r + 1}: reference {ref:.1f} s, this {this:.1f} s "
            f"(x{this / ref:.2f})", flush=True)
    print(f"{task}: this / reference, median x{statistics.median(ratios):.2f} "
          f"(x{min(ratios):.2f}-x{max(ratios):.2f}, {len(ratios)} pairs)")


if __name__ == "__main__":
  main()
