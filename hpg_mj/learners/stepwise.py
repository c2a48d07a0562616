"""Learners as objects for the Python executor (`hierarchy.executor`: the compiled
machine's test oracle, and the step-by-step path of the agents not yet on the
machine): each holds its arrays and calls the compiled rule functions (the same ones
the compiled loops call). The contract is `hierarchy.graph.Learner`.

The protocol the executor uses:
  start()                                   the subtask is called (Eq. 3: z <- 0)
  act(features, mask, rng_state, sample)    choose a child (or a continuous action),
                                            sampling the policy or taking its greedy choice
  observe(signal, next_features, done, terminal, learn)
                                            the child returned with signal R + G
"""
import dataclasses

import numpy as np

from hpg_mj.learners import actor_critic
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import qlambda


def table_state(features, n_states, who):
  """A view's value as a table's state: an integer in [0, n_states), else one line
  saying what was given and what is allowed (a float is not truncated; a state past
  the table never reaches its array)."""
  if isinstance(features, np.ndarray) and features.ndim == 0:
    features = features[()]
  if isinstance(features, (bool, np.bool_)) or not isinstance(features, (int, np.integer)):
    raise ValueError(f"{who}: the view gave {features!r} ({type(features).__name__}); "
                     f"expected an integer state in [0, {n_states})")
  if not 0 <= features < n_states:
    raise ValueError(f"{who}: the view gave state {features}; expected an integer state in "
                     f"[0, {n_states})")
  return int(features)


def tile_indices(features, n_active, n_weights, who):
  """A view's value as the active tiles of a CMAC: `n_active` integers in [0, n_weights)."""
  tiles = np.asarray(features)
  if tiles.shape != (n_active,) or not np.issubdtype(tiles.dtype, np.integer):
    raise ValueError(f"{who}: the view gave {tiles.size} value(s) of {tiles.dtype} with shape "
                     f"{tiles.shape}; expected {n_active} integer tile indices (one a tiling)")
  if tiles.min() < 0 or tiles.max() >= n_weights:
    raise ValueError(f"{who}: the view gave tile {int(tiles.max() if tiles.max() >= n_weights else tiles.min())}; "
                     f"expected tile indices in [0, {n_weights})")
  return tiles


class _PolicyGradient:
  """Eq. 3 (SPEC section 3): z <- 0 on start; z <- gamma z + psi; theta <- theta + alpha (R + G) z.

  `reset_states`: optional predicate on features; when it holds at a step the
  trace is reset (the paper's variance-reduction variant with a set S*).
  """

  def __init__(self, n_weights, alpha, gamma=1.0, reset_states=None, initial=0.0):
    if not alpha > 0:
      raise ValueError(f"alpha must be positive, got {alpha!r}")
    if not 0.0 < gamma <= 1.0:
      raise ValueError(f"trace discount gamma must lie in (0, 1], got {gamma!r}")
    self.trace = el.new_trace(n_weights, initial)
    self.alpha = float(alpha)
    self.gamma = float(gamma)
    self.reset_states = reset_states

  def start(self):
    el.reset(self.trace)

  def observe(self, signal, next_features, done, terminal, learn):
    if learn:
      el.learn(self.trace, self.alpha, signal, self.gamma)
      if self.reset_states is not None and not done and self.reset_states(next_features):
        el.reset(self.trace)

  def parameters(self):
    """The current parameters with pending trace updates applied (a copy)."""
    return el.parameters(self.trace)

  def state_arrays(self):
    return self.trace._asdict()


