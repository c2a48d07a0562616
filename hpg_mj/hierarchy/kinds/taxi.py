"""The taxi's kinds (SPEC section 5), over the program's world (`Program(graph,
world=taxi_rules.world_config(rules))`): the TaxiState view, the full state's index
(flat Q-learning's table). The observation is the taxi's numbers (row, col,
passenger, destination[, fuel]), as the fused loop and the Gymnasium and dm_control
taxis give them."""
import collections

import numba

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.kinds import base
from hpg_mj.worlds import taxi_core as core
from hpg_mj.worlds import taxi_rules

# `world`: taxi_rules.world_config's int64 array.
Settings = collections.namedtuple("Settings", ("world",))


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def state_view(P, obs, call, samples):
  return taxi_rules.encoded(obs, P.world)


class TaxiStateKind(base.ViewKind):
  block = blocks.TaxiState
  gives = "state"
  view = staticmethod(state_view)

  def size(self, block, world):
    return core.num_states(bool(world[taxi_rules.W_FUEL_ENABLED]),
                           int(world[taxi_rules.W_CAPACITY]))

  def settings(self, name, block, world):
    return Settings(world)
