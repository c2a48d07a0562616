"""Flat Q-learning on taxi-fuel over the full state (SPEC section 5).

One-step Watkins Q-learning is Q(lambda) with lambda = 0, so the rule is
`learners.qlambda.update` (written once); epsilon-greedy exploration decays
linearly from `epsilon_start` to `epsilon_end` over `epsilon_episodes` episodes.
"""
import numba
import numpy as np

from hpg_mj.hierarchy import taxi_compiled
from hpg_mj.hierarchy import taxi_rules as rules
from hpg_mj.learners import qlambda
from hpg_mj.worlds import taxi_core as core

# Per-episode record columns, as taxi_compiled's.
RETURN, STEPS, OUTCOME = 0, 1, 2
N_RECORD = 3


@numba.njit(cache=True)
def epsilon_at(episode, start, end, episodes):
  if episodes <= 0 or episode >= episodes:
    return end
  return start + (end - start) * episode / episodes


@numba.njit(cache=True)
def train(n_episodes, first_episode, learn, sample, rng_state, world, q, tr_index, tr_value,
          tr_count, alpha, epsilon_start, epsilon_end, epsilon_episodes, record):
  """Flat Q-learning for `n_episodes`; `first_episode` places them on the schedule."""
  n_actions = core.NUM_ACTIONS_FUEL if world[rules.W_FUEL_ENABLED] != 0 else \
      core.NUM_ACTIONS_CLASSIC
  fuel_enabled = world[rules.W_FUEL_ENABLED] != 0
  state = np.empty(5, dtype=np.int64)
  episode_info = np.zeros(3, dtype=np.int64)
  for e in range(n_episodes):
    taxi_compiled.sample_start(rng_state, world, state)
    episode_info[:] = 0
    qlambda.clear(tr_count)
    epsilon = epsilon_at(first_episode + e, epsilon_start, epsilon_end, epsilon_episodes) \
        if sample else 0.0
    s = core.encode_state(state[0], state[1], state[2], state[3], state[4], fuel_enabled)
    a = qlambda.epsilon_greedy(q, s, n_actions, epsilon, rng_state)
    total = 0.0
    while True:
      reward = rules.primitive_step(state, episode_info, a, world)
      total += reward
      s_next = core.encode_state(state[0], state[1], state[2], state[3], state[4], fuel_enabled)
      outcome = episode_info[rules.E_OUTCOME]
      if outcome != rules.RUNNING:
        if learn:
          qlambda.update(q, n_actions, tr_index, tr_value, tr_count, s, a, reward, s_next, 0,
                         outcome != rules.TRUNCATED, alpha, 1.0, 0.0)
        break
      a_next = qlambda.epsilon_greedy(q, s_next, n_actions, epsilon, rng_state)
      if learn:
        qlambda.update(q, n_actions, tr_index, tr_value, tr_count, s, a, reward, s_next, a_next,
                       False, alpha, 1.0, 0.0)
      s = s_next
      a = a_next
    record[e, RETURN] = total
    record[e, STEPS] = episode_info[rules.E_STEPS]
    record[e, OUTCOME] = episode_info[rules.E_OUTCOME]


class FlatQ:
  """Flat Q-learning's learner and generator, trained step by step or compiled."""

  def __init__(self, alpha=1.0, epsilon_start=0.1, epsilon_end=0.0, epsilon_episodes=50000,
               initial=20.0, seed=0, task=None):
    from hpg_mj.learners import agents
    from hpg_mj.learners import rng
    self.task = task if task is not None else core.TaxiRules()
    self.world = rules.world_config(self.task)
    self.n_actions = core.num_actions(self.task.fuel_enabled)
    self.n_states = core.num_states(self.task.fuel_enabled, self.task.capacity)
    self.epsilon_start, self.epsilon_end = float(epsilon_start), float(epsilon_end)
    self.epsilon_episodes = int(epsilon_episodes)
    self.learner = agents.QLambda(self.n_states, self.n_actions, alpha, lam=0.0,
                                  epsilon_source=self._epsilon, trace_capacity=16,
                                  initial=initial)
    self.rng_state = rng.make_state(seed)
    self.episodes = 0

  def _epsilon(self):
    return epsilon_at(self.episodes, self.epsilon_start, self.epsilon_end, self.epsilon_episodes)

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
