"""Python's cyclic garbage collector, paused while numba compiles hpg_mj's code.

numba's compiler makes hundreds of thousands of objects in reference cycles (IR blocks
and their scopes, types); their allocation sets off the collector, and each of its
full collections walks the whole heap again. Registered on import by the two bottom
layers (`hpg_mj.worlds`, `hpg_mj.learners`), so that every compile of the package's
code is covered, a graph's program (`hpg_mj_graph_...`, `hierarchy.graph_module`) too.
"""
import contextlib
import gc

from numba.core import event

# The modules whose compiles are paused: the package's, and the programs it writes
# per graph (with all they compile inside: the callees, a user's rules and kinds).
PREFIXES = ("hpg_mj.", "hpg_mj_graph_")


class CollectorPause(event.Listener):
  """Pauses the collector while numba compiles a function of hpg_mj, and collects the
  young objects once when that compile ends. Measured on the ship hybrid's first
  train (`hpg-mj train ship_hybrid`, empty caches): the collector took 1.1 s of its
  11-12 s without the pause. A collector the process turned off stays off, and a
  compile of code outside hpg_mj is left as it is. numba compiles under one lock, so
  the depth needs none."""

  def __init__(self):
    self.depth = 0
    self.paused = False

  def on_start(self, ev):
    self.depth += 1
    function = getattr(ev.data.get("dispatcher"), "py_func", None)
    if self.depth == 1 and gc.isenabled() and \
        (getattr(function, "__module__", None) or "").startswith(PREFIXES):
      gc.disable()
      self.paused = True

  def on_end(self, ev):
    self.depth = max(self.depth - 1, 0)     # 0: registered while a compile ran
    if self.depth == 0 and self.paused:
      self.paused = False
      gc.enable()
      gc.collect(0)


@contextlib.contextmanager
def paused():
  """The collector paused over several compiles and what runs between them, with one
  collection of the young objects after. Inside it a compile's own pause stays idle
  (the collector is already off), so the compiles do not each end with a collection
  (~50 ms after each of a graph's first compiles)."""
  if not gc.isenabled():
    yield
    return
  gc.disable()
  try:
    yield
  finally:
    gc.enable()
    gc.collect(0)


PAUSE = CollectorPause()
event.register("numba:compile", PAUSE)