class SoftmaxPolicyGradient(_PolicyGradient):
  """Tabular Gibbs policy, one parameter per (abstract state, child)."""

  def __init__(self, n_states, n_actions, alpha, gamma=1.0, reset_states=None, initial=0.0):
    super().__init__(n_states * n_actions, alpha, gamma, reset_states, initial)
    self.n_states, self.n_actions = int(n_states), int(n_actions)
    self._probs = np.empty(self.n_actions)
    self._index = np.empty(self.n_actions, dtype=np.int64)
    self._psi = np.empty(self.n_actions)
    self._all = np.ones(self.n_actions, dtype=np.bool_)

  def act(self, features, mask, rng_state, sample):
    """A child drawn from the Gibbs policy in state `features` among those `mask`
    offers, its score added to z (the likeliest when not `sample`)."""
    mask = self._all if mask is None else mask
    s = table_state(features, self.n_states, "SoftmaxPolicyGradient")
    if sample:
      return policies.softmax_act(self.trace, s, self.n_actions, mask,
                                  rng_state, self._probs, self._index, self._psi)
    return policies.softmax_greedy(self.trace, s, self.n_actions, mask)


class GaussianPolicyGradient(_PolicyGradient):
  """Gaussian-with-sigmoid policy over CMAC tiles (SPEC section 3); `features` are
  the active tile indices; the action is a continuous value in [-r_max, r_max].

  `baseline`: the TD(0) step size of a baseline b(s) over the same tiles
  (`policies.subtract_baseline`; 0: none, Eq. 3 exactly), held in `values`.
  `width_alpha` > 0: the exploration width sigma(s) learned too, on its own trace
  `width`, clipped to [sigma_low, sigma_high] (`policies.gaussian_width_act`)."""

  def __init__(self, n_weights, n_active, r_max, alpha, gamma=1.0, reset_states=None,
               sample_when_evaluating=False, baseline=0.0, width_alpha=0.0, sigma_low=0.25,
               sigma_high=4.0):
    super().__init__(n_weights, alpha, gamma, reset_states)
    if not 0.0 <= baseline <= 1.0:
      raise ValueError(f"baseline step size must lie in [0, 1], got {baseline!r}")
    self.r_max = float(r_max)
    self._psi = np.empty(int(n_active))
    self._psi_width = np.empty(int(n_active))
    self._tiles = np.empty(int(n_active), dtype=np.int64)
    self.sample_when_evaluating = sample_when_evaluating
    self.baseline = float(baseline)
    self.values = np.zeros(n_weights)
    self.width_alpha = float(width_alpha)
    self.width = el.new_trace(n_weights) if width_alpha != 0.0 else None
    self._log_sigma = (float(np.log(sigma_low)), float(np.log(sigma_high)))

  def start(self):
    """The subtask is called: z <- 0 (and the width's trace)."""
    el.reset(self.trace)
    if self.width is not None:
      el.reset(self.width)

  def act(self, features, mask, rng_state, sample):
    """The action drawn in the state of active tiles `features` (the mean when not
    `sample`), in [-r_max, r_max]; its score added to z."""
    self._tiles[:] = tile_indices(features, self._tiles.shape[0], self.values.shape[0],
                                  "GaussianPolicyGradient")   # (the view's array is reused)
    # (Its baseline's -alpha b(s) psi waits for `observe`, which knows whether it learns:
    # the same numbers as `policies.gaussian_choose`, which makes it at once.)
    return policies.gaussian_choose(self.trace, self.values, self._tiles, self._psi, self.alpha,
                                    0.0, self.r_max, False, sample, rng_state, self.width,
                                    self._psi_width, self.width_alpha, *self._log_sigma)

  def observe(self, signal, next_features, done, terminal, learn):
    """Eq. 3 with R + G = `signal` (and the baseline's TD(0) step), if `learn`."""
    if learn:
      if self.baseline != 0.0:
        policies.subtract_baseline(self.trace.theta, self.values, self._tiles, self.alpha,
                                   self._psi)
        if self.width is not None:
          policies.subtract_baseline(self.width.theta, self.values, self._tiles,
                                     self.width_alpha, self._psi_width)
      following = self._tiles if done else tile_indices(
          next_features, self._tiles.shape[0], self.values.shape[0], "GaussianPolicyGradient")
      policies.gaussian_learn(self.trace, self.values, self._tiles, following, self.alpha, self.gamma,
                              self.baseline, signal, done, self.width, self.width_alpha)
      if self.reset_states is not None and not done and self.reset_states(next_features):
        el.reset(self.trace)


