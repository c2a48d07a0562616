"""The taxi-fuel hierarchy (MAXQ's task graph with Refuel; paper section 5.1;
SPEC section 5), on the task-graph API:

    Root -> {Get, Put, Refuel}
    Get -> {Navigate(t = passenger's station), Pickup}
    Put -> {Navigate(t = destination), Dropoff}
    Refuel -> {Navigate(t = F), Fillup}
    Navigate(t) -> {South, North, East, West}

Each subtask learns a Gibbs policy by Eq. 3 over its abstract state
(`taxi_rules`), with the baseline of `taxi_compiled.HPGConfig`. `TaxiHierarchy`
trains step by step through a taxi environment on the arrays of a
`taxi_compiled.TaxiHPG` (policies and baselines), so the two paths share one
agent and one set of rule functions.
"""
import numpy as np

from hpg_mj.hierarchy import executor as executor_mod
from hpg_mj.hierarchy import taxi_compiled
from hpg_mj.hierarchy import taxi_rules as rules
from hpg_mj.hierarchy.graph import Child, Primitive, Subtask, TaskGraph
from hpg_mj.learners import agents
from hpg_mj.worlds import taxi_core as core

_TRACE_KEYS = ("w", "zs", "y", "touched", "marked", "count", "acc")


def rules_state(obs, fuel_enabled, out):
  """The observation as taxi_rules' int64 state in `out` (classic: the tank stays full)."""
  out[:4] = obs[:4]
  out[4] = obs[4] if fuel_enabled else core.CLASSIC_FUEL
  return out


def taxi_graph(world, learners, state_of, view_of):
  """The task graph above over `learners` (by subtask id), for HPG and MAXQ-Q alike:
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


def outcome_of(last):
  """How an episode ended, from the executor's last step (taxi_rules' codes)."""
  return (rules.TRUNCATED if last.truncated else
          rules.DELIVERED if last.reward == core.DELIVERY_REWARD else rules.OUT_OF_FUEL)


class _BaselinedSoftmax(agents.SoftmaxPolicyGradient):
  """The Gibbs learner with the compiled loop's baseline b(s) (`taxi_compiled`):
  Eq. 3, plus theta <- theta - alpha b(s) psi(s, a) for each choice and a TD(0)
  step of b when the child returns, by the same compiled functions.

  theta <- theta - alpha b(s) psi(s, a) is applied when the child returns, not
  at the choice as in the compiled loop: the child never touches this
  subtask's parameters, so the numbers are the same, and only then does the
  executor say whether it is learning.
  """

  def __init__(self, n_states, n_actions, values, beta):
    super().__init__(n_states, n_actions, alpha=1.0)
    self.values = values      # the compiled loop's baseline table (shared)
    self.beta = float(beta)
    self._here = 0
    self._mask = self._all

  def act(self, features, mask, rng_state, sample):
    self._here = int(features)
    self._mask = self._all if mask is None else mask
    return super().act(features, mask, rng_state, sample)

  def observe(self, signal, next_features, done, terminal, learn):
    taxi_compiled.subtract_baseline(self.trace["w"], self.values, self._here, self.n_actions,
                                    self._mask, learn, self.alpha, self._index, self._psi)
    super().observe(signal, next_features, done, terminal, learn)
    taxi_compiled.learn_baseline(self.values, self._here, learn, self.beta, signal, done,
                                 0 if next_features is None else int(next_features))


class TaxiHierarchy:
  """The task graph over a `TaxiHPG`'s learners (shared arrays)."""

  def __init__(self, hpg: taxi_compiled.TaxiHPG):
    self.hpg = hpg
    self.world = hpg.world
    sizes = rules.n_abstract_states(hpg.task.fuel_enabled, hpg.task.capacity)
    self.learners = []
    betas = hpg.config.betas()
    for i, trace in enumerate(hpg.traces):
      learner = _BaselinedSoftmax(sizes[i], rules.N_CHILDREN[i], hpg.values[i], betas[i])
      learner.trace = dict(zip(_TRACE_KEYS, trace))       # the compiled loop's arrays
      learner.gamma = float(hpg.config.gammas()[i])
      self.learners.append(learner)
    self._alphas = np.zeros(rules.N_SUBTASKS)
    self._state = np.zeros(5, dtype=np.int64)

  def _s(self, obs):
    return rules_state(obs, self.hpg.task.fuel_enabled, self._state)

  def graph(self):
    w = self.world
    views = {
        rules.ROOT: lambda call, obs: int(rules.root_state(self._s(obs), w)),
        rules.NAVIGATE: lambda call, obs: int(rules.navigate_state(call.args["target"],
                                                                   self._s(obs))),
    }
    for i in (rules.GET, rules.PUT, rules.REFUEL):
      views[i] = lambda call, obs, i=i: int(rules.carry_state(i, self._s(obs)))
    return taxi_graph(w, self.learners, self._s, views.__getitem__)
