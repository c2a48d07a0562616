"""Exploration schedules as compiled functions over plain arrays, shared by the
fused loops and the step-by-step learners.

The ship root's epsilon (SPEC section 3; `new_schedule`, `record_run`,
`end_episode`): held until both watched subtasks succeed in at least `threshold`
of their last `window` runs, then divided by `divisor` every `every` episodes.
`linear`: a linear decay from `start` to `end` over `episodes` episodes (flat
Q-learning, MAXQ-Q's levels).
"""
import numba
import numpy as np


# The held schedule's state: float64[4] = [epsilon, triggered,
# episodes since triggered, unused]; outcomes: int8[watched, window] ring buffers,
# counts: int64[watched, 2] = [runs recorded, next slot] per watched subtask.

def new_schedule(epsilon=0.1, window=1000, watched=2):
  """A held schedule at `epsilon`: (state, outcomes, counts) for `watched` subtasks'
  last `window` runs."""
  return (np.array([epsilon, 0.0, 0.0, 0.0]), np.zeros((watched, window), dtype=np.int8),
          np.zeros((watched, 2), dtype=np.int64))


@numba.njit(cache=True)
def record_run(outcomes, counts, subtask, success):
  """Records a run of watched subtask `subtask` as a success or a failure, in its
  ring buffer of the last runs."""
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
    for k in range(outcomes.shape[0]):
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


@numba.njit(cache=True, inline="always")
def linear(episode, start, end, episodes):
  """The value at learning episode `episode` of a linear decay from `start` to `end`
  over `episodes` episodes (`end` from then on, and at once when `episodes` <= 0)."""
  if episodes <= 0 or episode >= episodes:
    return end
  return start + (end - start) * episode / episodes
