"""Option-critic (Bacon, Harb and Precup, 2017) over a CMAC, for a continuous action:
the ship's. The graph is the tabular one's (`kinds.option_critic`), with every node
seeing the tiles of the same features: `StateTiles(oc.coder)`, the first numbers of
the observation, or on a ladder task `GateTiles(frame, oc.coder)`, the ship in the
frame of the observation's gate (`kinds.gate_frame`); an option's termination tiles
the features its node's view gives, so that beta_w is drawn where it is learned:

    root          OverOptionsCMAC(oc)          epsilon-greedy over Q_Omega(s, w)
    option w      IntraOptionCMAC(oc, w)       pi_w(u | s) = Normal(m_w(s), sigma^2), the
                                               action r_max tanh(u / 2) (the paper's
                                               Gaussian with sigmoid, SPEC section 3)
                  LearnedTerminationCMAC(oc, w)  beta_w(s) = sigmoid(vartheta_w(s))

Each function of s is linear in the k active tiles of s, as their mean:
Q_Omega(s, w) = mean q_w[tiles(s)], m_w(s) = mean theta_w[tiles(s)], vartheta_w(s) =
mean vartheta_w[tiles(s)]. After each primitive step of option w, from s with u to s'
with reward r:

    U(s', w)   = (1 - beta_w(s')) Q_Omega(s', w) + beta_w(s') max_w' Q_Omega(s', w')
    delta      = r + gamma U(s', w) - Q_Omega(s, w)       (r alone where s' is terminal)
    q_w        += alpha_critic delta                      on the tiles of s
    theta_w    += alpha_policy delta (u - m_w(s)) / sigma^2   on the tiles of s
    vartheta_w -= alpha_termination beta_w(s')(1 - beta_w(s'))
                  (Q_Omega(s', w) - max_w' Q_Omega(s', w') + xi)   on the tiles of s'

A continuous action has no table Q_U(s, w, u): the intra-option policy gradient takes
the one-step estimate r + gamma U(s', w) of Q_U with Q_Omega(s, w) as its baseline,
that is delta, as the authors' Atari agent does. Each step size moves the value at s
by that fraction of its error (each of the k active weights by the whole amount: the
mean's gradient times k), as the tabular kind's step sizes do.

As in the tabular kind, the termination is drawn before the option's learner
observes the step (with vartheta before this step's update); the root learns
nothing of its own. The learned arrays are saved by the root's name (`root.q_omega`,
`root.theta`, `root.vartheta`: [option * tiles + tile]).
"""
import collections
import dataclasses
import math

import numba
import numpy as np

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base
from hpg_mj.hierarchy.kinds import gate_frame
from hpg_mj.hierarchy.kinds import option_critic
from hpg_mj.learners import arrays
from hpg_mj.learners import policies
from hpg_mj.learners import rng as rng_mod
from hpg_mj.learners import tiles as tiles_mod


@dataclasses.dataclass(eq=False)
class OptionCriticCMAC:
  """The arrays and step sizes the option-critic's nodes share, over `coder`'s tiles;
  `r_max` bounds the continuous action."""
  coder: tiles_mod.TileCoder
  n_options: int
  r_max: float
  alpha_critic: float = 0.1
  alpha_policy: float = 0.01
  alpha_termination: float = 0.01
  gamma: float = 0.99
  epsilon: float = 0.05
  xi: float = 0.01
  sigma: float = 1.0
  initial: float = 0.0          # Q_Omega before learning

  def __post_init__(self):
    if not isinstance(self.coder, tiles_mod.TileCoder):
      raise ValueError(f"OptionCriticCMAC.coder = {self.coder!r}: must be a TileCoder")
    base.check_positive_int(self, "n_options", self.n_options)
    for field, low, high in (("r_max", 0, math.inf), ("alpha_critic", 0, 1),
                             ("alpha_policy", 0, math.inf), ("alpha_termination", 0, math.inf),
                             ("gamma", 0, 1), ("epsilon", 0, 1), ("xi", -math.inf, math.inf),
                             ("sigma", 0, math.inf), ("initial", -math.inf, math.inf)):
      value = getattr(self, field)
      if isinstance(value, bool) or not (isinstance(value, (int, float)) and
                                         math.isfinite(value) and low <= value <= high):
        raise ValueError(f"OptionCriticCMAC.{field} = {value!r}: must be a finite number in "
                         f"[{low}, {high}]")
    for field in ("r_max", "sigma"):
      if getattr(self, field) == 0:
        raise ValueError(f"OptionCriticCMAC.{field} = 0: must be > 0")
    size = self.coder.size * int(self.n_options)
    self.arrays = Learned(np.full(size, float(self.initial)), np.zeros(size), np.zeros(size))


@dataclasses.dataclass(eq=False)
class OverOptionsCMAC:
  """The root's learner: epsilon-greedy over Q_Omega among the options (its children)."""
  oc: OptionCriticCMAC


@dataclasses.dataclass(eq=False)
class IntraOptionCMAC:
  """Option `option`'s learner: pi_w's draw of its node's one continuous primitive, and
  the critic's, the policy's and the termination's updates after each of its steps."""
  oc: OptionCriticCMAC
  option: int


