"""Flat learners on the full ship task (SPEC section 4), in compiled loops.

* Flat PGRL: Eq. 3 over the whole episode with the Gaussian-with-sigmoid policy
  on a CMAC of 9 tilings x 20 x 20 x 36 x 5 = 72,000 tiles (648,000 weights).
* Actor-critic (Konda): the same actor; a linear critic over 9 tilings of
  5 x 5 x 36 x 5 x 30 = 135,000 tiles of (x, y, theta, theta_dot, r), learned by
  TD(lambda) (SARSA-style on the actions taken); the actor steps along
  Q_critic(s, a) * psi(s, a).

Both act every 0.6 s with SPEC section 2's rewards. Every step touches only the
active tiles (9 for the actor, 9 for the critic): traces are applied lazily
(`learners.eligibility`), so the cost of a step does not grow with the episode
or the number of weights.
"""
import numba
import numpy as np

from hpg_mj.hierarchy import ship_compiled
from hpg_mj.hierarchy import ship_rules as rules
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core as core

# Per-episode record columns (the hybrid's PASSED, STEPS; then the return).
PASSED, STEPS, RETURN = 0, 1, 2
N_RECORD = 3


def actor_coder(n_tilings=9, tiles=(20, 20, 36, 5)):
  return tiles_mod.TileCoder((0.0, 0.0, -180.0, -core.MAX_TURN_RATE),
                             (core.FIELD_SIZE, core.FIELD_SIZE, 180.0, core.MAX_TURN_RATE),
                             tuple(tiles), (False, False, True, False), n_tilings)


def critic_coder(n_tilings=9, tiles=(5, 5, 36, 5, 30)):
  return tiles_mod.TileCoder(
      (0.0, 0.0, -180.0, -core.MAX_TURN_RATE, -core.MAX_TURN_RATE),
      (core.FIELD_SIZE, core.FIELD_SIZE, 180.0, core.MAX_TURN_RATE, core.MAX_TURN_RATE),
      tuple(tiles), (False, False, True, False, False), n_tilings)


@numba.njit(cache=True)
def train_flat_pg(n_episodes, learn, sample, rng_state, w, zs, y, touched, marked, count, acc,
                  t_low, t_width, t_n, t_wrap, t_offsets, alpha, gamma, max_steps, record,
                  fixed_start, task_rewards):
  """Flat PGRL (Eq. 3 over the full task): z <- 0 at the start of an episode."""
  state = np.empty(4)
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  active = np.empty(t_offsets.shape[0], dtype=np.int64)
  psi = np.empty(t_offsets.shape[0])
  for episode in range(n_episodes):
    if fixed_start.shape[0] == 4:
      state[:] = fixed_start
    else:
      ship_compiled.sample_start(rng_state, state)
    el.reset(w, zs, y, touched, marked, count, acc)
    total = 0.0
    steps = 0
    event = core.NO_EVENT
    while True:
      tiles_mod.active_tiles(state, t_low, t_width, t_n, t_wrap, t_offsets, active)
      if sample:
        r = policies.gaussian_act(w, zs, y, touched, marked, count, acc, active, rules.R_MAX,
                                  rng_state, psi)
      else:
        r = policies.gaussian_greedy(w, zs, y, acc, active, rules.R_MAX)
      core.euler_control(state, r, samples)
      steps += 1
      event, reward = rules.global_outcome(samples, task_rewards[0], task_rewards[1])
      total += reward
      if learn:
        el.reward(w, zs, y, touched, marked, count, acc, alpha, reward, gamma)
      if event != core.NO_EVENT or steps >= max_steps:
        break
    record[episode, PASSED] = event == core.SUCCESS
    record[episode, STEPS] = steps
    record[episode, RETURN] = total


@numba.njit(cache=True)
def _critic_value(cw, czs, cy, cacc, ctiles):
  q = 0.0
  for k in range(ctiles.shape[0]):
    q += el.weight(cw, czs, cy, cacc, ctiles[k])
  return q


