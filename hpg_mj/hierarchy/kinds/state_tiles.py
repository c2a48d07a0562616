"""The StateTiles view: the world's state as it is, its first numbers (as many as its
learner's coder tiles), for a learner over the whole state (flat PGRL)."""
import numba

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def view(P, obs, call, samples, out):
  """The observation's first numbers, copied into `out`."""
  for i in range(out.shape[0]):
    out[i] = obs[i]


class StateTilesKind(base.ViewKind):
  """Runs a `StateTiles` view: as many features as its coder tiles."""
  block = blocks.StateTiles
  gives = "features"
  writes = True
  view = staticmethod(view)

  def size(self, block):
    return len(block.coder.low)

  def settings(self, name, block):
    return None