@dataclasses.dataclass(frozen=True, eq=False)
class LearnedTerminationCMAC:
  """Option `option`'s termination: drawn with probability beta_w(s'), over the tiles
  of the features its node's view gives (`StateTiles`: the observation's first numbers;
  `GateTiles`: the ship in the frame of the observation's gate)."""
  oc: OptionCriticCMAC
  option: int


Learned = collections.namedtuple("Learned", ("q_omega", "theta", "vartheta"))
Learned.__doc__ = """What the option-critic learns, saved by the root's name, each
indexed [w * tiles + tile]."""
Settings = collections.namedtuple("Settings", (
    "alpha_critic", "alpha_policy", "alpha_termination", "gamma", "epsilon", "xi", "sigma",
    "r_max", "k", "size", "option", "tiling", "q_omega", "theta", "vartheta", "features",
    "tiles", "at", "relative"))
Settings.__doc__ = """A node's settings `P`: the step sizes, epsilon, xi, sigma, r_max;
k options, the coder's tiles `size`, this node's option, the tiling; the shared
arrays; a termination's scratch (features, tiles) and the gate its features are
framed by (`blocks.GateFrame`'s at, relative; at -1: none, the observation as it is).
A variant's compiled operation finds the active tiles of the features x as the
shipped ones do: `hpg_mj.learners.tiles.active_tiles(x, P.tiling, out)` writes them into
`out` (int64, one a tiling: the node's scratch `N.tiles[0]`), and a function of s is
the mean of its array over them at offset w * P.size (option w)."""
Scratch = collections.namedtuple("Scratch", ("tiles", "last"))
Scratch.__doc__ = """A node's scratch: the active tiles of s (row 0) and s' (row 1);
[u, m] of its last draw."""
Nothing = collections.namedtuple("Nothing", ("option",))
Nothing.__doc__ = """What an option's node learns of its own: no array (the arrays
are the root's `Learned`)."""


def _settings(oc, option, frame=None):
  a = oc.arrays
  d, k = len(oc.coder.low), oc.coder.n_tilings
  at, relative = (-1, False) if frame is None else (frame.at, frame.relative)
  return Settings(float(oc.alpha_critic), float(oc.alpha_policy), float(oc.alpha_termination),
                  float(oc.gamma), float(oc.epsilon), float(oc.xi), float(oc.sigma),
                  float(oc.r_max), np.int64(oc.n_options), np.int64(oc.coder.size),
                  np.int64(option), oc.coder.arrays(), a.q_omega, a.theta, a.vartheta,
                  np.zeros(d), np.zeros(k, dtype=np.int64), np.int64(at),
                  np.int64(bool(relative)))


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _mean(w, offset, tiles):
  """The mean of w[offset + tile] over the active tiles."""
  total = 0.0
  for i in range(tiles.shape[0]):
    total += w[offset + tiles[i]]
  return total / tiles.shape[0]


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _add(w, offset, tiles, amount):
  for i in range(tiles.shape[0]):
    w[offset + tiles[i]] += amount


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _beta(P, option, tiles):
  return 1.0 / (1.0 + math.exp(-_mean(P.vartheta, option * P.size, tiles)))


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _best(P, tiles):
  """max_w Q_Omega(s, w) over the tiles of s, and the first option that has it."""
  best, arg = _mean(P.q_omega, 0, tiles), 0
  for w in range(1, P.k):
    v = _mean(P.q_omega, w * P.size, tiles)
    if v > best:
      best, arg = v, w
  return best, arg


# ---- the root ------------------------------------------------------------------

@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def root_choose(P, L, N, x, n, rng, learn, sample):
  """The root's choice of an option in the state of features x: epsilon-greedy over
  Q_Omega(s, .) on its tiles (greedy when not `sample`)."""
  if sample and rng_mod.uniform(rng) < P.epsilon:
    return float(rng_mod.randint(rng, n))
  tiles_mod.active_tiles(x, P.tiling, N.tiles[0])
  return float(_best(P, N.tiles[0])[1])


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def root_observe(P, L, N, x, signal, done, terminal, n, rng, learn, sample):
  """An option ended (it learned inside itself): unless done, the next option."""
  if done:
    return 0.0
  return root_choose(P, L, N, x, n, rng, learn, sample)


# ---- an option ------------------------------------------------------------------