@dataclasses.dataclass
class _Pending:
  state: object        # an int (a table's state) or an array of tiles
  action: int
  signal: float = 0.0
  next_state: object = -1
  waiting: bool = False


class QLambda:
  """Watkins's Q(lambda) with replacing traces over an SMDP (SPEC section 3).

  `epsilon` is read through `epsilon_source()` so that a schedule can own it.
  """

  def __init__(self, n_states, n_actions, alpha, lam, gamma=1.0, epsilon=0.1,
               epsilon_source=None, trace_capacity=4096, initial=0.0):
    self.n_states, self.n_actions = int(n_states), int(n_actions)
    self.q = np.full(self.n_states * self.n_actions, float(initial))
    self.index, self.value, self.count = qlambda.new_trace(trace_capacity)
    self.alpha, self.lam, self.gamma = float(alpha), float(lam), float(gamma)
    self.epsilon = float(epsilon)
    self.epsilon_source = epsilon_source
    self._pending = None

  def current_epsilon(self):
    """The epsilon it explores with now: its schedule's, else its own."""
    return self.epsilon_source() if self.epsilon_source is not None else self.epsilon

  def start(self):
    """The subtask is called: the trace cleared."""
    qlambda.clear(self.count)
    self._pending = None

  # What differs between the table and the tiles (TiledQLambda).
  def _state(self, features):
    return table_state(features, self.n_states, "QLambda")

  def _choose(self, s, epsilon, rng_state):
    return qlambda.epsilon_greedy(self.q, s, self.n_actions, epsilon, rng_state)

  def _backup(self, s, a, signal, s_next, a_next, terminal):
    qlambda.update(self.q, self.n_actions, self.index, self.value, self.count, s, a, signal,
                   s_next, a_next, terminal, self.alpha, self.gamma, self.lam)

  def act(self, features, mask, rng_state, sample):
    """A child chosen epsilon-greedily in state `features` (greedy when not
    `sample`); the previous transition's backup, which waited for it, is made."""
    s = self._state(features)
    epsilon = self.current_epsilon() if sample else 0.0
    a = self._choose(s, epsilon, rng_state)
    p = self._pending
    if p is not None and p.waiting:
      self._backup(p.state, p.action, p.signal, p.next_state, a, False)
    self._pending = _Pending(s, a)
    return a

  def observe(self, signal, next_features, done, terminal, learn):
    """The child returned R = `signal`: backed up now if the call ends, else when the
    next choice a' is known (`act`), if `learn`."""
    p = self._pending
    if not learn:
      return
    if done:
      # (A terminal backup does not read the next state: without one, any will do.)
      next_state = p.state if next_features is None else self._state(next_features)
      self._backup(p.state, p.action, signal, next_state, 0, terminal)
      qlambda.clear(self.count)
      self._pending = None
    else:
      p.signal, p.next_state, p.waiting = signal, self._state(next_features), True
    # (Without learning nothing is pending, so act() makes no backup.)

  def parameters(self):
    """The values Q(s, a) (a copy)."""
    return self.q.copy()


class TiledQLambda(QLambda):
  """Watkins's Q(lambda) over tiles (`qlambda.tiled_*`: linear in binary features).
  Its features are a state's active tiles, one per tiling, or (tiles, n) for a state
  that offers only its first n actions (an initiation set)."""

  def __init__(self, n_weights, n_tilings, n_actions, alpha, lam, gamma=1.0, epsilon=0.1,
               epsilon_source=None, trace_capacity=None):
    # Capacity: every weight at most once, so a trace of any length fits.
    super().__init__(n_weights, n_actions, alpha, lam, gamma, epsilon, epsilon_source,
                     trace_capacity or int(n_weights) * int(n_actions))
    self.n_tilings = int(n_tilings)

  def _state(self, features):
    tiles, n = features if isinstance(features, tuple) else (features, self.n_actions)
    tiles = np.array(tiles, dtype=np.int64)             # a copy: views reuse their arrays
    if tiles.shape != (self.n_tilings,):
      raise ValueError(f"TiledQLambda: features must be {self.n_tilings} active tiles, "
                       f"got shape {tiles.shape}")
    if not 1 <= int(n) <= self.n_actions:
      raise ValueError(f"TiledQLambda: a state offers 1 to {self.n_actions} actions, got {n}")
    return tiles, int(n)

  def _choose(self, s, epsilon, rng_state):
    return qlambda.tiled_epsilon_greedy(self.q, s[0], self.n_actions, s[1], epsilon, rng_state)

  def _backup(self, s, a, signal, s_next, a_next, terminal):
    qlambda.tiled_update(self.q, self.n_actions, self.index, self.value, self.count, s[0], a,
                         signal, s_next[0], s_next[1], a_next, terminal, self.alpha,
                         self.gamma, self.lam)


