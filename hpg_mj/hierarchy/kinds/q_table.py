"""The QTable kind: Watkins's Q(lambda) on a table of states x the node's children,
over the SMDP of its children's runs (SPEC section 3), epsilon-greedy, with
replacing traces (`learners.qlambda`)."""
import collections

import numba

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base
from hpg_mj.learners import qlambda

import numpy as np

Settings = collections.namedtuple("Settings", ("alpha", "gamma", "trace_decay", "epsilon"))
Settings.__doc__ = """A QTable's settings `P`: alpha, gamma, the trace's decay and
`epsilon` (float64[1], its own or the graph's schedule's: `epsilon_schedule=True`)."""
Learned = collections.namedtuple("Learned", ("q", "trace_index", "trace_value", "trace_count"))
Learned.__doc__ = """What a QTable learns, saved by these names: the values Q(s, a) at
s * n + a, and the trace's live entries (index, value; count of them)."""
Scratch = collections.namedtuple("Scratch", ("last",))
Scratch.__doc__ = """A node's scratch: [s, a], the state its last choice was made in
and that choice."""


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def start(P, L, N):
  """A call begins: the trace is cleared."""
  qlambda.clear(L.trace_count)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def choose(P, L, N, x, n, rng, learn, sample):
  """A child chosen in state x, epsilon-greedy over Q(x, .) (greedy when not
  `sample`)."""
  # n as a number, as `observe`'s backup reaches it (`qlambda.smdp_step`): given the
  # constant, epsilon_greedy and greedy were compiled twice.
  a = qlambda.epsilon_greedy(L.q, x, np.int64(n), P.epsilon[0] if sample else 0.0, rng)
  N.last[0] = x
  N.last[1] = a
  return float(a)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def observe(P, L, N, x, signal, done, terminal, n, rng, learn, sample):
  """The child returned R + G = signal in s' (x): the next choice a' unless done,
  then the backup of (s, a, R, s', a') (`qlambda.smdp_step`)."""
  a = qlambda.smdp_step((L.q, L.trace_index, L.trace_value, L.trace_count), np.int64(n),
                        N.last[0], N.last[1], signal, x, done, terminal,
                        P.epsilon[0] if sample else 0.0, P.alpha, P.gamma, P.trace_decay, learn,
                        rng)
  N.last[0] = x
  N.last[1] = a
  return float(a)


def rates(name, block, schedule):
  """(alpha, gamma, trace_decay, epsilon) of a Q(lambda) block (a QTable, a
  TiledQTable), each in [0, 1]; epsilon a float64[1], its own or the schedule's."""
  for field in ("alpha", "gamma", "trace_decay", "epsilon"):
    value = getattr(block, field)
    if not (isinstance(value, (int, float)) and 0.0 <= value <= 1.0):
      raise GraphError(f"subtask {name!r}: {type(block).__name__}.{field} = {value!r}: must "
                       "be a number in [0, 1]")
  epsilon = schedule.epsilon if block.epsilon_schedule else np.array([float(block.epsilon)])
  return float(block.alpha), float(block.gamma), float(block.trace_decay), epsilon


class QTableKind(base.TableKind):
  """Runs a `QTable` block."""
  block = blocks.QTable
  reads = "state"

  def check(self, name, block, n_children, view_size):
    super().check(name, block, n_children, view_size)
    base.check_positive_int(block, "trace_capacity", block.trace_capacity)

  def settings(self, name, block, schedule=None):
    return Settings(*rates(name, block, schedule))

  def learned(self, block, n_children):
    index, value, count = qlambda.new_trace(int(block.trace_capacity))
    return Learned(np.zeros(int(block.n_states) * n_children), index, value, count)

  def parameters(self, learned):
    """The values Q(s, a) (the trace is no parameter)."""
    return {"q": learned.q.copy()}

  def scratch(self, block, n_children):
    return Scratch(np.zeros(2, dtype=np.int64))

  start, choose, observe = staticmethod(start), staticmethod(choose), staticmethod(observe)
