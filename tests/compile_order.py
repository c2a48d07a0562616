"""For the agents whose rules compile leaves first (`learners.jit.compile_first`):
in a fresh process with an empty numba cache, every listed rule compiles exactly
once, so the listed examples have the types the loop calls the rules with."""
import json
import os
import subprocess
import sys

_COUNTING = """
import collections, json
from numba.core import event
counts = collections.Counter()
class Count(event.Listener):
  def on_start(self, ev):
    counts[ev.data["dispatcher"].py_func.__qualname__] += 1
  def on_end(self, ev):
    pass
event.register("numba:compile", Count())
"""
_REPORT = """
print(json.dumps({"counts": counts, "listed": [d.py_func.__qualname__ for d, _ in listed]}))
"""


def assert_each_compiles_once(cache_dir, code):
  """Runs `code` (which sets `listed` to the (dispatcher, example) list after running
  the agent) and checks that each listed dispatcher compiled exactly once."""
  env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
  done = subprocess.run([sys.executable, "-c", _COUNTING + code + _REPORT], env=env,
                        capture_output=True, text=True, timeout=300, check=True)
  result = json.loads(done.stdout.strip().splitlines()[-1])
  counts, listed = result["counts"], result["listed"]
  assert listed and all(counts.get(name) == 1 for name in listed), (counts, listed)
