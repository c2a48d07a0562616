"""The ship hierarchy trained in one compiled loop over the analytic ship.

The loop is Algorithm 1 unrolled for the ship's task graph (SPEC section 3):
a Q(lambda) root over eight directions and the two shared low-level subtasks
learning by Eq. 3, with the same rule functions, in the same order, as the
step-by-step executor (hpg_mj.hierarchy.executor); a test holds them equal.
"""
import numba
import numpy as np

from hpg_mj.hierarchy import ship_rules as rules
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import qlambda
from hpg_mj.learners import rng
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core as core

# Per-episode record columns.
# A subtask's runs count the calls that ended by its own success or failure; a call
# cut short by the end of the episode (gate, bounds, time limit) is no run.
PASSED, STEPS, CALLS, DIAG_RUNS, DIAG_SUCCESS, STRAIGHT_RUNS, STRAIGHT_SUCCESS, RETURN = range(8)
N_RECORD = 8


@numba.njit(cache=True)
def sample_start(rng_state, out):
  """A start of the full task (SPEC section 2), drawn in the order x, y, theta, theta_dot."""
  out[0] = rng.uniform_range(rng_state, 0.0, core.FIELD_SIZE)
  out[1] = rng.uniform_range(rng_state, 0.0, core.FIELD_SIZE)
  out[2] = core.wrap_deg(rng.uniform_range(rng_state, -180.0, 180.0))
  out[3] = rng.uniform_range(rng_state, -core.MAX_TURN_RATE, core.MAX_TURN_RATE)


@numba.njit(cache=True)
def run_low_level(state, direction, low_w, low_zs, low_y, low_touched, low_marked, low_count,
                  low_acc, tile_low, tile_width, tile_n, tile_wrap, tile_offsets, alpha_low,
                  gamma_low, learn, sample, rng_state, steps_before, max_steps_episode,
                  max_steps_call, scratch_tiles, scratch_psi, samples, local_samples,
                  local_state, origin, task_rewards):
  """One call of a low-level subtask from `state` (modified in place).

  Returns (global event, local event, reward to the root, control steps).
  """
  origin[0] = state[0]
  origin[1] = state[1]
  el.reset(low_w, low_zs, low_y, low_touched, low_marked, low_count, low_acc)  # Eq. 3: z <- 0
  reward_root = 0.0
  k = 0
  global_event = core.NO_EVENT
  local_event = core.NO_EVENT
  while True:
    core.global_to_local(state, origin, direction, local_state)
    tiles_mod.active_tiles(local_state, tile_low, tile_width, tile_n, tile_wrap, tile_offsets,
                           scratch_tiles)
    if sample:
      r = policies.gaussian_act(low_w, low_zs, low_y, low_touched, low_marked, low_count,
                                low_acc, scratch_tiles, rules.R_MAX, rng_state, scratch_psi)
    else:
      r = policies.gaussian_greedy(low_w, low_zs, low_y, low_acc, scratch_tiles, rules.R_MAX)
    core.euler_control(state, r, samples)
    k += 1
    global_event, reward = rules.global_outcome(samples, task_rewards[0], task_rewards[1])
    reward_root += reward
    local_event, internal = rules.low_level_outcome(samples, state, origin, direction, k,
                                                    local_samples, local_state, max_steps_call)
    if learn:
      el.reward(low_w, low_zs, low_y, low_touched, low_marked, low_count, low_acc, alpha_low,
                core.STEP_REWARD + internal, gamma_low)
    if (global_event != core.NO_EVENT or local_event != core.NO_EVENT
        or steps_before + k >= max_steps_episode):
      return global_event, local_event, reward_root, k


