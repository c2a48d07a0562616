"""MAXQ-Q (Dietterich 2000) on taxi-fuel, a baseline of HPG (tag "baseline"): its
configuration by level, its step-by-step nodes over the task graph of
`hierarchy.taxi` and its metrics. The algorithm, its fused loop, its tables and the
exact values it converges to are `hpg_mj.hierarchy.maxq` (which says why MAXQ-Q
keeps its own engine rather than the task-graph machine).
"""
import dataclasses

import numpy as np

from hpg_mj.agents import _taxi
from hpg_mj import taskfile
from hpg_mj.taskfile import param
from hpg_mj.hierarchy import taxi
from hpg_mj.hierarchy import taxi_subtasks as rules
from hpg_mj.hierarchy.maxq import (N_PRIMITIVES, MAXQEngine, choose, completion_table,
                                   epsilons_at, new_scratch, primitive_state, record_state,
                                   update_completion, update_primitive)


def _level(epsilon, epsilon_episodes, initial, pseudo_reward, doc):
  fields = [
      ("learner", str, param("maxq_q", "MAXQ-Q", choices=("maxq_q",))),
      ("alpha", float, param(1.0, "completion step size", low=0, high=1, low_open=True)),
      ("epsilon", float, param(epsilon, "epsilon-greedy at first, decaying linearly to 0",
                               low=0, high=1)),
      ("epsilon_episodes", int, param(epsilon_episodes, "episodes of the decay", low=0)),
      ("initial", float, param(initial, "C~ and C before learning")),
  ]
  if pseudo_reward:
    fields.append(("pseudo_reward", float, param(0.0, "C~'s reward when the subtask ends")))
  cls = dataclasses.make_dataclass("Level", fields, frozen=True, bases=(taskfile.Section,))
  cls.__doc__ = doc
  return cls


Root = _level(1.0, 14_000, 20.0, False, "[root]: Root -> {Get, Put, Refuel}; sees the full state")
Carry = _level(0.1, 6_000, 0.0, True, "[carry]: Get, Put, Refuel (each its own tables)")
Navigate = _level(0.1, 1_000, 0.0, True, "[navigate]: Navigate(t), over (t, row, col, fuel)")


@dataclasses.dataclass(frozen=True)
class PrimitiveLevel(taskfile.Section):
  """[primitive]: V(a, s) over (classic state, tank empty)."""
  alpha: float = param(1.0, "V(a, s) step size", low=0, high=1, low_open=True)
  all_states_updating: bool = param(True, "a child's target updates every state its run "
                                    "passed through")


@dataclasses.dataclass(frozen=True)
class Config:
  """MAXQ-Q's hyper-parameters, by level: [root]; [carry] (Get, Put and Refuel);
  [navigate] (Navigate(t)); and [primitive], the primitives' V(a, s).

  Exploration is epsilon-greedy, decaying linearly from each level's epsilon to 0
  over its epsilon_episodes, bottom-up: a parent learns C from its children's actual
  runs, so a child's exploration writes wrong completions into its parent (an
  exploring Navigate that runs the tank dry on the way teaches Put that the way is
  fatal). Each level keeps exploring after the one below has turned greedy, to
  repair them. Root starts fully random: it decides a few times an episode, so
  exploring there is cheap, and it has 6,500 rows to visit. Step sizes of 1: the
  taxi is deterministic, and once the children are greedy so is every target.
  Root's optimistic initial completions (20: no return exceeds +20) make it try
  every child.
  """
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)
  root: Root = dataclasses.field(default_factory=Root)
  carry: Carry = dataclasses.field(default_factory=Carry)
  navigate: Navigate = dataclasses.field(default_factory=Navigate)
  primitive: PrimitiveLevel = dataclasses.field(default_factory=PrimitiveLevel)


