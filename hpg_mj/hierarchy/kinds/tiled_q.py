"""The TiledQTable kind: Watkins's Q(lambda) linear in a CMAC's tiles of the node's
features x its children, over the SMDP of its children's runs (`learners.qlambda`'s
tiled rules), epsilon-greedy among the children offered. The tiled rules offer a
state's first k children (an option's initiation set), so its node's `available`,
if any, is one that offers a prefix of them (`AvailableKind.prefix`: NearGateLine)."""
import collections

import numba
import numpy as np

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base
from hpg_mj.hierarchy.kinds import q_table
from hpg_mj.learners import arrays
from hpg_mj.learners import qlambda
from hpg_mj.learners import tiles as tiles_mod

Settings = collections.namedtuple("Settings", ("alpha", "gamma", "trace_decay", "epsilon",
                                               "tiling"))
Settings.__doc__ = """A TiledQTable's settings `P`: alpha, gamma, the trace's decay,
`epsilon` (float64[1], its own or the graph's schedule's) and `tiling`, the coder's
arrays."""
Learned = collections.namedtuple("Learned", ("q", "trace_index", "trace_value", "trace_count"))
Learned.__doc__ = """What a TiledQTable learns, saved by these names: the weights
q[tile * n + a] and the trace's live entries (index, value; count of them)."""
Scratch = collections.namedtuple("Scratch", ("tiles", "last"))
Scratch.__doc__ = """A node's scratch: the active tiles of s (row 0) and s' (row 1);
its last choice."""


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def offered(mask):
  """How many of its first children the mask offers."""
  k = 0
  while k < mask.shape[0] and mask[k]:
    k += 1
  return np.int64(k)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def choose(P, L, N, x, n, mask, rng, learn, sample):
  """A child chosen in the state of features x among the first ones `mask` offers,
  epsilon-greedy over Q(s, .) on its tiles (greedy when not `sample`)."""
  tiles_mod.active_tiles(x, P.tiling, N.tiles[0])
  a = qlambda.tiled_epsilon_greedy(L.q, N.tiles[0], n, offered(mask),
                                   P.epsilon[0] if sample else 0.0, rng)
  N.last[0] = a
  return float(a)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def observe(P, L, N, x, signal, done, terminal, n, mask, rng, learn, sample):
  """The child returned R + G = signal in s' (x): the next choice a' among the
  children offered in s' unless done, then the backup (`qlambda.tiled_smdp_step`)."""
  if not terminal:
    tiles_mod.active_tiles(x, P.tiling, N.tiles[1])
  a = qlambda.tiled_smdp_step((L.q, L.trace_index, L.trace_value, L.trace_count), n,
                              N.tiles[0], N.last[0], signal, N.tiles[1], offered(mask), done,
                              terminal, P.epsilon[0] if sample else 0.0, P.alpha, P.gamma,
                              P.trace_decay, learn, rng)
  arrays.copy_into(N.tiles[0], N.tiles[1])
  N.last[0] = a
  return float(a)


class TiledQTableKind(base.LearnerKind):
  """Runs a `TiledQTable` block: a features learner, masked by a prefix."""
  block = blocks.TiledQTable
  reads = "features"
  masked = "prefix"

  def check(self, name, block, n_children, view_size):
    if block.trace_capacity is not None:
      base.check_positive_int(block, "trace_capacity", block.trace_capacity)
    if view_size is not None and view_size != len(block.coder.low):
      raise GraphError(f"subtask {name!r}: its view gives {view_size} numbers, its "
                       f"TiledQTable's coder tiles {len(block.coder.low)}")

  def size(self, block):
    return len(block.coder.low)

  def settings(self, name, block, schedule=None):
    return Settings(*q_table.rates(name, block, schedule), block.coder.arrays())

  def learned(self, block, n_children):
    size = block.coder.size * n_children
    index, value, count = qlambda.new_trace(size if block.trace_capacity is None else
                                            int(block.trace_capacity))
    return Learned(np.zeros(size), index, value, count)

  def parameters(self, learned):
    """The weights q[tile * n + a] (the trace is no parameter)."""
    return {"q": learned.q.copy()}

  def scratch(self, block, n_children):
    return Scratch(np.zeros((2, block.coder.n_tilings), dtype=np.int64),
                   np.zeros(1, dtype=np.int64))

  start = staticmethod(q_table.start)               # the trace cleared
  choose, observe = staticmethod(choose), staticmethod(observe)
