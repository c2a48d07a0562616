"""The taxi-fuel hierarchy (MAXQ's task graph with Refuel; paper section 5.1;
SPEC section 5), on the task-graph API:

    Root -> {Get, Put, Refuel}
    Get -> {Navigate(t = passenger's station), Pickup}
    Put -> {Navigate(t = destination), Dropoff}
    Refuel -> {Navigate(t = F), Fillup}
    Navigate(t) -> {South, North, East, West}

`taxi_graph` builds it over given learners, one per subtask, with Python callables
for the pure-Python executor: MAXQ-Q's step-by-step path (`hpg_mj.agents.taxi_maxq`;
MAXQ-Q keeps its own engine, `hierarchy.maxq`). Taxi HPG's graph is the same one
made of blocks (`hpg_mj.agents.taxi_hpg.graph`: the same `taxi_subtasks` rules),
which the task-graph machine runs.
"""
import numpy as np

from hpg_mj.hierarchy import taxi_subtasks as rules
from hpg_mj.hierarchy.graph import Child, Primitive, Subtask, TaskGraph
from hpg_mj.worlds import taxi_core as core

def rules_state(obs, fuel_enabled, out):
  """The observation as taxi_rules' int64 state in `out` (classic: the tank stays full)."""
  out[:4] = obs[:4]
  out[4] = obs[4] if fuel_enabled else core.CLASSIC_FUEL
  return out


def taxi_graph(world, learners, state_of, view_of):
  """The task graph above over `learners` (by subtask id), for the executor:
  `state_of(obs)` is taxi_rules' state of an observation, `view_of(subtask id)`
  the view function of that subtask."""

  def available(fill):
    def check(call, obs, i):
      mask = np.zeros(rules.MAX_CHILDREN, dtype=np.bool_)
      fill(state_of(obs), mask)
      return bool(mask[i])
    return check

  def carry(subtask, name, primitive):
    return Subtask(
        name, learner=learners[subtask], view=view_of(subtask),
        children=[Child("navigate", bind=lambda call, obs: {
            "target": int(rules.carry_target(subtask, state_of(obs)))}), primitive],
        available=available(lambda s, m: rules.carry_children(subtask, s, world, m)),
        termination=lambda call, step: bool(rules.carry_done(subtask, state_of(step.obs), world)))

  return TaskGraph("root", [
      Subtask("root", learner=learners[rules.ROOT], children=["get", "put", "refuel"],
              view=view_of(rules.ROOT),
              available=available(lambda s, m: rules.root_children(s, world, m)),
              termination=lambda call, step: False),          # ends with the episode
      carry(rules.GET, "get", "pickup"), carry(rules.PUT, "put", "dropoff"),
      carry(rules.REFUEL, "refuel", "fillup"),
      Subtask("navigate", learner=learners[rules.NAVIGATE],
              children=["south", "north", "east", "west"], view=view_of(rules.NAVIGATE),
              termination=lambda call, step: bool(
                  rules.navigate_done(call.args["target"], state_of(step.obs), world))),
      Primitive("south", core.SOUTH), Primitive("north", core.NORTH),
      Primitive("east", core.EAST), Primitive("west", core.WEST),
      Primitive("pickup", core.PICKUP), Primitive("dropoff", core.DROPOFF),
      Primitive("fillup", core.FILLUP),
  ])