class MAXQNode:
  """One subtask's MAXQ-Q learner, in the executor's protocol (`learners.stepwise`).

  act: an epsilon-greedy child by V(a, s) + C~(i, s, a) (`choose`); a
  primitive child's state goes on the episode's path (all-states updating).
  observe: a primitive child's V(a, s), then C~(i, ., a) and C(i, ., a)
  (`update_completion`), as the fused loop does after each child."""

  def __init__(self, subtask, shared):
    self.subtask = subtask
    self.shared = shared
    self._child = -1
    self._target = 0
    self._first = 0
    self._primitive = -1           # V(a, s)'s index when the child is a primitive

  def start(self):
    """The subtask is called: nothing to reset (MAXQ-Q keeps no trace)."""
    pass

  def act(self, features, mask, rng_state, sample):
    """An epsilon-greedy child by V(a, s) + C~(i, s, a) (greedy when not `sample`);
    `features` is (target, state)."""
    target, state = features
    h = self.shared
    a = choose(self.subtask, target, state, h.world, h.tables, h.epsilons[self.subtask],
               sample, rng_state, h.scratch)
    self._child, self._target, self._first = a, target, int(h.cursor[0])
    self._primitive = -1
    action = a if self.subtask == rules.NAVIGATE else (
        rules.carry_primitive(self.subtask) if a == rules.CARRY_PRIMITIVE and
        self.subtask != rules.ROOT else -1)
    if action >= 0:
      record_state(h.path, state, self._first)
      self._primitive = primitive_state(state, h.world) * N_PRIMITIVES + action
    return a

  def observe(self, signal, next_features, done, terminal, learn):
    """The child returned: a primitive's V(a, s), then C~ and C over the states of
    the child's run (`update_completion`), when learning."""
    h = self.shared
    if self._primitive >= 0:
      h.cursor[0] += 1
      if learn:
        update_primitive(h.values, self._primitive, signal, h.alpha_primitive)
    if learn:
      ended = next_features is None                 # a delivery or an empty tank
      after = h.path[self._first] if ended else next_features[1]
      update_completion(self.subtask, self._target, self._child, h.path, self._first,
                        int(h.cursor[0]), after, ended, h.world, h.tables, h.settings,
                        h.all_states, h.scratch)

  def parameters(self):
    """This subtask's C (a copy), (abstract states, children)."""
    return completion_table(self.shared.c, self.shared.offsets, self.subtask).copy()


class TaxiMAXQHierarchy:
  """The task graph over a `MAXQEngine`' tables (shared arrays, same generator)."""

  def __init__(self, agent: "MAXQEngine"):
    self.agent = agent
    self.world = agent.world
    self.tables = agent.tables
    self.values = agent.values
    self.settings = agent.settings
    self.alpha_primitive = float(agent.config.primitive.alpha)
    self.all_states = bool(agent.config.primitive.all_states_updating)
    self.epsilons = np.zeros(rules.N_SUBTASKS)
    self.scratch = new_scratch()
    self.path = np.zeros((agent.task.max_steps, 5), dtype=np.int64)
    self.cursor = np.zeros(1, dtype=np.int64)          # primitive steps in this episode
    self.learners = [MAXQNode(i, self) for i in range(rules.N_SUBTASKS)]
    self._state = np.zeros(5, dtype=np.int64)

  def _view(self, call, obs):
    return call.args.get("target", 0), self._s(obs).copy()

  def _s(self, obs):
    return taxi.rules_state(obs, self.agent.task.fuel_enabled, self._state)

  def graph(self):
    """The taxi's task graph, MAXQ-Q's nodes its learners."""
    return taxi.taxi_graph(self.world, self.learners, self._s, lambda subtask: self._view)


class TaxiMAXQ(_taxi.TaxiAgent):
  """MAXQ-Q's tables and generator, trained step by step or compiled."""

  name = "taxi_maxq"
  Config = Config
  record_fields = ("return", "steps", "outcome")
  tags = ("baseline",)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    self._adopt(MAXQEngine(seed=seed, config=self.config, task=self.rules))
    self.hierarchy = TaxiMAXQHierarchy(self.engine)

  def state(self):
    a = self.engine
    return {"rng_state": self.rng_state, "primitive_values": a.values,
            "completions_pseudo": a.c_tilde, "completions": a.c}

  def compiled(self, episodes, learn, sample):
    """`episodes` episodes of the fused MAXQ-Q loop, as (episodes, 3) float rows."""
    before = self.engine.episodes
    rows = self.engine.run(episodes, learn=learn, sample=sample)
    self.engine.episodes = before
    return rows

  def graph(self):
    return self.hierarchy.graph()

  def begin_episode(self, learn):
    h = self.hierarchy
    epsilons_at(h.settings, self.engine.episodes, h.epsilons)
    h.cursor[0] = 0
