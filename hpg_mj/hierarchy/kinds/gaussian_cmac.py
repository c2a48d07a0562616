"""The GaussianCMAC kind: Eq. 3 with a Gaussian-with-sigmoid policy over a CMAC of
the node's features (SPEC section 3), optionally with a baseline b(s) over the same
tiles; its node's one child is a continuous primitive, whose value it draws."""
import collections
import math

import numba
import numpy as np

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base
from hpg_mj.learners import arrays
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import tiles as tiles_mod

# `tiling`: the coder's arrays (`TileCoder.arrays`).
Settings = collections.namedtuple("Settings", ("alpha", "trace_gamma", "baseline", "r_max",
                                               "tiling"))
# What it learns (saved by these names): Eq. 3's trace over theta in its lazy form
# (`learners.eligibility`: theta, zs, y, touched, marked, count, acc) and the
# baseline's values b over the same tiles.
Learned = collections.namedtuple("Learned", el.Trace._fields + ("values",))
# A node's scratch: the active tiles of s (row 0) and of s' (row 1), the score psi.
Scratch = collections.namedtuple("Scratch", ("tiles", "psi"))


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def start(P, L, N):
  el.reset(el.trace_of(L))                        # Eq. 3: z <- 0


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def choose(P, L, N, x, n, rng, learn, sample):
  """u ~ Normal(m(s), 1), its score added to z (`policies.gaussian_choose`)."""
  tiles = N.tiles[0]
  tiles_mod.active_tiles(x, P.tiling, tiles)
  return policies.gaussian_choose(el.trace_of(L), L.values, tiles, N.psi, P.alpha, P.baseline,
                                  P.r_max, learn, sample, rng)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def observe(P, L, N, x, signal, done, terminal, n, rng, learn, sample):
  """Eq. 3 with R + G (`policies.gaussian_learn`), then, unless done, the next draw
  in s' (x)."""
  if not done:
    tiles_mod.active_tiles(x, P.tiling, N.tiles[1])
  if learn:
    policies.gaussian_learn(el.trace_of(L), L.values, N.tiles[0], N.tiles[1], P.alpha,
                            P.trace_gamma, P.baseline, signal, done)
  if done:
    return 0.0
  arrays.copy_into(N.tiles[0], N.tiles[1])
  return policies.gaussian_choose(el.trace_of(L), L.values, N.tiles[0], N.psi, P.alpha,
                                  P.baseline, P.r_max, learn, sample, rng)


class GaussianCMACKind(base.LearnerKind):
  block = blocks.GaussianCMAC
  reads = "features"
  continuous = True

  def check(self, name, block, n_children, view_size):
    if block.width_alpha != 0.0:
      raise GraphError(f"subtask {name!r}: a GaussianCMAC's learned width (width_alpha = "
                       f"{block.width_alpha!r}) is not run by the open machine yet "
                       "(hierarchy.program); set width_alpha=0")
    if view_size is not None and view_size != len(block.coder.low):
      raise GraphError(f"subtask {name!r}: its view gives {view_size} numbers, its "
                       f"GaussianCMAC's coder tiles {len(block.coder.low)}")

  def size(self, block):
    return len(block.coder.low)

  def settings(self, name, block, schedule=None):
    for field, low in (("alpha", 0.0), ("trace_gamma", 0.0), ("baseline", 0.0), ("r_max", 0.0)):
      value = getattr(block, field)
      if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= low):
        raise GraphError(f"subtask {name!r}: GaussianCMAC.{field} = {value!r}: must be a "
                         f"finite number >= {low}")
    return Settings(float(block.alpha), float(block.trace_gamma), float(block.baseline),
                    float(block.r_max), block.coder.arrays())

  def learned(self, block, n_children):
    return Learned(*el.new_trace(block.coder.size), np.zeros(block.coder.size))

  def parameters(self, learned):
    """theta with its pending Eq. 3 updates applied, and the baseline's values."""
    return {"theta": el.parameters(learned), "values": learned.values.copy()}

  def scratch(self, block, n_children):
    k = block.coder.n_tilings
    return Scratch(np.zeros((2, k), dtype=np.int64), np.zeros(k))

  start, choose, observe = staticmethod(start), staticmethod(choose), staticmethod(observe)
