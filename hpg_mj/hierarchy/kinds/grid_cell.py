"""The GridCell view: the cell i * grid + j of the ship's (x, y) on a grid of `cell_m`
cells, clamped to it (the hybrid root's state, SPEC section 3)."""
import collections

import numba
import numpy as np

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.kinds import base

Settings = collections.namedtuple("Settings", ("cell_m", "grid"))
Settings.__doc__ = """A GridCell's settings: the cell's side in m, the cells per
side."""


@numba.njit(cache=True, inline="always")
def grid_cell(x, y, cell_m, grid):
  """The cell i * grid + j of (x, y) on a grid of `cell_m` cells, clamped to it."""
  i = min(max(int(x // cell_m), 0), grid - 1)
  j = min(max(int(y // cell_m), 0), grid - 1)
  return i * grid + j


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def view(P, obs, call, samples):
  """The state: the cell i * grid + j of the ship's (x, y), clamped to the grid."""
  return grid_cell(obs[0], obs[1], P.cell_m, P.grid)


class GridCellKind(base.ViewKind):
  """Runs a `GridCell` view: grid ** 2 states."""
  block = blocks.GridCell
  gives = "state"
  view = staticmethod(view)

  def size(self, block):
    return int(block.grid) ** 2

  def settings(self, name, block):
    base.check_positive_int(block, "grid", block.grid)
    return Settings(float(block.cell_m), np.int64(block.grid))
