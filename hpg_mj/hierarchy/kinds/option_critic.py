"""Option-critic (Bacon, Harb and Precup, 2017) as kinds of the open machine: the
options are learned, not designed. A graph of `n_options` option nodes under a root:

    root          OverOptions(oc)             epsilon-greedy over Q_Omega(s, w)
    option w      IntraOption(oc, w)          pi_w(a | s), a softmax over the
                                              primitives, its own parameters theta_w
                  LearnedTermination(oc, w)   beta_w(s) = sigmoid(vartheta_w(s)): the
                                              option ends with that probability

All share one `OptionCritic` block's arrays, over a table of states (the root's and
the options' view: `TaxiState`, or any view of `n_states` states): Q_Omega(s, w),
Q_U(s, w, a), theta[w, s, a], vartheta[w, s]. After each primitive step of option
w, from s with a to s' with reward r (the tabular algorithm of the paper's
Algorithm 1, as its authors' four-rooms code runs it):

    U(s', w)       = (1 - beta_w(s')) Q_Omega(s', w) + beta_w(s') max_w' Q_Omega(s', w')
    target         = r + gamma U(s', w)           (r alone where s' is terminal)
    Q_Omega(s, w) += alpha_critic (target - Q_Omega(s, w))       (intra-option Q-learning)
    Q_U(s, w, a)  += alpha_critic (target - Q_U(s, w, a))
    theta_w(s, .) += alpha_policy (Q_U(s, w, a) - Q_Omega(s, w)) grad log pi_w(a | s)
                                                   (intra-option policy gradient; the
                                                    baseline Q_Omega with `baseline`)
    vartheta_w(s') -= alpha_termination beta_w(s')(1 - beta_w(s'))
                      (Q_Omega(s', w) - max_w' Q_Omega(s', w') + xi)   (termination gradient)

The termination is drawn (the machine judges a call before its learner observes:
so it is drawn with beta before this step's vartheta update, where the authors'
loop updates first). The root learns nothing of its own: Q_Omega is learned inside
the options. The learned arrays are saved by the root's name (`root.q_omega`, ...).

`LearnedTermination` reads the taxi's full state (the program's world,
`taxi_rules.encoded`), the state the options' `TaxiState` views give.
"""
import collections
import dataclasses
import math

import numba
import numpy as np

from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base
from hpg_mj.learners import qlambda
from hpg_mj.learners import rng as rng_mod
from hpg_mj.worlds import taxi_rules


@dataclasses.dataclass(eq=False)
class OptionCritic:
  """The arrays and step sizes the option-critic's nodes share."""
  n_states: int
  n_options: int
  n_actions: int
  alpha_critic: float = 0.5
  alpha_policy: float = 0.25
  alpha_termination: float = 0.25
  gamma: float = 0.99
  epsilon: float = 0.01
  xi: float = 0.01
  temperature: float = 1.0
  baseline: bool = True
  initial: float = 0.0          # Q_Omega and Q_U before learning (optimism explores)

  def __post_init__(self):
    for field in ("n_states", "n_options", "n_actions"):
      value = getattr(self, field)
      if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"OptionCritic.{field} = {value!r}: must be an integer >= 1")
    for field, low, high in (("alpha_critic", 0, 1), ("alpha_policy", 0, math.inf),
                             ("alpha_termination", 0, math.inf), ("gamma", 0, 1),
                             ("epsilon", 0, 1), ("xi", -math.inf, math.inf),
                             ("temperature", 0, math.inf), ("initial", -math.inf, math.inf)):
      value = getattr(self, field)
      if not (isinstance(value, (int, float)) and math.isfinite(value) and low <= value <= high):
        raise ValueError(f"OptionCritic.{field} = {value!r}: must be a finite number in "
                         f"[{low}, {high}]")
    if self.temperature == 0:
      raise ValueError("OptionCritic.temperature = 0: must be > 0")
    n, k, m = self.n_states, self.n_options, self.n_actions
    self.arrays = Learned(np.full(n * k, float(self.initial)),
                          np.full(n * k * m, float(self.initial)), np.zeros(k * n * m),
                          np.zeros(k * n))


@dataclasses.dataclass(eq=False)
class OverOptions:
  """The root's learner: epsilon-greedy over Q_Omega among the options (its children)."""
  oc: OptionCritic


@dataclasses.dataclass(eq=False)
class IntraOption:
  """Option `option`'s learner: pi_w over its primitive children, and the critic's and
  the termination's updates after each of its steps."""
  oc: OptionCritic
  option: int


