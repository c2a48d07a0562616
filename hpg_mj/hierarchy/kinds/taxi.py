"""The taxi's kinds (SPEC section 5), over the program's world (`Program(graph,
world=taxi_rules.world_config(rules))`). The observation is the taxi's numbers (row,
col, passenger, destination[, fuel]), as the fused loop and the Gymnasium and
dm_control taxis give them; the rules read it as taxi_rules' int64 state.

- `TaxiState`: a view, the full state's index (flat Q-learning's table).
- The taxi hierarchy's pieces (`hierarchy.taxi_subtasks`), by subtask: its view
  `TaxiAbstraction` (Navigate's reads its call's `target`), its `available`
  `TaxiChildren`, its termination `TaxiEnd`, and Navigate's binding `TaxiTarget`
  (the station Get, Put or Refuel goes to: `Child("navigate", bind=TaxiTarget("get"))`).
"""
import collections

import numba
import numpy as np

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy import taxi_subtasks as sub
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base
from hpg_mj.worlds import taxi_core as core
from hpg_mj.worlds import taxi_rules

Settings = collections.namedtuple("Settings", ("world", "subtask", "board"))
Settings.__doc__ = """A taxi kind's settings: `world`, taxi_rules.world_config's int64
array; `subtask`, the taxi subtask's id (`taxi_subtasks.ROOT` ...); `board`, scratch
for the state read from the observation."""


def _settings(world, block=None):
  subtask = -1 if block is None else blocks.TAXI_SUBTASKS.index(block.subtask)
  return Settings(world, np.int64(subtask), np.zeros(5, dtype=np.int64))


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _board(P, obs):
  """taxi_rules' int64 state of the observation (the classic taxi's tank stays full)."""
  s = P.board
  for i in range(4):
    s[i] = np.int64(obs[i])
  s[4] = np.int64(obs[4]) if P.world[taxi_rules.W_FUEL_ENABLED] != 0 else core.CLASSIC_FUEL
  return s


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def state_view(P, obs, call, samples):
  """TaxiState's view: the index of the full state (`taxi_rules.encoded`)."""
  return taxi_rules.encoded(obs, P.world)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def abstraction(P, obs, call, samples):
  """TaxiAbstraction's view of Root, Get, Put or Refuel: its abstract state
  (`taxi_subtasks.abstract_state`)."""
  return sub.abstract_state(P.subtask, np.int64(0), _board(P, obs), P.world)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def navigate_abstraction(P, obs, call, samples):
  """TaxiAbstraction's view of Navigate: (the call's target, row, col) as one index."""
  return sub.navigate_state(call.target, _board(P, obs))


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def offer(P, obs, call, mask):
  """TaxiChildren's `offer`: the children the subtask may choose in this state, into
  `mask` (`taxi_subtasks.children_of`)."""
  sub.children_of(P.subtask, _board(P, obs), P.world, mask)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def end(P, obs, call, samples):
  """TaxiEnd's termination of Root, Get, Put or Refuel: whether it has ended
  (`taxi_subtasks.done_of`; Root never)."""
  return sub.done_of(P.subtask, np.int64(0), _board(P, obs), P.world)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def navigate_end(P, obs, call, samples):
  """TaxiEnd's termination of Navigate: whether the taxi is at the call's target."""
  return sub.navigate_done(call.target, _board(P, obs), P.world)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def bind(P, obs, call):
  """TaxiTarget's binding: (t,), the station that Get, Put or Refuel sends Navigate
  to (`taxi_subtasks.carry_target`)."""
  return (sub.carry_target(P.subtask, _board(P, obs)),)


def _needs_target(name, block, arguments):
  if block.subtask == "navigate" and arguments.get("target") is not True:
    raise GraphError(f"subtask {name!r}: its {type(block).__name__}('navigate') reads its "
                     f"call's integer argument 'target'; its calls bind {sorted(arguments)}")


class TaxiStateKind(base.ViewKind):
  """Runs a `TaxiState` view: as many states as the world's taxi has."""
  block = blocks.TaxiState
  view = staticmethod(state_view)

  def size(self, block, world):
    return core.num_states(bool(world[taxi_rules.W_FUEL_ENABLED]),
                           int(world[taxi_rules.W_CAPACITY]))

  def settings(self, name, block, world):
    return _settings(world)


class TaxiAbstractionKind(base.ViewKind):
  """Runs a `TaxiAbstraction` view, its subtask's abstraction."""
  block = blocks.TaxiAbstraction

  def operation(self, block):
    return navigate_abstraction if block.subtask == "navigate" else abstraction

  def size(self, block, world):
    return sub.n_abstract_states(bool(world[taxi_rules.W_FUEL_ENABLED]),
                                 int(world[taxi_rules.W_CAPACITY]))[
                                     blocks.TAXI_SUBTASKS.index(block.subtask)]

  def settings(self, name, block, world):
    return _settings(world, block)

  check = staticmethod(_needs_target)


class TaxiChildrenKind(base.AvailableKind):
  """Runs a `TaxiChildren`: its subtask's available children."""
  block = blocks.TaxiChildren
  offer = staticmethod(offer)

  def settings(self, name, block, world):
    return _settings(world, block)


class TaxiEndKind(base.TerminationKind):
  """Runs a `TaxiEnd`: its subtask's termination."""
  block = blocks.TaxiEnd

  def operation(self, block):
    return navigate_end if block.subtask == "navigate" else end

  def settings(self, name, block, world):
    return _settings(world, block)

  check = staticmethod(_needs_target)


class TaxiTargetKind(base.BindingKind):
  """Runs a `TaxiTarget`: Navigate's `target`, bound by its parent."""
  block = blocks.TaxiTarget
  bind = staticmethod(bind)

  def names(self, block):
    return {"target": True}

  def settings(self, name, block, world):
    return _settings(world, block)


KINDS = (TaxiStateKind(), TaxiAbstractionKind(), TaxiChildrenKind(), TaxiEndKind(),
         TaxiTargetKind())
