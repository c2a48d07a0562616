"""The GaussianCMAC kind: Eq. 3 with a Gaussian-with-sigmoid policy over a CMAC of
the node's features (SPEC section 3), optionally with a baseline b(s) over the same
tiles and a learned exploration width log sigma(s) (`width_alpha` != 0: its own
Eq. 3 trace over the tiles, `policies.gaussian_choose`); its node's one child is a
continuous primitive, whose value it draws."""
import collections
import math

import numba
import numpy as np
from numba.core import types
from numba.extending import overload

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base
from hpg_mj.learners import arrays
from hpg_mj.learners import banks
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import tiles as tiles_mod

Settings = collections.namedtuple("Settings", ("alpha", "trace_gamma", "baseline", "r_max",
                                               "tiling", "width_alpha", "log_sigma_low",
                                               "log_sigma_high"))
Settings.__doc__ = """A GaussianCMAC's settings `P`: Eq. 3's step size and trace
decay, the baseline's step size, the largest action r_max, `tiling` the coder's
arrays (`TileCoder.arrays`), and the learned width's step size and bounds on
log sigma."""
Learned = collections.namedtuple("Learned", el.Trace._fields + ("values",))
Learned.__doc__ = """What a GaussianCMAC learns, saved by these names: Eq. 3's trace
over theta in its lazy form (`learners.eligibility`: theta, zs, y, touched, marked,
count, acc) and the baseline's values b over the same tiles."""
WIDTH_FIELDS = tuple(f"width_{field}" for field in el.Trace._fields)
LearnedWidth = collections.namedtuple("LearnedWidth", Learned._fields + WIDTH_FIELDS)
LearnedWidth.__doc__ = """`Learned`, with a learned width's Eq. 3 trace too
(width_theta, width_zs, ...)."""
Scratch = collections.namedtuple("Scratch", ("tiles", "psi", "psi_width"))
Scratch.__doc__ = """A node's scratch: the active tiles of s (row 0) and of s'
(row 1), the scores psi of the mean and of the width."""


def width_of(L):
  """The learned width's trace of `L`, or None where it has none (by type: numba then
  compiles Eq. 3 without the width's code)."""


@overload(width_of, inline="always")
def _width_of(L):
  names = L.field_dict if isinstance(L, banks.BankType) else L.fields
  if "width_theta" not in names:
    return lambda L: None
  return lambda L: el.Trace(L.width_theta, L.width_zs, L.width_y, L.width_touched,
                            L.width_marked, L.width_count, L.width_acc)


def reset_width(L):
  """z <- 0 on the learned width's trace, if `L` has one (by type, as `width_of`)."""


@overload(reset_width, inline="always")
def _reset_width(L):
  names = L.field_dict if isinstance(L, banks.BankType) else L.fields
  if "width_theta" not in names:
    return lambda L: None
  return lambda L: el.reset(width_of(L))


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def _choose(P, L, N, tiles, learn, sample, rng):
  """The draw (`policies.gaussian_choose`): called, not inlined, so that `choose` and
  `observe` share one compiled copy of it (inlined into both, it was compiled twice:
  ~1.3 s of flat PGRL's first compile)."""
  return policies.gaussian_choose(el.trace_of(L), L.values, tiles, N.psi, P.alpha, P.baseline,
                                  P.r_max, learn, sample, rng, width_of(L), N.psi_width,
                                  P.width_alpha, P.log_sigma_low, P.log_sigma_high)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def start(P, L, N):
  """A call begins: Eq. 3's z <- 0, and the learned width's."""
  el.reset(el.trace_of(L))                        # Eq. 3: z <- 0
  reset_width(L)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def choose(P, L, N, x, n, rng, learn, sample):
  """u ~ Normal(m(s), 1), its score added to z (`policies.gaussian_choose`)."""
  tiles_mod.active_tiles(x, P.tiling, N.tiles[0])
  return _choose(P, L, N, N.tiles[0], learn, sample, rng)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def observe(P, L, N, x, signal, done, terminal, n, rng, learn, sample):
  """Eq. 3 with R + G (`policies.gaussian_learn`), then, unless done, the next draw
  in s' (x)."""
  if not done:
    tiles_mod.active_tiles(x, P.tiling, N.tiles[1])
  if learn:
    policies.gaussian_learn(el.trace_of(L), L.values, N.tiles[0], N.tiles[1], P.alpha,
                            P.trace_gamma, P.baseline, signal, done, width_of(L),
                            P.width_alpha)
  if done:
    return 0.0
  arrays.copy_into(N.tiles[0], N.tiles[1])
  return _choose(P, L, N, N.tiles[0], learn, sample, rng)


class GaussianCMACKind(base.LearnerKind):
  """Runs a `GaussianCMAC` block: a features learner drawing its node's one
  continuous primitive."""
  block = blocks.GaussianCMAC
  reads = "features"
  continuous = True

  def check(self, name, block, n_children, view_size):
    try:
      blocks.check_width(block.width_alpha, block.sigma_low, block.sigma_high)
    except ValueError as e:
      raise GraphError(f"subtask {name!r}: {e}") from None
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
                    float(block.r_max), block.coder.arrays(), float(block.width_alpha),
                    math.log(block.sigma_low), math.log(block.sigma_high))

  def learned(self, block, n_children):
    size = block.coder.size
    if block.width_alpha == 0.0:
      return Learned(*el.new_trace(size), np.zeros(size))
    return LearnedWidth(*el.new_trace(size), np.zeros(size), *el.new_trace(size))

  def parameters(self, learned):
    """theta with its pending Eq. 3 updates applied, and the baseline's values; with a
    learned width, log sigma's weights (`log_sigma`) the same way."""
    out = {"theta": el.parameters(learned), "values": learned.values.copy()}
    if isinstance(learned, LearnedWidth):
      out["log_sigma"] = el.parameters(el.Trace(*(getattr(learned, f) for f in WIDTH_FIELDS)))
    return out

  def scratch(self, block, n_children):
    k = block.coder.n_tilings
    return Scratch(np.zeros((2, k), dtype=np.int64), np.zeros(k), np.zeros(k))

  start, choose, observe = staticmethod(start), staticmethod(choose), staticmethod(observe)
