"""Small array helpers for the compiled loops, and the one test of a count."""

import numba
import numpy as np


def is_count(n, low=1):
  """Whether `n` is an integer >= `low` (a bool or a float is not, even 12.0): a
  number of tiles, states or anything an array is made of."""
  return isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n >= low


@numba.njit(cache=True, inline="always")
def copy_into(dst, src):
  """dst[:] = src for two 1-D arrays of one length, as a loop: numba compiles a slice
  copy from an array with its shape-mismatch message, string formatting included,
  which adds about 2 s to an empty cache's first compile."""
  for i in range(dst.shape[0]):
    dst[i] = src[i]
