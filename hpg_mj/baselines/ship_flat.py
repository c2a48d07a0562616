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
