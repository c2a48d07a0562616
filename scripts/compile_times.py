"""Where a first compile spends its time: runs an `hpg-mj` command in this process and
prints, per compiled function, the seconds numba spent compiling it (self: without
the functions it compiled on the way; total: with them).

  NUMBA_CACHE_DIR=$(mktemp -d) .venv/bin/python scripts/compile_times.py \\
      train taxi_fuel_maxq --episodes 2000 --out /tmp/maxq [--who-compiles NAME]

Use an empty cache (functions loaded from numba's cache are not compiled, and so
not counted). `--who-compiles NAME` also prints the chain of functions being
compiled whenever a function whose name contains NAME starts compiling (for
example `raise_with_shape_context`: which loop compiles numba's slice-copy error
message).
"""
import collections
import sys
import time

from numba.core import event

from hpg_mj import cli


def main(argv):
  watch = None
  if "--who-compiles" in argv:
    i = argv.index("--who-compiles")
    watch = argv[i + 1]
    argv = argv[:i] + argv[i + 2:]
  stack = []
  total = collections.defaultdict(float)
  own = collections.defaultdict(float)

  class Listener(event.Listener):
    def on_start(self, ev):
      function = ev.data["dispatcher"].py_func
      name = f"{function.__module__.rsplit('.', 1)[-1]}.{function.__qualname__}"
      if watch is not None and watch in name:
        print(f"{name} compiled within: {' > '.join(s[0] for s in stack)}", file=sys.stderr)
      stack.append([name, time.perf_counter(), 0.0])

    def on_end(self, ev):
      name, start, inner = stack.pop()
      seconds = time.perf_counter() - start
      total[name] += seconds
      own[name] += seconds - inner
      if stack:
        stack[-1][2] += seconds

  event.register("numba:compile", Listener())
  start = time.perf_counter()
  try:
    cli.main(argv)
  except SystemExit:
    pass
  print(f"\n{time.perf_counter() - start:.2f} s in all, {sum(own.values()):.2f} s compiling",
        file=sys.stderr)
  print(f"{'self':>7} {'total':>7}  function", file=sys.stderr)
  for name, seconds in sorted(own.items(), key=lambda kv: -kv[1])[:30]:
    print(f"{seconds:7.2f} {total[name]:7.2f}  {name}", file=sys.stderr)


if __name__ == "__main__":
  main(sys.argv[1:])
