"""The GibbsTable kind: Eq. 3 with a Gibbs (softmax) policy over a table of states x
the node's children, among the children its `available` offers (paper section 5.1;
taxi HPG), optionally with a baseline b(s) learned by TD(0) (`learners.policies`:
`softmax_choose`, `softmax_learn`). Its step size is alpha times a warm-up read at
each call from the learning episodes ended: `start_fraction` for the first `delay`,
then a linear rise to 1 over `ramp`."""
import collections
import math

import numba
import numpy as np

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies

Settings = collections.namedtuple("Settings", ("alpha", "trace_gamma", "baseline",
                                               "start_fraction", "delay", "ramp", "learned"))
Settings.__doc__ = """A GibbsTable's settings `P`: Eq. 3's step size and trace decay,
the baseline's step size, the warm-up (start fraction, delay and ramp in learning
episodes) and `learned`, the live count of learning episodes ended (int64[1])."""
Learned = collections.namedtuple("Learned", el.Trace._fields + ("baseline",))
Learned.__doc__ = """What a GibbsTable learns, saved by these names: Eq. 3's trace
over theta[s * n + a] in its lazy form (`learners.eligibility`), and the baseline
b(s)."""
Scratch = collections.namedtuple("Scratch", ("state", "alpha", "probs", "index", "psi"))
Scratch.__doc__ = """A node's scratch: the state its last choice was made in; this
call's step size; the softmax's scratch (probabilities, the offered children, their
scores)."""


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def start(P, L, N):
  """z <- 0; the step size after the warm-up at the learning episodes so far."""
  el.reset(el.trace_of(L))
  e = P.learned[0]
  fraction = P.start_fraction
  if e >= P.delay:
    rise = min(1.0, (e - P.delay + 1.0) / P.ramp)
    fraction += (1.0 - fraction) * rise
  N.alpha[0] = P.alpha * fraction


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def choose(P, L, N, x, n, mask, rng, learn, sample):
  """A child drawn from the softmax over theta(x, .) among those `mask` offers (the
  likeliest when not `sample`), its score added to z."""
  N.state[0] = x
  return float(policies.softmax_choose(el.trace_of(L), L.baseline, x, n, mask, N.alpha[0], learn,
                                       sample, rng, N.probs[:n], N.index[:n], N.psi[:n]))


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def observe(P, L, N, x, signal, done, terminal, n, mask, rng, learn, sample):
  """Eq. 3 with R + G and b's TD(0) step (`policies.softmax_learn`); unless done, the
  next choice in s' (x) among the children offered there."""
  if learn:
    policies.softmax_learn(el.trace_of(L), L.baseline, N.state[0], x, N.alpha[0], P.trace_gamma,
                           P.baseline, signal, done)
  if done:
    return 0.0
  return choose(P, L, N, x, n, mask, rng, learn, sample)


class GibbsTableKind(base.TableKind):
  """Runs a `GibbsTable` block: a table learner over the children its node offers."""
  block = blocks.GibbsTable
  reads = "state"
  masked = True


  def settings(self, name, block, learned_episodes):
    for field, low, high in (("alpha", 0.0, math.inf), ("trace_gamma", 0.0, 1.0),
                             ("baseline", 0.0, 1.0), ("start_fraction", 0.0, 1.0)):
      value = getattr(block, field)
      if not (isinstance(value, (int, float)) and low <= value <= high):
        raise GraphError(f"subtask {name!r}: GibbsTable.{field} = {value!r}: must be a number "
                         f"in [{low}, {high}]")
    base.check_positive_int(block, "delay", block.delay, low=0)
    base.check_positive_int(block, "ramp", block.ramp)
    return Settings(float(block.alpha), float(block.trace_gamma), float(block.baseline),
                    float(block.start_fraction), float(block.delay), float(block.ramp),
                    learned_episodes)

  def learned(self, block, n_children):
    return Learned(*el.new_trace(block.n_states * n_children), np.zeros(block.n_states))

  def parameters(self, learned):
    """theta with its pending Eq. 3 updates applied (by s * n + a), and b(s)."""
    return {"theta": el.parameters(learned), "baseline": learned.baseline.copy()}

  def scratch(self, block, n_children):
    return Scratch(np.zeros(1, dtype=np.int64), np.zeros(1), np.zeros(n_children),
                   np.zeros(n_children, dtype=np.int64), np.zeros(n_children))

  start, choose, observe = staticmethod(start), staticmethod(choose), staticmethod(observe)
