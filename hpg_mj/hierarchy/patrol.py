"""The continuing patrol (SPEC section 8) as compiled loops: `patrol`, the
hybrid's graph with an average-reward root on the never-ending task, one record
row an hour; `run_low_level`, one call of a low-level subtask as the patrol makes
it; and `scripted`, the figure-eight helmsman on the same task. The agent, its
configuration and its step-by-step path are `hpg_mj.agents.ship_patrol`.
"""
import collections

import numba
import numpy as np

from hpg_mj.hierarchy import executor
from hpg_mj.hierarchy import ship_rules as rules
from hpg_mj.hierarchy.graph import Step
from hpg_mj.learners import arrays
from hpg_mj.learners import average_reward
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import qlambda
from hpg_mj.learners import schedules
from hpg_mj.learners import tiles
from hpg_mj.worlds import ship_core as core

# The hyper-parameters `run_low_level` takes, each named [section] key as in the task
# file (`hpg_mj.agents.ship_patrol.settings` fills them from its Config).
Settings = collections.namedtuple("Settings", (
    "root_alpha", "root_trace_decay", "root_epsilon_threshold", "root_epsilon_every",
    "root_epsilon_divisor", "low_level_alpha", "low_level_trace_gamma", "low_level_baseline",
    "low_level_max_steps",
    "environment_max_steps", "environment_gate_reward", "environment_out_of_bounds_reward"))


# error_model="numpy": no raising branch on division, less reference counting (learners.policies).
# Only compiled code calls it: no Python entry point to compile (a first compile 0.15 s shorter).
@numba.njit(cache=True, error_model="numpy", no_cpython_wrapper=True)
def run_low_level(state, direction, low, low_values, tiling, s, learn, sample, rng_state,
                  steps_before, scratch):
  """One call of a low-level subtask (trace `low`, baseline `low_values`) from
  `state` (modified in place). The baseline b (`policies.subtract_baseline`) is
  learned with step size s.low_level_baseline; 0 leaves it out (Eq. 3 exactly).

  Returns (global event, local event, reward to the root, control steps).
  """
  scratch_tiles, scratch_psi, scratch_next, samples, local_samples, local_state, origin = scratch
  beta = s.low_level_baseline
  origin[0] = state[0]
  origin[1] = state[1]
  el.reset(low)                                        # Eq. 3: z <- 0
  reward_root = 0.0
  k = 0
  global_event = core.NO_EVENT
  local_event = core.NO_EVENT
  core.global_to_local(state, origin, direction, local_state)
  tiles.active_tiles(local_state, tiling, scratch_tiles)
  while True:
    r = policies.gaussian_choose(low, low_values, scratch_tiles, scratch_psi, s.low_level_alpha,
                                 beta, core.MAX_TURN_RATE, learn, sample, rng_state)
    core.euler_control(state, r, samples)
    k += 1
    global_event, reward = core.global_outcome(samples, s.environment_gate_reward,
                                               s.environment_out_of_bounds_reward)
    reward_root += reward
    local_event, internal = core.low_level_outcome(samples, state, origin, direction, k,
                                                   local_samples, local_state,
                                                   s.low_level_max_steps)
    ended = (global_event != core.NO_EVENT or local_event != core.NO_EVENT
             or steps_before + k >= s.environment_max_steps)
    if not ended:       # the next state, already local (`low_level_outcome`), and its tiles
      tiles.active_tiles(local_state, tiling, scratch_next)
    if learn:                                          # Eq. 3 with R + G
      policies.gaussian_learn(low, low_values, scratch_tiles, scratch_next, s.low_level_alpha,
                              s.low_level_trace_gamma, beta, core.STEP_REWARD + internal, ended)
    if ended:
      return global_event, local_event, reward_root, k
    arrays.copy_into(scratch_tiles, scratch_next)


# Record columns, one row per hour (`ShipPatrol.record_fields`).
(STEPS, GATES, DEPARTURES, CALLS, DIAG_RUNS, DIAG_SUCCESS, STRAIGHT_RUNS, STRAIGHT_SUCCESS,
 RETURN, GAIN) = range(10)
N_RECORD = 10
NEVER = 1 << 60              # no episode clock: only the subtasks' 300 steps end a call