@numba.njit(cache=True)
def train_actor_critic(n_episodes, learn, sample, rng_state, actor_w,
                       a_low, a_width, a_n, a_wrap, a_offsets,
                       cw, czs, cy, ctouched, cmarked, ccount, cacc,
                       c_low, c_width, c_n, c_wrap, c_offsets,
                       alpha_actor, alpha_critic, lam, max_steps, record, fixed_start,
                       task_rewards):
  """Konda's actor-critic on the full task.

  Per step, with a = (u, r) drawn from the actor in s and a' in s':
    delta = R + Q(s', a') - Q(s, a)                   (no Q(s', a') at the end)
    e <- lambda e + phi(s, a);  w_c <- w_c + alpha_critic * delta * e     (TD(lambda))
    theta <- theta + alpha_actor * Q(s, a) * psi(s, a)
  Q(s, a) is the critic's value before this step's update.
  """
  state = np.empty(4)
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  sa = np.empty(5)
  a_tiles = np.empty(a_offsets.shape[0], dtype=np.int64)
  a_next = np.empty_like(a_tiles)
  c_tiles = np.empty(c_offsets.shape[0], dtype=np.int64)
  c_next = np.empty_like(c_tiles)
  ones = np.ones(c_offsets.shape[0])
  n_actor = a_offsets.shape[0]
  for episode in range(n_episodes):
    if fixed_start.shape[0] == 4:
      state[:] = fixed_start
    else:
      ship_compiled.sample_start(rng_state, state)
    el.reset(cw, czs, cy, ctouched, cmarked, ccount, cacc)      # e <- 0
    tiles_mod.active_tiles(state, a_low, a_width, a_n, a_wrap, a_offsets, a_tiles)
    m = policies.tile_mean(actor_w, a_tiles)
    u = policies.gaussian_draw(m, rng_state) if sample else m
    total = 0.0
    steps = 0
    event = core.NO_EVENT
    while True:
      r = policies.squash(u, rules.R_MAX)
      sa[:4] = state
      sa[4] = r
      tiles_mod.active_tiles(sa, c_low, c_width, c_n, c_wrap, c_offsets, c_tiles)
      q = _critic_value(cw, czs, cy, cacc, c_tiles)
      core.euler_control(state, r, samples)
      steps += 1
      event, reward = rules.global_outcome(samples, task_rewards[0], task_rewards[1])
      total += reward
      done = event != core.NO_EVENT or steps >= max_steps
      target = reward
      if not done or event == core.NO_EVENT:
        # The next action (also at a truncation, to bootstrap from it).
        tiles_mod.active_tiles(state, a_low, a_width, a_n, a_wrap, a_offsets, a_next)
        m_next = policies.tile_mean(actor_w, a_next)
        u_next = policies.gaussian_draw(m_next, rng_state) if sample else m_next
        sa[:4] = state
        sa[4] = policies.squash(u_next, rules.R_MAX)
        tiles_mod.active_tiles(sa, c_low, c_width, c_n, c_wrap, c_offsets, c_next)
        target += _critic_value(cw, czs, cy, cacc, c_next)
      if learn:
        delta = target - q
        el.add_score(czs, cy, ctouched, cmarked, ccount, cacc, c_tiles, ones)
        el.reward(cw, czs, cy, ctouched, cmarked, ccount, cacc, alpha_critic, delta, lam)
        step = alpha_actor * q * (u - m) / n_actor
        for k in range(n_actor):
          actor_w[a_tiles[k]] += step
      if done:
        break
      a_tiles[:] = a_next
      m = m_next
      u = u_next
    record[episode, PASSED] = event == core.SUCCESS
    record[episode, STEPS] = steps
    record[episode, RETURN] = total


# ---- agents: both training paths over the same arrays ------------------------