class ActorCritic:
  """Konda's actor-critic for a continuous action (SPEC section 4), step by step.

  `features` are the raw state; the actor is a Gaussian-with-sigmoid policy over
  `actor_coder`'s tiles (plain weights, stepped along Q(s, a) psi); the critic is
  linear over `critic_coder`'s tiles of (state, r), learned by TD(lambda) on an
  Eq. 3-style lazy trace. The order of draws and updates is that of
  the open machine's (`hierarchy.kinds.actor_critic`).
  """

  def __init__(self, actor_coder, critic_coder, r_max, alpha_actor, alpha_critic, lam):
    from hpg_mj.learners import tiles as tiles_mod
    self._tiles = tiles_mod
    self.actor_arrays = actor_coder.arrays()
    self.critic_arrays = critic_coder.arrays()
    self.actor_w = np.zeros(actor_coder.size)
    self.critic = el.new_trace(critic_coder.size)
    self.r_max = float(r_max)
    self.alpha_actor, self.alpha_critic, self.lam = float(alpha_actor), float(alpha_critic), float(lam)
    self._a = np.empty(actor_coder.n_tilings, dtype=np.int64)
    self._c = np.empty(critic_coder.n_tilings, dtype=np.int64)
    self._ones = np.ones(critic_coder.n_tilings)
    self._sa = np.empty(len(critic_coder.low))
    self._next = None

  def _choose(self, state, rng_state, sample):
    a = np.empty_like(self._a)
    self._tiles.active_tiles(np.asarray(state, dtype=np.float64), self.actor_arrays, a)
    m = policies.tile_mean(self.actor_w, a)
    u = policies.gaussian_draw(m, rng_state) if sample else m
    return a, m, u

  def _q(self, state, u):
    self._sa[:4] = state
    self._sa[4] = policies.squash(u, self.r_max)
    c = np.empty_like(self._c)
    self._tiles.active_tiles(self._sa, self.critic_arrays, c)
    return c, actor_critic.critic_value(self.critic, c)

  def start(self):
    """The subtask is called: the critic's trace cleared."""
    el.reset(self.critic)
    self._next = None

  def act(self, features, mask, rng_state, sample):
    """The action drawn from the actor in state `features` (drawn already when the
    last step looked ahead), in [-r_max, r_max]."""
    if self._next is None:
      a, m, u = self._choose(features, rng_state, sample)
    else:
      a, m, u = self._next
    self._current = (a, m, u, features)
    self._rng, self._sample = rng_state, sample
    return policies.squash(u, self.r_max)

  def observe(self, signal, next_features, done, terminal, learn):
    """The primitive returned R = `signal`: a' drawn in s', then the critic's
    TD(lambda) and the actor's steps, if `learn`."""
    a, m, u, state = self._current
    c, q = self._q(state, u)
    target = signal
    self._next = None
    if not terminal:
      self._next = self._choose(next_features, self._rng, self._sample)
      _, q_next = self._q(next_features, self._next[2])
      target += q_next
    if learn:
      actor_critic.learn(self.critic, c, self._ones, self.alpha_critic, target - q, self.lam,
                         self.actor_w, a, self.alpha_actor, q, u, m)