@numba.njit(cache=True)
def n_root_cells(near_gate_m, near_gate_cell_m):
  """How many places the root tells apart: the 20 x 20 grid's 50 m cells, then,
  with `near_gate_m` > 0, the finer cells of the square of that half-width about
  the gate's centre (`root_state`)."""
  if near_gate_m <= 0.0:
    return rules.ROOT_GRID ** 2
  side = int(round(2.0 * near_gate_m / near_gate_cell_m))
  return rules.ROOT_GRID ** 2 + side * side


@numba.njit(cache=True)
def root_state(state, heading_sectors, near_gate_m=0.0, near_gate_cell_m=25.0):
  """The root's abstract state: where the ship is and, with `heading_sectors`
  n > 1, its heading in n equal sectors counted clockwise, sector 0 centred on
  south (-180 deg): place * n + sector. The place is the 50 m cell of (x, y)
  (`ship_rules.root_cell`) or, inside the square of half-width `near_gate_m`
  about the gate's centre, a cell of `near_gate_cell_m` there (numbered after
  the 400 coarse ones): how far the ship is from a post decides whether a
  U-turn passes the gate again. n = 1 and `near_gate_m` 0 is the hybrid's root."""
  cell = rules.root_cell(state[0], state[1])
  if near_gate_m > 0.0:
    x0 = 0.5 * (core.GATE[0, 0] + core.GATE[1, 0]) - near_gate_m
    y0 = 0.5 * (core.GATE[0, 1] + core.GATE[1, 1]) - near_gate_m
    side = int(round(2.0 * near_gate_m / near_gate_cell_m))
    i = int(np.floor((state[0] - x0) / near_gate_cell_m))
    j = int(np.floor((state[1] - y0) / near_gate_cell_m))
    if 0 <= i < side and 0 <= j < side:
      cell = rules.ROOT_GRID ** 2 + i * side + j
  if heading_sectors == 1:
    return cell
  width = 360.0 / heading_sectors
  sector = int((core.wrap_deg(state[2] + 0.5 * width) + 180.0) // width) % heading_sectors
  return cell * heading_sectors + sector


@numba.njit(cache=True)
def count_run(row, sub, l_event, g_event):
  """A call that ended by its subtask's own success or failure is a run (as the
  hybrid counts them); one cut by a gate pass or a departure is not."""
  if g_event != core.NO_EVENT or l_event == core.NO_EVENT:
    return False
  if sub == rules.DIAGONAL:
    row[DIAG_RUNS] += 1
    row[DIAG_SUCCESS] += l_event == core.SUCCESS
  else:
    row[STRAIGHT_RUNS] += 1
    row[STRAIGHT_SUCCESS] += l_event == core.SUCCESS
  return True


@numba.njit(cache=True)
def patrol(n_rows, record_steps, learn, sample, rng_state, ship, q, gain, schedule, low_level,
           tiling, s, rule, view, record):
  """Sails the continuing task for `n_rows` rows of at least `record_steps` control
  steps each (a call is never cut: the row in which it starts holds it), from
  and into `ship` (the process's state, kept between calls).

  The root chooses epsilon-greedily from `q` (epsilon 0 unless `sample`); with
  `learn` it learns by average-reward SMDP Q-learning (`gain` = [rho, greedy
  transitions]; `rule` = (gain_step, Schwartz's step size; the planning model;
  planning_every); SPEC section 8) and the subtasks by Eq. 3 with the hybrid's
  baseline (`run_low_level`). Without
  `learn`, `q` may be any root's table, the episodic hybrid's too: each runs its
  greedy policy on this task. `low_level` = (diagonal trace, its baseline values,
  straight trace, its baseline values); `view` = (heading_sectors, near_gate_m,
  near_gate_cell_m) of `root_state`. With `learn` and `planning_every` > 0, each
  call's transition is kept in `model` and every `planning_every` of them one
  sweep of `average_reward.plan` backs the whole model up (issue 24).
  """
  eps_state, outcomes, counts = schedule
  diagonal, diagonal_values, straight, straight_values = low_level
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  n_tilings = tiling.offsets.shape[0]
  scratch = (np.empty(n_tilings, dtype=np.int64), np.empty(n_tilings),
             np.empty(n_tilings, dtype=np.int64), samples, np.empty_like(samples), np.empty(4),
             np.empty(2))
  n = rules.N_DIRECTIONS
  heading_sectors, near_m, near_cell_m = view
  gain_step, model, planning_every = rule
  for i in range(n_rows):
    row = record[i]
    row[:] = 0.0
    while row[STEPS] < record_steps:
      epsilon = eps_state[0] if sample else 0.0
      cell = root_state(ship, heading_sectors, near_m, near_cell_m)
      a = qlambda.epsilon_greedy(q, cell, n, epsilon, rng_state)
      was_greedy = average_reward.is_greedy(q, cell, a, n)
      sub = rules.subtask_of(a)
      low, low_values = ((diagonal, diagonal_values) if sub == rules.DIAGONAL else
                         (straight, straight_values))
      g_event, l_event, reward, k = run_low_level(ship, a, low, low_values, tiling, s,
                                                         learn, sample, rng_state, 0, scratch)
      row[CALLS] += 1
      row[STEPS] += k
      row[RETURN] += reward
      if count_run(row, sub, l_event, g_event) and learn:
        schedules.record_run(outcomes, counts, sub, l_event == core.SUCCESS)
      if g_event == core.SUCCESS:
        row[GATES] += 1
      elif g_event == core.FAILURE:          # SPEC section 8: a fresh start, sail on
        row[DEPARTURES] += 1
        rules.sample_start(rng_state, ship)
      if learn:
        after = root_state(ship, heading_sectors, near_m, near_cell_m)
        average_reward.update(q, n, gain, cell, a, reward, float(k), after, s.root_alpha,
                              gain_step, was_greedy)
        average_reward.remember_and_plan(q, n, gain, model, cell, a, reward, float(k), after,
                                         s.root_alpha, planning_every)
        # The held schedule, counted in root decisions (there are no episodes).
        schedules.end_episode(eps_state, outcomes, counts, s.root_epsilon_threshold,
                              s.root_epsilon_every, s.root_epsilon_divisor)
    row[GAIN] = gain[average_reward.RHO]


@numba.njit(cache=True)
def scripted(n_rows, record_steps, rng_state, ship, gate_reward, out_of_bounds_reward, record):
  """The figure-eight helmsman (`ship_core.patrol_pilot_target`) on the continuing
  task: the reference figure, rows as `patrol`'s."""
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  phase = 0
  for i in range(n_rows):
    row = record[i]
    row[:] = 0.0
    while row[STEPS] < record_steps:
      tx, ty, phase = core.patrol_pilot_target(ship, phase)
      core.euler_control(ship, core.pilot_turn_rate(ship, tx, ty), samples, core.SPEED,
                         core.TIME_CONSTANT, core.SAMPLING_INTERVAL)
      event, reward = core.global_outcome(samples, gate_reward, out_of_bounds_reward)
      row[STEPS] += 1
      row[RETURN] += reward
      if event == core.SUCCESS:
        row[GATES] += 1
        phase = 0
      elif event == core.FAILURE:
        row[DEPARTURES] += 1
        rules.sample_start(rng_state, ship)
        phase = 0


class AgentRestarts(executor.GymAdapter):
  """The patrol's step-by-step path's adapter (the executor's `reset` / `step`) over a
  Gymnasium patrol: after a departure the ship is put at a start drawn from the
  agent's generator, as the compiled loop draws it, in place of the
  environment's own; the step's `info["state_before_restart"]` keeps where it
  left. A truncated step is refused: a row is the agent's hour, not the
  environment's."""

  def __init__(self, inner, rng_state):
    self.inner, self.env, self.rng_state = inner, inner.env, rng_state

  def reset(self, start=None):
    return self.inner.reset(start)

  def step(self, action):
    step = self.inner.step(action)
    if step.truncated:
      raise ValueError("ship_patrol's step-by-step rows end between calls; make the patrol "
                       f"environment with max_steps={NEVER} (ShipPatrol.stepwise_env does)")
    if step.info.get("event") == "out_of_bounds":
      if "state_before_restart" not in step.info:
        raise ValueError("ship_patrol's step-by-step path needs the Gymnasium patrol "
                         "(hpg_mj/ShipPatrol-v0), whose info holds state_before_restart")
      start = np.empty(4)
      rules.sample_start(self.rng_state, start)
      step = Step(self.inner.reset(start), step.reward, step.terminated, step.truncated,
                  step.info)
    return step
