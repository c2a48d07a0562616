"""Flat Q-learning on taxi-fuel over the full state (SPEC section 5): a baseline
of HPG (tag "baseline"). One-step Watkins Q-learning, epsilon-greedy with a
linear decay; the fused loop is `train`, the step-by-step
path the one-node graph over the same Q-table."""

import dataclasses

import numba
import numpy as np

from hpg_mj.agents import _taxi
from hpg_mj import taskfile
from hpg_mj.taskfile import param
from hpg_mj.hierarchy import flat as flat_graph
from hpg_mj.hierarchy import taxi_subtasks as rules
from hpg_mj.learners import qlambda
from hpg_mj.learners import schedules
from hpg_mj.worlds import taxi_core as core
from hpg_mj.worlds import taxi_rules as world_rules

# Per-episode record columns (the order of `record_fields`).
RETURN, STEPS, OUTCOME = 0, 1, 2
N_RECORD = 3


@numba.njit(cache=True)
def train(n_episodes, first_episode, learn, sample, rng_state, world, q, tr_index, tr_value,
          tr_count, alpha, epsilon_start, epsilon_end, epsilon_episodes, record):
  """Flat Q-learning for `n_episodes`; `first_episode` places them on the schedule."""
  n_actions = core.NUM_ACTIONS_FUEL if world[world_rules.W_FUEL_ENABLED] != 0 else \
      core.NUM_ACTIONS_CLASSIC
  fuel_enabled = world[world_rules.W_FUEL_ENABLED] != 0
  state = np.empty(5, dtype=np.int64)
  episode_info = np.zeros(3, dtype=np.int64)
  for e in range(n_episodes):
    rules.sample_start(rng_state, world, state)
    episode_info[:] = 0
    qlambda.clear(tr_count)
    epsilon = schedules.linear(first_episode + e, epsilon_start, epsilon_end, epsilon_episodes) \
        if sample else 0.0
    s = core.encode_state(state[0], state[1], state[2], state[3], state[4], fuel_enabled)
    a = qlambda.epsilon_greedy(q, s, n_actions, epsilon, rng_state)
    total = 0.0
    while True:
      reward = world_rules.primitive_step(state, episode_info, a, world)
      total += reward
      s_next = core.encode_state(state[0], state[1], state[2], state[3], state[4], fuel_enabled)
      outcome = episode_info[world_rules.E_OUTCOME]
      if outcome != world_rules.RUNNING:
        if learn:
          qlambda.update(q, n_actions, tr_index, tr_value, tr_count, s, a, reward, s_next, 0,
                         outcome != world_rules.TRUNCATED, alpha, 1.0, 0.0)
        break
      a_next = qlambda.epsilon_greedy(q, s_next, n_actions, epsilon, rng_state)
      if learn:
        qlambda.update(q, n_actions, tr_index, tr_value, tr_count, s, a, reward, s_next, a_next,
                       False, alpha, 1.0, 0.0)
      s = s_next
      a = a_next
    record[e, RETURN] = total
    record[e, STEPS] = episode_info[world_rules.E_STEPS]
    record[e, OUTCOME] = episode_info[world_rules.E_OUTCOME]


class FlatQTable:
  """Flat Q-learning's learner and generator, trained step by step or compiled."""

  def __init__(self, alpha=1.0, epsilon_start=0.1, epsilon_end=0.0, epsilon_episodes=50000,
               initial=20.0, seed=0, task=None):
    from hpg_mj.learners import stepwise
    from hpg_mj.learners import rng
    self.task = task if task is not None else core.TaxiRules()
    self.world = world_rules.world_config(self.task)
    self.n_actions = core.num_actions(self.task.fuel_enabled)
    self.n_states = core.num_states(self.task.fuel_enabled, self.task.capacity)
    self.epsilon_start, self.epsilon_end = float(epsilon_start), float(epsilon_end)
    self.epsilon_episodes = int(epsilon_episodes)
    self.learner = stepwise.QLambda(self.n_states, self.n_actions, alpha, lam=0.0,
                                  epsilon_source=self._epsilon, trace_capacity=16,
                                  initial=initial)
    self.rng_state = rng.make_state(seed)
    self.episodes = 0

  def _epsilon(self):
    return schedules.linear(self.episodes, self.epsilon_start, self.epsilon_end, self.epsilon_episodes)

  def train_compiled(self, episodes, learn=True, sample=None):
    sample = learn if sample is None else (sample or learn)
    lr = self.learner
    record = np.zeros((episodes, N_RECORD))
    train(episodes, self.episodes, learn, sample, self.rng_state, self.world, lr.q, lr.index,
          lr.value, lr.count, lr.alpha, self.epsilon_start, self.epsilon_end,
          self.epsilon_episodes, record)
    if learn:
      self.episodes += episodes
    return record


@dataclasses.dataclass(frozen=True)
class Policy(taskfile.Section):
  """[policy]: Q-learning over the full state."""
  learner: str = param("q_learning", "one-step Watkins Q-learning", choices=("q_learning",))
  alpha: float = param(1.0, "step size", low=0, high=1, low_open=True)
  epsilon_start: float = param(0.1, "exploration at first", low=0, high=1)
  epsilon_end: float = param(0.0, "exploration after the decay", low=0, high=1)
  epsilon_episodes: int = param(50_000, "episodes of the linear decay", low=0)
  initial: float = param(20.0, "Q before learning")


@dataclasses.dataclass(frozen=True)
class Config:
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)
  policy: Policy = dataclasses.field(default_factory=Policy)


class TaxiFlatQ(_taxi.TaxiAgent):
  """Flat Q-learning's table and generator, trained step by step or compiled."""

  name = "taxi_flat_q"
  Config = Config
  record_fields = ("return", "steps", "outcome")
  tags = ("baseline",)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    pol = self.config.policy
    self._adopt(FlatQTable(pol.alpha, pol.epsilon_start, pol.epsilon_end,
                                  pol.epsilon_episodes, pol.initial, seed=seed, task=self.rules))
    self.engine.primitive_steps = 0

  def state(self):
    lr = self.engine.learner
    return {"rng_state": self.rng_state, "q": lr.q, "trace_index": lr.index,
            "trace_value": lr.value, "trace_count": lr.count}

  def compiled(self, episodes, learn, sample):
    before = self.engine.episodes
    rows = self.engine.train_compiled(episodes, learn=learn, sample=sample)
    self.engine.episodes = before
    return rows

  def _view(self, call, obs):
    fuel = self.rules.fuel_enabled
    return core.encode_state(*(int(v) for v in obs[:4]),
                             int(obs[4]) if fuel else core.CLASSIC_FUEL, fuel)

  def graph(self):
    return flat_graph.flat_graph(self.engine.learner, self._view,
                                 list(core.ACTION_NAMES[:self.engine.n_actions]))