@dataclasses.dataclass(frozen=True, eq=False)
class LearnedTermination:
  """Option `option`'s termination: drawn with probability beta_w(s')."""
  oc: OptionCritic
  option: int


Learned = collections.namedtuple("Learned", ("q_omega", "q_u", "theta", "vartheta"))
Learned.__doc__ = """What the option-critic learns, saved by the root's name:
Q_Omega[s * k + w], Q_U[(s * k + w) * m + a], theta[(w * n + s) * m + a],
vartheta[w * n + s]."""
Settings = collections.namedtuple("Settings", (
    "alpha_critic", "alpha_policy", "alpha_termination", "gamma", "epsilon", "xi",
    "temperature", "baseline", "k", "m", "n", "option", "q_omega", "q_u", "theta", "vartheta",
    "world"))
Settings.__doc__ = """A node's settings `P`: the step sizes, epsilon, xi, the softmax's
temperature, whether Q_Omega is the baseline, k options, m actions, n states, this
node's option, the shared arrays (a view of the root's learned ones) and the world."""
Scratch = collections.namedtuple("Scratch", ("last", "probs"))
Scratch.__doc__ = """An option node's scratch: [s, a] of its last choice; the policy's
probabilities."""
Nothing = collections.namedtuple("Nothing", ("option",))
Nothing.__doc__ = """What an option's node learns of its own: no array (the arrays
are the root's `Learned`)."""


def _settings(oc, option, world=None):
  a = oc.arrays
  return Settings(float(oc.alpha_critic), float(oc.alpha_policy), float(oc.alpha_termination),
                  float(oc.gamma), float(oc.epsilon), float(oc.xi), float(oc.temperature),
                  np.int64(bool(oc.baseline)), np.int64(oc.n_options), np.int64(oc.n_actions),
                  np.int64(oc.n_states), np.int64(option), a.q_omega, a.q_u, a.theta,
                  a.vartheta, np.zeros(7, dtype=np.int64) if world is None else world)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _sigmoid(v):
  return 1.0 / (1.0 + math.exp(-v))


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _max_omega(P, s):
  return qlambda.max_value(P.q_omega, s, P.k)


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _policy(P, s, probs):
  """pi_w(. | s) into probs (a softmax of theta_w(s, .) / temperature)."""
  base = (P.option * P.n + s) * P.m
  top = P.theta[base]
  for b in range(1, P.m):
    top = max(top, P.theta[base + b])
  total = 0.0
  for b in range(P.m):
    probs[b] = math.exp((P.theta[base + b] - top) / P.temperature)
    total += probs[b]
  for b in range(P.m):
    probs[b] /= total


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _draw(probs, rng):
  u = rng_mod.uniform(rng)
  acc = 0.0
  for b in range(probs.shape[0] - 1):
    acc += probs[b]
    if u < acc:
      return b
  return probs.shape[0] - 1


# ---- the root ------------------------------------------------------------------

@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def root_choose(P, L, N, x, n, rng, learn, sample):
  """The root's choice of an option in state x: epsilon-greedy over Q_Omega(x, .)
  (greedy when not `sample`)."""
  return float(qlambda.epsilon_greedy(P.q_omega, x, n, P.epsilon if sample else 0.0, rng))


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def root_observe(P, L, N, x, signal, done, terminal, n, rng, learn, sample):
  """An option ended (its learner learned inside it): unless done, the next option."""
  if done:
    return 0.0
  return root_choose(P, L, N, x, n, rng, learn, sample)


# ---- an option ------------------------------------------------------------------

