"""Average-reward SMDP Q-learning (relative values), for a continuing root
(SPEC section 8).

This is R-learning (Schwartz 1993) in its semi-Markov form, as Ghavamzadeh &
Mahadevan use it for the root of a continuing task ("Continuous-time
hierarchical reinforcement learning", ICML 2001; "Hierarchically optimal
average reward reinforcement learning", ICML 2002). Q is a float64[n_states *
n_actions] table of relative action values; `gain` is float64[2] = [rho,
greedy transitions seen]. On a transition (s, a, r, tau, s'), where r is the
reward summed over the child's run and tau its duration (control steps):

    delta = r - rho * tau + max_b Q(s', b) - Q(s, a)
    Q(s, a) += alpha * delta

and, when a was greedy in s (an exploratory step says nothing of the greedy
policy's gain), Schwartz's gain update, after the backup:

    rho += beta * (r - rho * tau + max_b Q(s', b) - max_b Q(s, b))

Its fixed point is the greedy policy's gain whatever the distribution of the
states it is taken in: for the optimal relative values h, r - g tau + h(s') -
h(s) has mean 0 in every state. (The plain ratio of reward to time over greedy
transitions, SMART's estimate, is not: with exploration the states where greedy
steps are taken are not those of the greedy policy, and on the SMDP of
tests/learners/test_average_reward.py it settles ~3% low.) For an optimal
policy h(s) = max_a Q(s, a) satisfies the average-reward Bellman equation
h(s) = r(s, a) - rho tau(s, a) + E h(s') up to a constant; that test solves a
small SMDP exactly and compares.

Planning (`new_model`, `remember_and_plan`, `plan`): Dyna-Q (Sutton 1990) with a
model that keeps each (s, a)'s latest transition, swept with the same backup and
today's rho (as the differential Dyna of Wan, Naik & Sutton 2021, "Learning and
planning in average-reward Markov decision processes"). A continuing process
that has settled in one part of its states meets the rest rarely; their values
keep the level of the gain when they were last met, and sweeping their kept
transitions brings them to today's.
"""
import numba
import numpy as np

from hpg_mj.learners import qlambda

RHO, GREEDY_SEEN = range(2)


def new_gain():
  """The gain estimate's state: [rho, greedy transitions seen]."""
  return np.zeros(2)


@numba.njit(cache=True)
def update(q, n_actions, gain, s, a, reward, duration, s_next, alpha, gain_step, was_greedy):
  """One average-reward SMDP backup of (s, a, r, tau, s'); returns delta."""
  entry = s * n_actions + a
  next_value = qlambda.max_value(q, s_next, n_actions)
  delta = reward - gain[RHO] * duration + next_value - q[entry]
  q[entry] += alpha * delta
  if was_greedy:
    gain[GREEDY_SEEN] += 1.0
    gain[RHO] += gain_step * (reward - gain[RHO] * duration + qlambda.max_value(
        q, s_next, n_actions) - qlambda.max_value(q, s, n_actions))
  return delta


def new_model(n_entries):
  """A last-transition model of the SMDP for planning (`remember_and_plan`, `plan`): per
  (s, a), the next state of its latest transition (-1: never taken), its reward
  and its duration; and [transitions remembered] (what counts the sweeps)."""
  return (np.full(n_entries, -1, dtype=np.int64), np.zeros(n_entries), np.zeros(n_entries),
          np.zeros(1, dtype=np.int64))


@numba.njit(cache=True)
def remember_and_plan(q, n_actions, gain, model, s, a, reward, duration, s_next, alpha, every):
  """After `update` of (s, a, r, tau, s'): with `every` > 0, keeps it as the latest
  transition of (s, a) and, every `every` transitions kept, one sweep of `plan`."""
  if every <= 0:
    return
  entry = s * n_actions + a
  model[0][entry] = s_next
  model[1][entry] = reward
  model[2][entry] = duration
  model[3][0] += 1
  if model[3][0] % every == 0:
    plan(q, n_actions, gain, model, alpha)


@numba.njit(cache=True)
def plan(q, n_actions, gain, model, alpha):
  """One sweep of planning (Dyna-Q, Sutton 1990; in the average-reward setting as
  Wan, Naik & Sutton 2021's differential Dyna): every (s, a) of the model backed up
  once, in order, as if its latest transition happened again now, with today's
  gain rho and today's values of its next state; rho itself is not moved (no new
  experience). An entry the process has not met again since the gain was low
  thus learns what its call costs at the gain of now."""
  next_state, reward, duration, _ = model
  for entry in range(q.shape[0]):
    if next_state[entry] >= 0:
      update(q, n_actions, gain, entry // n_actions, entry % n_actions, reward[entry],
             duration[entry], next_state[entry], alpha, 0.0, False)


@numba.njit(cache=True)
def is_greedy(q, s, a, n_actions):
  """Whether action a has the largest value in s (ties count as greedy)."""
  return q[s * n_actions + a] == qlambda.max_value(q, s, n_actions)


def relative_values(q, n_states, n_actions, reference=0):
  """h(s) = max_a Q(s, a), shifted so that h(reference) = 0."""
  h = np.asarray(q).reshape(n_states, n_actions).max(axis=1)
  return h - h[reference]


class RLearning:
  """The root's learner on the step-by-step path (the protocol of
  `hpg_mj.learners.stepwise`): epsilon-greedy over `q`, and on each return of a
  child the backup `update` above, in the order of the compiled loop
  (`hpg_mj.agents.ship_patrol.patrol`).

  The process never ends, so `done` and `terminal` change nothing: the end of a
  record row (an hour) is no end of the task. The child's duration tau is not
  part of the protocol's signal; the graph sets `duration` before `observe`.
  `epsilon_source()` reads the schedule that owns epsilon.
  """

  def __init__(self, q, gain, n_actions, alpha, gain_step, epsilon_source, model=None,
               planning_every=0):
    self.q, self.gain = q, gain
    self.planning_every = int(planning_every)
    self.model = new_model(0) if model is None else model
    self.n_actions = int(n_actions)
    self.alpha, self.gain_step = float(alpha), float(gain_step)
    self.epsilon_source = epsilon_source
    self.duration = 0.0
    self._state = self._action = -1
    self._greedy = False

  def start(self):
    """A row starts: nothing is reset (the relative values and rho go on)."""

  def act(self, features, mask, rng_state, sample):
    """A child chosen in state `features` (an int), epsilon-greedy over Q(s, .)
    (greedy when not `sample`)."""
    s = int(features)
    epsilon = self.epsilon_source() if sample else 0.0
    a = qlambda.epsilon_greedy(self.q, s, self.n_actions, epsilon, rng_state)
    self._state, self._action = s, a
    self._greedy = is_greedy(self.q, s, a, self.n_actions)
    return a

  def observe(self, signal, next_features, done, terminal, learn):
    """The child's run of tau steps returned R = `signal`: (s, a, R, tau, s') backed
    up, remembered, and a planning sweep when one is due, if `learn`."""
    if learn:
      update(self.q, self.n_actions, self.gain, self._state, self._action, signal,
             float(self.duration), int(next_features), self.alpha, self.gain_step,
             self._greedy)
      remember_and_plan(self.q, self.n_actions, self.gain, self.model, self._state,
                        self._action, signal, float(self.duration), int(next_features),
                        self.alpha, self.planning_every)

  def parameters(self):
    """The relative values Q(s, a) (a copy)."""
    return self.q.copy()
