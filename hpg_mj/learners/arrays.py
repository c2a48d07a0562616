"""Small array helpers for the compiled loops."""

import numba


@numba.njit(cache=True, inline="always")
def copy_into(dst, src):
  """dst[:] = src for two 1-D arrays of one length, as a loop: numba compiles a slice
  copy from an array with its shape-mismatch message, string formatting included,
  which adds about 2 s to an empty cache's first compile."""
  for i in range(dst.shape[0]):
    dst[i] = src[i]
