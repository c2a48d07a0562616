"""The continuing ship's kinds (SPEC section 8; `agents.ship_patrol`):

  RLearning           average-reward SMDP Q-learning (`learners.average_reward`):
                      relative values Q and the gain rho, epsilon-greedy, each call
                      of tau steps backed up as (s, a, R, tau, s'), optionally with
                      a planning sweep every `planning_every` decisions
  PatrolCell          the root's view: the 50 m cell (finer near the gate) and the
                      heading's sector (`ship_rules.root_state`)
  Clock(steps)        a continuing root's end: a record row of `steps` primitive
                      steps, ended between its children's calls; the world's events
                      end its children's calls only (`algorithm.CONTINUING`)
"""
import collections

import numba
import numpy as np

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy import ship_rules
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base
from hpg_mj.learners import average_reward
from hpg_mj.learners import qlambda
from hpg_mj.worlds import ship_core as core

Settings = collections.namedtuple("Settings", ("alpha", "gain_step", "epsilon",
                                               "planning_every"))
Settings.__doc__ = """An RLearning's settings `P`: the step sizes of Q and of the gain,
`epsilon` (float64[1], its own or the graph's schedule's) and the decisions between
planning sweeps."""
Learned = collections.namedtuple("Learned", ("q", "gain", "model_next", "model_reward",
                                             "model_steps", "model_count"))
Learned.__doc__ = """What an RLearning learns, saved by these names: Q(s, a) at
s * n + a, the gain [rho, greedy transitions seen], and the planning model of each
(s, a)'s latest transition."""
Scratch = collections.namedtuple("Scratch", ("last", "tau"))
Scratch.__doc__ = """A node's scratch: [s, a, whether a was greedy] of its last
choice; tau, the steps of its current child's run (live: the program's)."""
ViewSettings = collections.namedtuple("ViewSettings", ("sectors", "near_gate_m",
                                                       "near_gate_cell_m"))
ViewSettings.__doc__ = """A PatrolCell's settings: the heading's sectors, the distance
in m from the gate within which cells are finer, and their side in m."""
ClockSettings = collections.namedtuple("ClockSettings", ("steps",))
ClockSettings.__doc__ = """A Clock's settings: the primitive steps of a record row."""


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def choose(P, L, N, x, n, rng, learn, sample):
  """A child chosen in state x, epsilon-greedy over Q(x, .) (greedy when not
  `sample`); whether it was greedy is kept for the gain's update."""
  a = qlambda.epsilon_greedy(L.q, x, n, P.epsilon[0] if sample else 0.0, rng)
  N.last[0] = x
  N.last[1] = a
  N.last[2] = average_reward.is_greedy(L.q, x, a, n)
  return float(a)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def observe(P, L, N, x, signal, done, terminal, n, rng, learn, sample):
  """(s, a, R, tau, s') backed up (and remembered for planning); unless done, the next
  choice in s'."""
  if learn:
    s, a, tau = N.last[0], N.last[1], float(N.tau[0])
    average_reward.update(L.q, n, L.gain, s, a, signal, tau, x, P.alpha, P.gain_step,
                          N.last[2] != 0)
    average_reward.remember_and_plan(
        L.q, n, L.gain, (L.model_next, L.model_reward, L.model_steps, L.model_count), s, a,
        signal, tau, x, P.alpha, P.planning_every)
  if done:
    return 0.0
  return choose(P, L, N, x, n, rng, learn, sample)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def patrol_cell(P, obs, call, samples):
  """The root's state: the ship's cell and heading sector
  (`ship_rules.root_state`)."""
  return ship_rules.root_state(obs, P.sectors, P.near_gate_m, P.near_gate_cell_m)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def clock(P, obs, call, samples):
  """A success once the call has run `steps` primitive steps, else no event."""
  return core.SUCCESS if call.steps >= P.steps else core.NO_EVENT


class RLearningKind(base.TableKind):
  """Runs an `RLearning` block: a table learner of relative values and the gain."""
  block = blocks.RLearning

  def check(self, name, block, n_children, view_size):
    super().check(name, block, n_children, view_size)
    base.check_positive_int(block, "planning_every", block.planning_every, low=0)

  def settings(self, name, block, schedule=None):
    for field in ("alpha", "gain_step", "epsilon"):
      value = getattr(block, field)
      if not (isinstance(value, (int, float)) and 0.0 <= value <= 1.0):
        raise GraphError(f"subtask {name!r}: RLearning.{field} = {value!r}: must be a number "
                         "in [0, 1]")
    epsilon = schedule.epsilon if block.epsilon_schedule else np.array([float(block.epsilon)])
    return Settings(float(block.alpha), float(block.gain_step), epsilon,
                    np.int64(block.planning_every))

  def learned(self, block, n_children):
    size = int(block.n_states) * n_children
    return Learned(np.zeros(size), average_reward.new_gain(),        # (no model unplanned)
                   *average_reward.new_model(size if block.planning_every > 0 else 0))

  def parameters(self, learned):
    """The relative values Q(s, a) and the gain [rho, greedy transitions seen]."""
    return {"q": learned.q.copy(), "gain": learned.gain.copy()}

  def scratch(self, block, n_children, child_steps):
    return Scratch(np.zeros(3, dtype=np.int64), child_steps)

  start, choose, observe = (staticmethod(base.no_start), staticmethod(choose),
                            staticmethod(observe))


class PatrolCellKind(base.ViewKind):
  """Runs a `PatrolCell` view."""
  block = blocks.PatrolCell
  view = staticmethod(patrol_cell)

  def size(self, block):
    return int(block.n_states())

  def settings(self, name, block):
    base.check_positive_int(block, "heading_sectors", block.heading_sectors)
    return ViewSettings(np.int64(block.heading_sectors), float(block.near_gate_m),
                        float(block.near_gate_cell_m))


class ClockKind(base.TerminationKind):
  """Runs a `Clock`: a continuing root's end."""
  block = blocks.Clock
  end = staticmethod(clock)
  continuing = True

  def settings(self, name, block):
    return ClockSettings(np.int64(base.check_positive_int(block, "steps", block.steps)))


KINDS = (RLearningKind(), PatrolCellKind(), ClockKind())
