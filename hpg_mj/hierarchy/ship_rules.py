"""The ship hierarchy's subtask rules as compiled functions (SPEC section 3).

Shared by the step-by-step hierarchy (hpg_mj.hierarchy.ship) and the fused
compiled loop (hpg_mj.hierarchy.ship_compiled), so both see the same numbers.
"""
import numba
import numpy as np

from hpg_mj.worlds import ship_core as core

ROOT_CELL_M = 50.0            # the root's 20 x 20 grid of 50 m cells
ROOT_GRID = 20
N_DIRECTIONS = 8
DIAGONAL = 0                  # low-level subtask ids
STRAIGHT = 1
R_MAX = core.MAX_TURN_RATE


@numba.njit(cache=True)
def root_cell(x, y):
  """The root's abstract state: the 50 m cell of (x, y), clamped to the field."""
  i = min(max(int(x // ROOT_CELL_M), 0), ROOT_GRID - 1)
  j = min(max(int(y // ROOT_CELL_M), 0), ROOT_GRID - 1)
  return i * ROOT_GRID + j


@numba.njit(cache=True)
def subtask_of(direction):
  """Which shared low-level subtask sails `direction` (0..7 = N..NW)."""
  return DIAGONAL if direction % 2 == 1 else STRAIGHT


@numba.njit(cache=True)
def low_level_outcome(samples, state, origin, direction, steps_in_call, local_samples,
                      local_state, max_steps):
  """After one control step inside a low-level call: (local event, G).

  The local event is SUCCESS (goal within 10 m), FAILURE (left the 150 m frame,
  or `max_steps` control steps without success) or NO_EVENT. G is the internal
  reward: the heading shaping and the local +100 / -100; it never reaches the
  root. The low level learns from R + G with R the step's -1.
  """
  core.samples_to_local(samples, origin, direction, local_samples)
  gx, gy = core.local_goal(direction)
  goal = np.array([gx, gy])
  event, _ = core.subtask_event(local_samples, goal, core.GOAL_RADIUS, core.LOCAL_SIZE)
  if event == core.NO_EVENT and steps_in_call >= max_steps:
    event = core.FAILURE
  core.global_to_local(state, origin, direction, local_state)
  internal = core.shaping_reward(local_state[0], local_state[1], local_state[2], gx, gy)
  if event == core.SUCCESS:
    internal += core.GATE_REWARD
  elif event == core.FAILURE:
    internal += core.OUT_OF_BOUNDS_REWARD
  return event, internal


@numba.njit(cache=True)
def global_outcome(samples, gate_reward, out_of_bounds_reward):
  """The full task's event and reward for one control step (SPEC section 2)."""
  event, _ = core.steer_event(samples, core.GATE, core.FIELD_SIZE)
  reward = core.STEP_REWARD
  if event == core.SUCCESS:
    reward += gate_reward
  elif event == core.FAILURE:
    reward += out_of_bounds_reward
  return event, reward


# Epsilon schedule of the root (SPEC section 3): epsilon = 0.1 until both
# low-level subtasks succeed in at least 80% of their last 1,000 runs, then
# divided by 1.01 every 50 episodes. State: float64[4] = [epsilon, triggered,
# episodes since triggered, unused]; outcomes: int8[2, window] ring buffers,
# counts: int64[2, 2] = [runs recorded, next slot] per subtask.

def new_schedule(epsilon=0.1, window=1000):
  return (np.array([epsilon, 0.0, 0.0, 0.0]), np.zeros((2, window), dtype=np.int8),
          np.zeros((2, 2), dtype=np.int64))


@numba.njit(cache=True)
def record_run(outcomes, counts, subtask, success):
  window = outcomes.shape[1]
  slot = counts[subtask, 1]
  outcomes[subtask, slot] = 1 if success else 0
  counts[subtask, 1] = (slot + 1) % window
  if counts[subtask, 0] < window:
    counts[subtask, 0] += 1


@numba.njit(cache=True)
def end_episode(schedule, outcomes, counts, threshold, every, divisor):
  """Advances the epsilon schedule at the end of an episode."""
  window = outcomes.shape[1]
  if schedule[1] == 0.0:
    ready = True
    for k in range(2):
      if counts[k, 0] < window:
        ready = False
      else:
        total = 0
        for i in range(window):
          total += outcomes[k, i]
        if total < threshold * window:
          ready = False
    if ready:
      schedule[1] = 1.0
      schedule[2] = 0.0
  else:
    schedule[2] += 1.0
    if schedule[2] >= every:
      schedule[2] = 0.0
      schedule[0] /= divisor
