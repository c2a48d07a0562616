"""MAXQ-Q on the taxi-fuel task graph (Dietterich 2000; SPEC section 5), on the
task-graph API:

    Root -> {Get, Put, Refuel}
    Get -> {Navigate(t = passenger's station), Pickup}
    Put -> {Navigate(t = destination), Dropoff}
    Refuel -> {Navigate(t = F), Fillup}
    Navigate(t) -> {South, North, East, West}

Each subtask's learner is a `MAXQNode`: its completion functions C~ and C, and
for its primitive children V(a, s). A node's choice needs its children's values,
which MAXQ evaluates recursively down the graph, so a node sees the full state
(its view is `(t, state)`) and abstracts it itself (`baselines.taxi_maxq`).
`TaxiMAXQHierarchy` trains step by step through a taxi environment on the
arrays of a `baselines.taxi_maxq.TaxiMAXQ`, and its nodes call the compiled
rules of the fused loop (`choose_child`, `update_primitive`, `learn_completion`),
so the two paths are one algorithm (tested bit for bit).
"""
import numpy as np

from hpg_mj.baselines import taxi_maxq as mq
from hpg_mj.hierarchy import executor as executor_mod
from hpg_mj.hierarchy import taxi
from hpg_mj.hierarchy import taxi_compiled
from hpg_mj.hierarchy import taxi_rules as rules


class MAXQNode:
  """One subtask's MAXQ-Q learner, in the executor's protocol (`learners.agents`).

  act: an epsilon-greedy child by V(a, s) + C~(i, s, a) (`choose_child`); a
  primitive child's state goes on the episode's path (all-states updating).
  observe: a primitive child's V(a, s), then C~(i, ., a) and C(i, ., a)
  (`learn_completion`), as the fused loop does after each child."""

  def __init__(self, subtask, shared):
    self.subtask = subtask
    self.shared = shared
    self._child = -1
    self._target = 0
    self._first = 0
    self._primitive = -1           # V(a, s)'s index when the child is a primitive

  def start(self):
    pass

  def act(self, features, mask, rng_state, sample):
    target, state = features
    h = self.shared
    a = mq.choose_child(self.subtask, target, state, h.world, h.values, h.c_tilde, h.c,
                        h.offsets, h.epsilons[self.subtask], sample, rng_state, *h.scratch)
    self._child, self._target, self._first = a, target, int(h.cursor[0])
    self._primitive = -1
    action = a if self.subtask == rules.NAVIGATE else (
        rules.carry_primitive(self.subtask) if a == rules.CARRY_PRIMITIVE and
        self.subtask != rules.ROOT else -1)
    if action >= 0:
      mq.record_state(h.path, state, self._first)
      self._primitive = mq.primitive_state(state, h.world) * mq.N_PRIMITIVES + action
    return a

  def observe(self, signal, next_features, done, terminal, learn):
    h = self.shared
    if self._primitive >= 0:
      h.cursor[0] += 1
      if learn:
        mq.update_primitive(h.values, self._primitive, signal, h.alpha_primitive)
    if learn:
      ended = next_features is None                 # a delivery or an empty tank
      after = h.path[self._first] if ended else next_features[1]
      mq.learn_completion(self.subtask, self._target, self._child, h.path, self._first,
                          int(h.cursor[0]), after, ended, h.world, h.values, h.c_tilde, h.c,
                          h.offsets, h.settings, h.all_states, *h.scratch)

  def parameters(self):
    """This subtask's C (a copy), (abstract states, children)."""
    return mq.completion_table(self.shared.c, self.shared.offsets, self.subtask).copy()


class TaxiMAXQHierarchy:
  """The task graph over a `TaxiMAXQ`'s tables (shared arrays, same generator)."""

  def __init__(self, agent: mq.TaxiMAXQ):
    self.agent = agent
    self.world = agent.world
    self.values, self.c_tilde, self.c, self.offsets = (agent.values, agent.c_tilde, agent.c,
                                                       agent.offsets)
    self.settings = agent.settings
    self.alpha_primitive = float(agent.config.alpha_primitive)
    self.all_states = bool(agent.config.all_states)
    self.epsilons = np.zeros(rules.N_SUBTASKS)
    self.scratch = mq.new_scratch()
    self.path = np.zeros((agent.task.max_steps, 5), dtype=np.int64)
    self.cursor = np.zeros(1, dtype=np.int64)          # primitive steps in this episode
    self.learners = [MAXQNode(i, self) for i in range(rules.N_SUBTASKS)]
    self._state = np.zeros(5, dtype=np.int64)

  def _view(self, call, obs):
    return call.args.get("target", 0), self._s(obs).copy()

  def _s(self, obs):
    return taxi.rules_state(obs, self.agent.task.fuel_enabled, self._state)

  def graph(self):
    return taxi.taxi_graph(self.world, self.learners, self._s, lambda subtask: self._view)
