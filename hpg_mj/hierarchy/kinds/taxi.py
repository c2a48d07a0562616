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

# `world`: taxi_rules.world_config's int64 array; `subtask`: the taxi subtask's id
# (`taxi_subtasks.ROOT` ...); `board`: the state read from the observation.
Settings = collections.namedtuple("Settings", ("world", "subtask", "board"))


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


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def state_view(P, obs, call, samples):
  return taxi_rules.encoded(obs, P.world)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def abstraction(P, obs, call, samples):
  return sub.abstract_state(P.subtask, np.int64(0), _board(P, obs), P.world)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def navigate_abstraction(P, obs, call, samples):
  return sub.navigate_state(call.target, _board(P, obs))


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def offer(P, obs, call, mask):
  sub.children_of(P.subtask, _board(P, obs), P.world, mask)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def end(P, obs, call, samples):
  return sub.done_of(P.subtask, np.int64(0), _board(P, obs), P.world)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def navigate_end(P, obs, call, samples):
  return sub.navigate_done(call.target, _board(P, obs), P.world)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def bind(P, obs, call):
  return (sub.carry_target(P.subtask, _board(P, obs)),)


def _needs_target(name, block, arguments):
  if block.subtask == "navigate" and arguments.get("target") is not True:
    raise GraphError(f"subtask {name!r}: its {type(block).__name__}('navigate') reads its "
                     f"call's integer argument 'target'; its calls bind {sorted(arguments)}")


class TaxiStateKind(base.ViewKind):
  block = blocks.TaxiState
  view = staticmethod(state_view)

  def size(self, block, world):
    return core.num_states(bool(world[taxi_rules.W_FUEL_ENABLED]),
                           int(world[taxi_rules.W_CAPACITY]))

  def settings(self, name, block, world):
    return _settings(world)


class TaxiAbstractionKind(base.ViewKind):
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
  block = blocks.TaxiChildren
  offer = staticmethod(offer)

  def settings(self, name, block, world):
    return _settings(world, block)


class TaxiEndKind(base.TerminationKind):
  block = blocks.TaxiEnd

  def operation(self, block):
    return navigate_end if block.subtask == "navigate" else end

  def settings(self, name, block, world):
    return _settings(world, block)

  check = staticmethod(_needs_target)


class TaxiTargetKind(base.BindingKind):
  block = blocks.TaxiTarget
  bind = staticmethod(bind)

  def names(self, block):
    return {"target": True}

  def settings(self, name, block, world):
    return _settings(world, block)


KINDS = (TaxiStateKind(), TaxiAbstractionKind(), TaxiChildrenKind(), TaxiEndKind(),
         TaxiTargetKind())
