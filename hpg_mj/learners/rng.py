"""A small counter-free random generator (xoshiro256**) over a uint64[4] state.

Both training paths draw from it in the same order, so a fixed seed gives the
same numbers in Python and in compiled loops, and its state is a plain array
that a checkpoint saves and restores exactly.
"""
import math

import numba
import numpy as np

_MASK = (1 << 64) - 1
# The seeds the generator takes: make_state keeps a seed's low 64 bits, so a larger
# seed would give the same numbers as a smaller one; the command line and the task
# and experiment files refuse seeds outside 0..MAX_SEED.
MAX_SEED = _MASK


def make_state(seed: int) -> np.ndarray:
  """The generator state for an integer seed (splitmix64, as xoshiro recommends)."""
  if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool):
    raise ValueError(f"seed must be an integer, got {seed!r}")
  x = int(seed) & _MASK
  out = np.empty(4, dtype=np.uint64)
  for i in range(4):
    x = (x + 0x9E3779B97F4A7C15) & _MASK
    z = x
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK
    out[i] = z ^ (z >> 31)
  return out


# The generator's functions are inlined by numba (`inline="always"`) into every
# compiled rule that draws, and numba runs its front end on an inlined function
# again at each call site: a first compile pays for every site of every function in
# the chain. So next_u64 writes its two rotations out rather than call a helper, and
# `normal` draws its two uniforms from one call site (together, the generator's
# sites were ~0.7 s of the ship hybrid's first train).

@numba.njit(cache=True, inline="always")
def next_u64(s):
  """The generator's next uint64, its state `s` advanced (xoshiro256**)."""
  x = s[1] * numba.uint64(5)
  result = ((x << numba.uint64(7)) | (x >> numba.uint64(57))) * numba.uint64(9)   # rotl(x, 7)
  t = s[1] << numba.uint64(17)
  s[2] ^= s[0]
  s[3] ^= s[1]
  s[1] ^= s[2]
  s[0] ^= s[3]
  s[2] ^= t
  s[3] = (s[3] << numba.uint64(45)) | (s[3] >> numba.uint64(19))               # rotl(s[3], 45)
  return result


@numba.njit(cache=True, inline="always")
def uniform(s):
  """A float in [0, 1) with 53 random bits."""
  return (next_u64(s) >> numba.uint64(11)) * (1.0 / 9007199254740992.0)


@numba.njit(cache=True)
def uniform_range(s, low, high):
  """A float uniform in [low, high)."""
  return low + (high - low) * uniform(s)


@numba.njit(cache=True, inline="always")
def randint(s, n):
  """An integer in 0..n-1 (n >= 1)."""
  return min(int(uniform(s) * n), n - 1)


@numba.njit(cache=True, inline="always")
def normal(s):
  """A standard normal draw (Box-Muller; uses two uniforms, u1 then u2, drawn at one
  call site: see above)."""
  u1, u2 = 0.0, 0.0
  for i in range(2):
    u = uniform(s)
    if i == 0:
      u1 = 1.0 - u               # in (0, 1]: log is finite
    else:
      u2 = u
  return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)