@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def option_choose(P, L, N, x, n, rng, learn, sample):
  """Option w's choice of a primitive in state x: drawn from pi_w(. | x), the most
  likely when not `sample`."""
  _policy(P, x, N.probs)
  if sample:
    a = _draw(N.probs, rng)
  else:
    a = 0
    for b in range(1, n):
      if N.probs[b] > N.probs[a]:
        a = b
  N.last[0] = x
  N.last[1] = a
  return float(a)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def option_observe(P, L, N, x, signal, done, terminal, n, rng, learn, sample):
  """The critic's, the policy's and the termination's updates of the step (s, a, r,
  s' = x); unless done, the next action in s'."""
  if learn:
    s, a, w = N.last[0], N.last[1], P.option
    target = signal
    beta = 0.0
    if not terminal:
      beta = _sigmoid(P.vartheta[w * P.n + x])
      best = _max_omega(P, x)
      target += P.gamma * ((1.0 - beta) * P.q_omega[x * P.k + w] + beta * best)
    so = s * P.k + w
    sa = so * P.m + a
    P.q_omega[so] += P.alpha_critic * (target - P.q_omega[so])
    P.q_u[sa] += P.alpha_critic * (target - P.q_u[sa])
    feedback = P.q_u[sa] - (P.q_omega[so] if P.baseline != 0 else 0.0)
    _policy(P, s, N.probs)
    row = (w * P.n + s) * P.m
    for b in range(P.m):
      P.theta[row + b] -= P.alpha_policy * feedback * N.probs[b]
    P.theta[row + a] += P.alpha_policy * feedback
    if not terminal:               # (the advantage after the critic's update, as theirs)
      advantage = P.q_omega[x * P.k + w] - _max_omega(P, x) + P.xi
      P.vartheta[w * P.n + x] -= P.alpha_termination * beta * (1.0 - beta) * advantage
  if done:
    return 0.0
  return option_choose(P, L, N, x, n, rng, learn, sample)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def learned_end(P, obs, call, samples, rng):
  """The option ends in s' with probability beta_w(s') (drawn whether or not learning:
  a greedy run follows the learned terminations as drawn)."""
  s = taxi_rules.encoded(obs, P.world)
  return rng_mod.uniform(rng) < _sigmoid(P.vartheta[P.option * P.n + s])


# ---- the kinds ------------------------------------------------------------------

def check_option(name, block, shared=None):
  """The block's shared arrays (`block.oc`, an instance of `shared`: OptionCritic here,
  `option_critic_cmac.OptionCriticCMAC` there) and its option index, checked."""
  shared = shared or OptionCritic
  oc = block.oc
  if not isinstance(oc, shared):
    raise GraphError(f"subtask {name!r}: its {type(block).__name__}.oc must be an "
                     f"{shared.__name__}; got {type(oc).__name__}")
  option = getattr(block, "option", 0)
  if isinstance(option, bool) or not isinstance(option, (int, np.integer)) or \
      not 0 <= option < oc.n_options:
    raise GraphError(f"subtask {name!r}: its {type(block).__name__}.option = {option!r}: "
                     f"must be an integer in [0, {oc.n_options})")
  return oc


class _OptionCriticNode(base.TableKind):
  """A node of the option-critic: `among` its children (the options, or the actions)."""
  among = ("options", "n_options")

  def check(self, name, block, n_children, view_size):
    oc = check_option(name, block)
    what, field = self.among
    if n_children != getattr(oc, field):
      raise GraphError(f"subtask {name!r}: {type(block).__name__} chooses among "
                       f"{getattr(oc, field)} {what} (OptionCritic.{field}); it has "
                       f"{n_children} children")
    if view_size is not None and view_size != oc.n_states:
      raise GraphError(f"subtask {name!r}: its view gives {view_size} states, its "
                       f"OptionCritic has n_states = {oc.n_states}")

  def size(self, block):
    return int(block.oc.n_states)


class OverOptionsKind(_OptionCriticNode):
  """Runs an `OverOptions` root's learner."""
  block = OverOptions

  def settings(self, name, block):
    return _settings(block.oc, 0)

  def learned(self, block, n_children):
    return block.oc.arrays

  def scratch(self, block, n_children):
    return Nothing(np.int64(0))

  start, choose, observe = (staticmethod(base.no_start), staticmethod(root_choose),
                            staticmethod(root_observe))


class IntraOptionKind(_OptionCriticNode):
  """Runs an `IntraOption` learner: an option's policy and the shared updates."""
  block = IntraOption
  among = ("actions", "n_actions")
  bootstraps_at_own_end = True       # an option's end is no end of the task: U(s', w)

  def settings(self, name, block):
    return _settings(block.oc, block.option)

  def learned(self, block, n_children):
    return Nothing(np.int64(block.option))

  def parameters(self, learned):
    return {}

  def scratch(self, block, n_children):
    return Scratch(np.zeros(2, dtype=np.int64), np.zeros(n_children))

  start, choose, observe = (staticmethod(base.no_start), staticmethod(option_choose),
                            staticmethod(option_observe))


class LearnedTerminationKind(base.TerminationKind):
  """Runs a `LearnedTermination`: an option's end, drawn."""
  block = LearnedTermination
  end = staticmethod(learned_end)
  draws = True

  def check(self, name, block, arguments):
    check_option(name, block)

  def settings(self, name, block, world):
    return _settings(block.oc, block.option, world)


KINDS = (OverOptionsKind(), IntraOptionKind(), LearnedTerminationKind())
