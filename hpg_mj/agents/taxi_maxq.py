"""MAXQ-Q (Dietterich 2000) on taxi-fuel over the task graph of SPEC section 5: a
baseline of HPG (tag "baseline"). The fused loop is `baselines.taxi_maxq.train`;
the step-by-step path runs the same compiled rules through `MAXQNode` learners on
the shared taxi graph (`hierarchy.taxi.taxi_graph`), below. A node's choice needs
its children's values, which MAXQ evaluates recursively down the graph, so a node
sees the full state (its view is `(t, state)`) and abstracts it itself.
"""
import dataclasses

import numpy as np

from hpg_mj.agents import _taxi
from hpg_mj.agents.taskfile import param
from hpg_mj.baselines import taxi_maxq as mq
from hpg_mj.hierarchy import taxi
from hpg_mj.hierarchy import taxi_rules as rules

LEVELS = ("root", "carry", "navigate")


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
  cls = dataclasses.make_dataclass("Level", fields, frozen=True)
  cls.__doc__ = doc
  return cls


Root = _level(1.0, 14_000, 20.0, False, "[root]: Root -> {Get, Put, Refuel}; sees the full state")
Carry = _level(0.1, 6_000, 0.0, True, "[carry]: Get, Put, Refuel (each its own tables)")
Navigate = _level(0.1, 1_000, 0.0, True, "[navigate]: Navigate(t), over (t, row, col, fuel)")


@dataclasses.dataclass(frozen=True)
class Primitive:
  """[primitive]: V(a, s) over (classic state, tank empty)."""
  alpha: float = param(1.0, "V(a, s) step size", low=0, high=1, low_open=True)
  all_states_updating: bool = param(True, "a child's target updates every state its run "
                                    "passed through")


@dataclasses.dataclass(frozen=True)
class Config:
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)
  root: Root = dataclasses.field(default_factory=Root)
  carry: Carry = dataclasses.field(default_factory=Carry)
  navigate: Navigate = dataclasses.field(default_factory=Navigate)
  primitive: Primitive = dataclasses.field(default_factory=Primitive)


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


class TaxiMAXQ(_taxi.TaxiAgent):
  """MAXQ-Q's tables and generator, trained step by step or compiled."""

  name = "taxi_maxq"
  Config = Config
  record_fields = ("return", "steps", "outcome")
  tags = ("baseline",)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    kwargs = {}
    for level in LEVELS:
      sec = getattr(self.config, level)
      kwargs.update({f"alpha_{level}": sec.alpha, f"epsilon_{level}": sec.epsilon,
                     f"epsilon_episodes_{level}": sec.epsilon_episodes,
                     f"initial_{level}": sec.initial})
      if level != "root":
        kwargs[f"pseudo_reward_{level}"] = sec.pseudo_reward
    prim = self.config.primitive
    config = mq.MAXQConfig(alpha_primitive=prim.alpha, all_states=prim.all_states_updating,
                           **kwargs)
    self._adopt(mq.TaxiMAXQ(seed=seed, config=config, task=self.rules))
    self.hierarchy = TaxiMAXQHierarchy(self.engine)

  def state(self):
    a = self.engine
    return {"rng_state": self.rng_state, "primitive_values": a.values,
            "completions_pseudo": a.c_tilde, "completions": a.c}

  def compiled(self, episodes, learn, sample):
    before = self.engine.episodes
    rows = self.engine.run(episodes, learn=learn, sample=sample)
    self.engine.episodes = before
    return rows

  def graph(self):
    return self.hierarchy.graph()

  def begin_episode(self, learn):
    h = self.hierarchy
    mq.epsilons_at(h.settings, self.engine.episodes, h.epsilons)
    h.cursor[0] = 0
