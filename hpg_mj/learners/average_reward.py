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


@numba.njit(cache=True)
def is_greedy(q, s, a, n_actions):
  """Whether action a has the largest value in s (ties count as greedy)."""
  return q[s * n_actions + a] == qlambda.max_value(q, s, n_actions)


def relative_values(q, n_states, n_actions, reference=0):
  """h(s) = max_a Q(s, a), shifted so that h(reference) = 0."""
  h = np.asarray(q).reshape(n_states, n_actions).max(axis=1)
  return h - h[reference]