@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _draw(P, N, rng, sample):
  """u ~ Normal(m_w(s), sigma^2) over the tiles of s (N.tiles[0]); the mode when not
  sampling. Returns the action r_max tanh(u / 2)."""
  m = _mean(P.theta, P.option * P.size, N.tiles[0])
  u = m + P.sigma * rng_mod.normal(rng) if sample else m
  N.last[0] = u
  N.last[1] = m
  return policies.squash(u, P.r_max)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def option_choose(P, L, N, x, n, rng, learn, sample):
  """Option w's action in the state of features x: u ~ Normal(m_w(s), sigma^2) (the
  mean when not `sample`), returned as r_max tanh(u / 2)."""
  tiles_mod.active_tiles(x, P.tiling, N.tiles[0])
  return _draw(P, N, rng, sample)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def option_observe(P, L, N, x, signal, done, terminal, n, rng, learn, sample):
  """The critic's, the policy's and the termination's updates of the step (s, u, r,
  s' = x); unless done, the next draw in s'."""
  w = P.option * P.size
  if not terminal:
    tiles_mod.active_tiles(x, P.tiling, N.tiles[1])
  if learn:
    s, s_next = N.tiles[0], N.tiles[1]
    target = signal
    beta = 0.0
    if not terminal:
      beta = _beta(P, P.option, s_next)
      target += P.gamma * ((1.0 - beta) * _mean(P.q_omega, w, s_next) +
                           beta * _best(P, s_next)[0])
    delta = target - _mean(P.q_omega, w, s)
    _add(P.q_omega, w, s, P.alpha_critic * delta)
    _add(P.theta, w, s, P.alpha_policy * delta * (N.last[0] - N.last[1]) / (P.sigma * P.sigma))
    if not terminal:               # (the advantage after the critic's update, as theirs)
      advantage = _mean(P.q_omega, w, s_next) - _best(P, s_next)[0] + P.xi
      _add(P.vartheta, w, s_next, -P.alpha_termination * beta * (1.0 - beta) * advantage)
  if done:
    return 0.0
  arrays.copy_into(N.tiles[0], N.tiles[1])
  return _draw(P, N, rng, sample)


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def learned_end(P, obs, call, samples, rng):
  """The option ends in s' with probability beta_w(s') (drawn whether or not learning:
  a greedy run follows the learned terminations as drawn), s' the features its node's
  view gives (the observation's first numbers, or the ship in its gate's frame)."""
  if P.at < 0:
    for i in range(P.features.shape[0]):
      P.features[i] = obs[i]
  else:
    gx, gy, s, c = gate_frame.gate_pose(P.at, P.relative, obs)
    gate_frame.framed_ship(obs, gx, gy, s, c, P.features)
  tiles_mod.active_tiles(P.features, P.tiling, P.tiles)
  return rng_mod.uniform(rng) < _beta(P, P.option, P.tiles)


# ---- the kinds ------------------------------------------------------------------

def _check_option(name, block):
  return option_critic.check_option(name, block, OptionCriticCMAC)


class _Node(base.LearnerKind):
  reads = "features"

  def check(self, name, block, n_children, view_size):
    oc = _check_option(name, block)
    if not self.continuous and n_children != oc.n_options:
      raise GraphError(f"subtask {name!r}: OverOptionsCMAC chooses among {oc.n_options} "
                       f"options (OptionCriticCMAC.n_options); it has {n_children} children")
    if view_size is not None and view_size != len(oc.coder.low):
      raise GraphError(f"subtask {name!r}: its view gives {view_size} numbers, its "
                       f"OptionCriticCMAC's coder tiles {len(oc.coder.low)}")

  def size(self, block):
    return len(block.oc.coder.low)

  def scratch(self, block, n_children):
    return Scratch(np.zeros((2, block.oc.coder.n_tilings), dtype=np.int64), np.zeros(2))


class OverOptionsCMACKind(_Node):
  """Runs an `OverOptionsCMAC` root's learner."""
  block = OverOptionsCMAC

  def settings(self, name, block):
    return _settings(block.oc, 0)

  def learned(self, block, n_children):
    return block.oc.arrays

  start, choose, observe = (staticmethod(base.no_start), staticmethod(root_choose),
                            staticmethod(root_observe))


class IntraOptionCMACKind(_Node):
  """Runs an `IntraOptionCMAC` learner: an option's continuous policy and the shared
  updates."""
  block = IntraOptionCMAC
  continuous = True
  bootstraps_at_own_end = True       # an option's end is no end of the task: U(s', w)

  def settings(self, name, block):
    return _settings(block.oc, block.option)

  def learned(self, block, n_children):
    return Nothing(np.int64(block.option))

  def parameters(self, learned):
    return {}

  start, choose, observe = (staticmethod(base.no_start), staticmethod(option_choose),
                            staticmethod(option_observe))


class LearnedTerminationCMACKind(base.TerminationKind):
  """Runs a `LearnedTerminationCMAC`: an option's end, drawn."""
  block = LearnedTerminationCMAC
  end = staticmethod(learned_end)
  draws = True

  def check(self, name, block, arguments):
    _check_option(name, block)

  def settings(self, name, block, node):
    # It tiles the features its node's view gives, which the option's learner tiles
    # too: the observation's first numbers (StateTiles) or the framed ship (GateTiles).
    view = node.view
    if not isinstance(view, (blocks.StateTiles, blocks.GateTiles)):
      raise GraphError(f"subtask {name!r}: a LearnedTerminationCMAC tiles its node's view's "
                       f"features, which must be a StateTiles or a GateTiles; got "
                       f"{type(view).__name__}")
    # (A GateTiles frame reaching past the observation is refused by the view's kind.)
    return _settings(block.oc, block.option, getattr(view, "frame", None))


KINDS = (OverOptionsCMACKind(), IntraOptionCMACKind(), LearnedTerminationCMACKind())