@numba.njit(cache=True)
def train(n_episodes, learn, sample, rng_state, q, q_index, q_value, q_count, alpha_root, lam,
          schedule, outcomes, counts, eps_threshold, eps_every, eps_divisor,
          diag_w, diag_zs, diag_y, diag_touched, diag_marked, diag_count, diag_acc,
          str_w, str_zs, str_y, str_touched, str_marked, str_count, str_acc,
          tile_low, tile_width, tile_n, tile_wrap, tile_offsets, alpha_low, gamma_low,
          max_steps_episode, max_steps_call, record, fixed_start, task_rewards):
  """Trains for `n_episodes` episodes; with learn=False it only runs the policy,
  sampling it (sample=True) or greedily (sample=False: epsilon 0, u = m).

  `task_rewards` = [gate bonus, out-of-bounds penalty] (SPEC: +100, -100).
  `record` (n_episodes, N_RECORD) receives one row per episode. With
  `fixed_start` of length 4, every episode starts there instead of at random.
  """
  state = np.empty(4)
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  local_samples = np.empty_like(samples)
  local_state = np.empty(4)
  origin = np.empty(2)
  n_tilings = tile_offsets.shape[0]
  scratch_tiles = np.empty(n_tilings, dtype=np.int64)
  scratch_psi = np.empty(n_tilings)
  for episode in range(n_episodes):
    if fixed_start.shape[0] == 4:
      state[:] = fixed_start
    else:
      sample_start(rng_state, state)
    qlambda.clear(q_count)
    steps = 0
    total = 0.0
    cell = rules.root_cell(state[0], state[1])
    epsilon = schedule[0] if sample else 0.0
    a = qlambda.epsilon_greedy(q, cell, rules.N_DIRECTIONS, epsilon, rng_state)
    row = record[episode]
    row[:] = 0.0
    while True:
      sub = rules.subtask_of(a)
      if sub == rules.DIAGONAL:
        g_event, l_event, reward, k = run_low_level(
            state, a, diag_w, diag_zs, diag_y, diag_touched, diag_marked, diag_count, diag_acc,
            tile_low, tile_width, tile_n, tile_wrap, tile_offsets, alpha_low, gamma_low, learn,
            sample, rng_state, steps, max_steps_episode, max_steps_call, scratch_tiles, scratch_psi,
            samples, local_samples, local_state, origin, task_rewards)
      else:
        g_event, l_event, reward, k = run_low_level(
            state, a, str_w, str_zs, str_y, str_touched, str_marked, str_count, str_acc,
            tile_low, tile_width, tile_n, tile_wrap, tile_offsets, alpha_low, gamma_low, learn,
            sample, rng_state, steps, max_steps_episode, max_steps_call, scratch_tiles, scratch_psi,
            samples, local_samples, local_state, origin, task_rewards)
      if g_event == core.NO_EVENT and steps + k < max_steps_episode:
        success = l_event == core.SUCCESS
        if sub == rules.DIAGONAL:
          row[DIAG_RUNS] += 1
          row[DIAG_SUCCESS] += success
        else:
          row[STRAIGHT_RUNS] += 1
          row[STRAIGHT_SUCCESS] += success
        if learn:
          rules.record_run(outcomes, counts, sub, success)
      steps += k
      total += reward
      row[CALLS] += 1
      terminal = g_event != core.NO_EVENT
      truncated = (not terminal) and steps >= max_steps_episode
      next_cell = rules.root_cell(state[0], state[1])
      if terminal or truncated:
        if learn:
          qlambda.update(q, rules.N_DIRECTIONS, q_index, q_value, q_count, cell, a, reward,
                         next_cell, 0, terminal, alpha_root, 1.0, lam)
          qlambda.clear(q_count)
        break
      a_next = qlambda.epsilon_greedy(q, next_cell, rules.N_DIRECTIONS, epsilon, rng_state)
      if learn:
        qlambda.update(q, rules.N_DIRECTIONS, q_index, q_value, q_count, cell, a, reward,
                       next_cell, a_next, False, alpha_root, 1.0, lam)
      cell = next_cell
      a = a_next
    row[PASSED] = g_event == core.SUCCESS
    row[STEPS] = steps
    row[RETURN] = total
    if learn:
      rules.end_episode(schedule, outcomes, counts, eps_threshold, eps_every, eps_divisor)