class _FlatShipAgent:
  """Shared by the flat agents: a one-node task graph for the step-by-step path."""

  def __init__(self, seed, max_steps, gate_reward, out_of_bounds_reward):
    from hpg_mj.learners import rng
    self.rng_state = rng.make_state(seed)
    self.max_steps = int(max_steps)
    self.task_rewards = np.array([gate_reward, out_of_bounds_reward], dtype=np.float64)
    self.episodes = 0

  def _fixed(self, start):
    return np.empty(0) if start is None else np.array(start, dtype=np.float64)

  def graph(self):
    from hpg_mj.hierarchy.graph import Primitive, Subtask, TaskGraph
    return TaskGraph("policy", [
        Subtask("policy", children=["turn"], learner=self.learner, view=self.view,
                termination=lambda call, step: False),     # flat: ends with the episode
        Primitive("turn"),
    ])

  def train_stepwise(self, adapter, episodes, learn=True, start=None, sample=None):
    from hpg_mj.hierarchy import executor
    run = executor.Executor(self.graph(), adapter, self.rng_state)
    record = np.zeros((episodes, N_RECORD))
    for i in range(episodes):
      begin = np.array(start, dtype=np.float64) if start is not None else self._start()
      total, steps, last = run.run_episode(begin, learn=learn, sample=sample)
      record[i] = (last.info.get("event") == "gate", steps, total)
    if learn:
      self.episodes += episodes
    return record

  def _start(self):
    s = np.empty(4)
    ship_compiled.sample_start(self.rng_state, s)
    return s


class FlatPolicyGradient(_FlatShipAgent):
  """Flat PGRL (SPEC section 4)."""

  def __init__(self, alpha=0.01, trace_gamma=0.99, tilings=9, tiles=(20, 20, 36, 5), seed=0,
               max_steps=core.STEER_MAX_STEPS, gate_reward=core.GATE_REWARD,
               out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD):
    from hpg_mj.learners import agents
    super().__init__(seed, max_steps, gate_reward, out_of_bounds_reward)
    self.coder = actor_coder(tilings, tiles)
    self.arrays = self.coder.arrays()
    self.learner = agents.GaussianPolicyGradient(self.coder.size, tilings, rules.R_MAX, alpha,
                                                 trace_gamma)
    self._active = np.empty(tilings, dtype=np.int64)

  def view(self, call, obs):
    tiles_mod.active_tiles(np.asarray(obs, dtype=np.float64), *self.arrays, self._active)
    return self._active

  def train_compiled(self, episodes, learn=True, start=None, sample=None):
    sample = learn if sample is None else (sample or learn)
    t = self.learner.trace
    record = np.zeros((episodes, N_RECORD))
    train_flat_pg(episodes, learn, sample, self.rng_state, t["w"], t["zs"], t["y"],
                  t["touched"], t["marked"], t["count"], t["acc"], *self.arrays,
                  self.learner.alpha, self.learner.gamma, self.max_steps, record,
                  self._fixed(start), self.task_rewards)
    if learn:
      self.episodes += episodes
    return record


class ActorCriticAgent(_FlatShipAgent):
  """Konda's actor-critic (SPEC section 4)."""

  def __init__(self, alpha_actor=1e-4, alpha_critic=0.01, lam=0.9, actor_tilings=9,
               actor_tiles=(20, 20, 36, 5), critic_tilings=9, critic_tiles=(5, 5, 36, 5, 30),
               seed=0, max_steps=core.STEER_MAX_STEPS, gate_reward=core.GATE_REWARD,
               out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD):
    from hpg_mj.learners import agents
    super().__init__(seed, max_steps, gate_reward, out_of_bounds_reward)
    self.actor = actor_coder(actor_tilings, actor_tiles)
    self.critic = critic_coder(critic_tilings, critic_tiles)
    self.learner = agents.ActorCritic(self.actor, self.critic, rules.R_MAX, alpha_actor,
                                      alpha_critic, lam)

  def view(self, call, obs):
    return np.array(obs, dtype=np.float64)

  def train_compiled(self, episodes, learn=True, start=None, sample=None):
    sample = learn if sample is None else (sample or learn)
    lr = self.learner
    c = lr.critic
    record = np.zeros((episodes, N_RECORD))
    train_actor_critic(episodes, learn, sample, self.rng_state, lr.actor_w, *lr.actor_arrays,
                       c["w"], c["zs"], c["y"], c["touched"], c["marked"], c["count"], c["acc"],
                       *lr.critic_arrays, lr.alpha_actor, lr.alpha_critic, lr.lam,
                       self.max_steps, record, self._fixed(start), self.task_rewards)
    if learn:
      self.episodes += episodes
    return record
