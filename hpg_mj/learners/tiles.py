"""CMAC tile coding (SPEC section 3): several offset tilings, one weight per tile.

A tiling divides each input dimension into `n_tiles[d]` equal tiles over
[low[d], high[d]); a wrapping dimension (the heading) continues around the
circle, the others clip to their edge tiles. Tiling k is shifted by k/n of a
tile along a displacement vector of the first integers coprime with n (for
n = 9: 1, 2, 4, 5, 7, ...; SPEC section 3), so that every tiling is offset
differently from every other in every dimension and neighbouring states share
most tiles. (Miller & Glanz's odd vector 1, 3, 5, 7, ... is coprime only with a
power of two: modulo 9 it gives the second dimension 3 offsets and the fifth none.)
Every state activates exactly one tile per tiling; the tile indices of tiling k
are offset by k * tiles_per_tiling, so all active indices are distinct.

The per-step rules are compiled with numba's `error_model="numpy"`: a division by
zero, which none of them can make, would give inf or nan instead of raising, and
without that raising branch numba drops most of the reference counting (atomic
operations) on the arrays they take. Nothing else changes: the same numbers, faster.
"""
import collections
import dataclasses
import math

import numba
import numpy as np

from hpg_mj.learners.arrays import is_count


Tiling = collections.namedtuple("Tiling", ("low", "width", "n_tiles", "wrap", "offsets"))
Tiling.__doc__ = """The arrays of a `TileCoder` as the compiled functions take them:
each dimension's low end, tile width, tiles and whether it wraps; each tiling's
offsets, in fractions of a tile."""


@dataclasses.dataclass(frozen=True)
class TileCoder:
  """The layout of a CMAC; `arrays()` gives what the compiled functions take."""
  low: tuple
  high: tuple
  n_tiles: tuple
  wrap: tuple
  n_tilings: int = 9

  def __post_init__(self):
    d = len(self.low)
    if not (len(self.high) == len(self.n_tiles) == len(self.wrap) == d) or d == 0:
      raise ValueError(f"tile coder: low, high, n_tiles and wrap must have one entry per "
                       f"dimension, got {self.low}, {self.high}, {self.n_tiles}, {self.wrap}")
    for lo, hi, n in zip(self.low, self.high, self.n_tiles):
      if not is_count(n):
        raise ValueError(f"tile coder: n_tiles must be integers >= 1, got {self.n_tiles}")
      if not hi > lo:
        raise ValueError(f"tile coder: need high > low and n_tiles >= 1, got [{lo}, {hi}) "
                         f"with {n} tiles")
    if not is_count(self.n_tilings):
      raise ValueError(f"tile coder: n_tilings must be an integer >= 1, got {self.n_tilings!r}")

  @property
  def tiles_per_tiling(self):
    """The tiles of one tiling: the product of `n_tiles`."""
    return int(np.prod(self.n_tiles))

  @property
  def size(self):
    """The tiles of all its tilings: the length of a weight vector over them."""
    return self.n_tilings * self.tiles_per_tiling

  def arrays(self):
    """Its `Tiling`: the arrays the compiled functions take."""
    low = np.asarray(self.low, dtype=np.float64)
    width = (np.asarray(self.high, dtype=np.float64) - low) / np.asarray(self.n_tiles)
    n = np.asarray(self.n_tiles, dtype=np.int64)
    wrap = np.asarray(self.wrap, dtype=np.bool_)
    displacement = coprime_displacement(len(self.low), self.n_tilings)
    offsets = ((np.arange(self.n_tilings)[:, None] * displacement[None, :])
               % self.n_tilings) / self.n_tilings
    return Tiling(low, width, n, wrap, offsets)

  def active(self, x):
    """The active tile indices of input `x` (a convenience for Python code)."""
    out = np.empty(self.n_tilings, dtype=np.int64)
    active_tiles(np.asarray(x, dtype=np.float64), self.arrays(), out)
    return out


def coprime_displacement(dims, n_tilings):
  """The first `dims` positive integers coprime with `n_tilings` (SPEC section 3):
  k * d mod n then differs for every pair of tilings, in every dimension."""
  out = []
  d = 1
  while len(out) < dims:
    if math.gcd(d, n_tilings) == 1:
      out.append(d)
    d += 1
  return np.array(out, dtype=np.int64)


@numba.njit(cache=True, error_model="numpy")
def active_tiles(x, tiling, out):
  """Writes the index of the active tile of every tiling into `out`.

  Tile c of dimension d in tiling k is floor((x[d] - low[d]) / width[d] + offsets[k, d]).
  The scaled input (x[d] - low[d]) / width[d] is the same for every tiling, so it is
  computed once per dimension (one division, not one per tiling: the same numbers),
  and `out` accumulates each tiling's index dimension by dimension.
  """
  low, width, n_tiles, wrap, offsets = tiling
  n_tilings = offsets.shape[0]
  for k in range(n_tilings):
    out[k] = 0
  per_tiling = 1
  for d in range(x.shape[0]):
    scaled = (x[d] - low[d]) / width[d]
    n = n_tiles[d]
    per_tiling *= n
    for k in range(n_tilings):
      c = int(np.floor(scaled + offsets[k, d]))
      if wrap[d]:
        # c % n, without the integer division where the input lies within one turn
        # of the range (a wrapped heading always does).
        if c >= n:
          c = c - n if c < 2 * n else c % n
        elif c < 0:
          c = c + n if c >= -n else c % n
      elif c < 0:
        c = 0
      elif c >= n:
        c = n - 1
      out[k] = out[k] * n + c
  for k in range(n_tilings):
    out[k] += k * per_tiling
