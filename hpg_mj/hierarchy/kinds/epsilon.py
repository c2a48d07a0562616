"""The graph-wide exploration schedules (a `TaskGraph`'s `schedule`), read by the table
learners with `epsilon_schedule=True` (`learners.schedules`):

* `HeldEpsilon`: epsilon held until every watched subtask succeeds in `threshold` of
  its last `window` runs, then divided by `divisor` every `every` episodes (with
  `per_decision`, every `every` decisions of the root) (SPEC section 3);
* `LinearEpsilon`: a linear decay over the learning episodes.

Its compiled operations, called by Algorithm 1 (`hierarchy.algorithm`) while it learns:
  run_ended(S, watched, success)   a watched subtask's run ended (its index in `watch`)
  episode_ended(S, learned)        the root returned; `learned` learning episodes so far
  decided(S)                       the root is about to take its child's return
"""
import collections

import numba
import numpy as np

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base
from hpg_mj.learners import schedules

Schedule = collections.namedtuple("Schedule", ("epsilon", "state", "outcomes", "counts",
                                               "settings"))
Schedule.__doc__ = """A graph's schedule record `S`. `epsilon`: float64[1], the value
its learners read (a view of `state`'s first); `state`: the held schedule's [epsilon,
triggered, episodes since, unused] (saved); `outcomes` and `counts`: its watched
subtasks' last runs (saved); `settings`: [threshold, every, divisor, per decision] or
[start, end, episodes, 0]."""


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def held_run_ended(S, watched, success):
  """HeldEpsilon's `run_ended`: the run of watched subtask `watched` (its index in
  `watch`) is recorded as a success or a failure."""
  schedules.record_run(S.outcomes, S.counts, watched, success)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _held_step(S):
  schedules.end_episode(S.state, S.outcomes, S.counts, S.settings[0], np.int64(S.settings[1]),
                        S.settings[2])


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def held_episode_ended(S, learned):
  """HeldEpsilon's `episode_ended`: the schedule advances one episode (unless it
  counts decisions)."""
  if S.settings[3] == 0.0:
    _held_step(S)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def held_decided(S):
  """HeldEpsilon's `decided`: the schedule advances one root decision (if it counts
  decisions, `per_decision`)."""
  if S.settings[3] != 0.0:
    _held_step(S)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def linear_run_ended(S, watched, success):
  """LinearEpsilon's `run_ended`: nothing (it watches no subtask)."""
  pass


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def linear_episode_ended(S, learned):
  """LinearEpsilon's `episode_ended`: epsilon set to its linear decay's value after
  `learned` learning episodes."""
  S.epsilon[0] = schedules.linear(learned, S.settings[0], S.settings[1], S.settings[2])


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def linear_decided(S):
  """LinearEpsilon's `decided`: nothing (it moves per episode)."""
  pass


class ScheduleKind(base.Kind):
  """A schedule kind: `record(block)` makes its `Schedule`, and its compiled
  `run_ended`, `episode_ended` and `decided` (the module docstring) move it."""
  role = "schedule"
  run_ended = episode_ended = decided = None

  def watch(self, block):
    """The subtasks whose runs it watches, by name."""
    return tuple(getattr(block, "watch", ()))

  def start(self, S, block, learned_episodes):
    """Where the schedule stands after `learned_episodes` (a resumed run's)."""


class HeldEpsilonKind(ScheduleKind):
  """Runs a `HeldEpsilon` schedule."""
  block = blocks.HeldEpsilon
  run_ended = staticmethod(held_run_ended)
  episode_ended = staticmethod(held_episode_ended)
  decided = staticmethod(held_decided)

  def record(self, block):
    """A fresh `Schedule` for `block` (its epsilon checked to lie in [0, 1])."""
    if not 0.0 <= block.epsilon <= 1.0:
      raise GraphError(f"HeldEpsilon.epsilon = {block.epsilon!r}: must lie in [0, 1]")
    state, outcomes, counts = schedules.new_schedule(block.epsilon, block.window,
                                                     max(len(block.watch), 1))
    return Schedule(state[0:1], state, outcomes, counts,
                    np.array([block.threshold, block.every, block.divisor,
                              float(bool(block.per_decision))]))


class LinearEpsilonKind(ScheduleKind):
  """Runs a `LinearEpsilon` schedule."""
  block = blocks.LinearEpsilon
  run_ended = staticmethod(linear_run_ended)
  episode_ended = staticmethod(linear_episode_ended)
  decided = staticmethod(linear_decided)

  def record(self, block):
    """A fresh `Schedule` for `block`, epsilon at its start."""
    state = np.array([block.start, 0.0, 0.0, 0.0])
    return Schedule(state[0:1], state, np.zeros((1, 1), dtype=np.int8),
                    np.zeros((1, 2), dtype=np.int64),
                    np.array([block.start, block.end, float(block.episodes), 0.0]))

  def start(self, S, block, learned_episodes):
    S.state[3] = float(learned_episodes)
    S.epsilon[0] = schedules.linear(float(learned_episodes), block.start, block.end,
                                    block.episodes)
