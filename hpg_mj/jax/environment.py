"""gymnax's functional environment interface, without gymnax: the base class of the
JAX tasks, their spaces and their state and parameter records.

An environment is pure functions over an `EnvState` and an `EnvParams` record, as
gymnax's (`gymnax/environments/environment.py`, the interface of PureJaxRL and
rejax): `reset(key, params)` -> `(obs, state)`, `step(key, state, action, params)`
-> `(obs, state, reward, done, info)`, where `step` resets an episode that ended,
in the same call, from the second half of its key (gymnax's auto-reset), and
`done` is `terminated or truncated`. `step_env` and `reset_env` are the task's own,
without the auto-reset. Everything is jit-, vmap- and scan-able. gymnax computes the
reset for every copy at every step and selects; a task whose start is costly
computes it only where an episode ended (`Environment.auto_reset`, `where_needed`).

gymnax itself is not a dependency (it brings flax, orbax and seaborn, and rejax
0.1.3 needs gymnax < 1): the records are frozen dataclasses registered as JAX
pytrees, and the spaces are gymnax's two kinds written again. Where gymnax is
installed (it comes with rejax) the spaces are subclasses of gymnax's own, so that
code that asks `isinstance(space, gymnax.environments.spaces.Discrete)` (rejax
does, to tell discrete from continuous actions) sees what it expects.
"""
import dataclasses
import functools

import jax
import jax.numpy as jnp
from jax import custom_batching

try:   # gymnax's spaces as bases, only where gymnax is installed (module docstring)
  from gymnax.environments import spaces as _gymnax_spaces
  _DiscreteBase, _BoxBase = _gymnax_spaces.Discrete, _gymnax_spaces.Box
except Exception:   # noqa: BLE001  absent, or an old gymnax that no longer imports
  _DiscreteBase = _BoxBase = object   # under a new JAX: the spaces stay plain


def record(cls):
  """A frozen dataclass that is a JAX pytree of all its fields (flax.struct's
  `dataclass`, which gymnax uses, without flax), with flax's `replace`."""
  cls = dataclasses.dataclass(frozen=True)(cls)
  names = [f.name for f in dataclasses.fields(cls)]

  def replace(self, **changes):
    """A copy with the fields `changes` names replaced (flax's `replace`); a name that
    is no field is refused naming the fields, as `make` refuses one."""
    unknown = sorted(set(changes) - set(names))
    if unknown:
      raise ValueError(f"{cls.__name__}.replace: unknown parameter(s) {unknown}; allowed: "
                       f"{names}")
    return dataclasses.replace(self, **changes)
  cls.replace = replace
  return jax.tree_util.register_dataclass(cls, data_fields=names, meta_fields=[])


class Discrete(_DiscreteBase):
  """Actions 0..n-1 (gymnax's `Discrete`): `n`, shape `()`, `sample(key)`, `contains(x)`."""

  def __init__(self, num_categories):
    self.n = int(num_categories)
    self.shape = ()
    self.dtype = jax.dtypes.canonicalize_dtype(jnp.int64)   # gymnax's jnp.int_, no warning

  def sample(self, key):
    """An action drawn uniformly from 0..n-1 with `key`."""
    return jax.random.randint(key, self.shape, 0, self.n).astype(self.dtype)

  def contains(self, x):
    """Whether `x` is one of its actions."""
    return jnp.logical_and(x >= 0, x < self.n)

  def __repr__(self):
    return f"Discrete({self.n})"


class Box(_BoxBase):
  """An array in [low, high] (gymnax's `Box`): `low`, `high`, `shape`, `dtype`,
  `sample(key)` (uniform), `contains(x)`."""

  def __init__(self, low, high, shape, dtype=jnp.float32):
    self.low = low
    self.high = high
    self.shape = tuple(shape)
    self.dtype = dtype

  def sample(self, key):
    """An array drawn uniformly from [low, high] with `key`."""
    return jax.random.uniform(key, self.shape, minval=self.low,
                              maxval=self.high).astype(self.dtype)

  def contains(self, x):
    """Whether every entry of `x` lies in [low, high]."""
    return jnp.logical_and(jnp.all(x >= self.low), jnp.all(x <= self.high))

  def __repr__(self):
    return f"Box({self.low}, {self.high}, {self.shape}, {jnp.dtype(self.dtype).name})"


class Environment:
  """gymnax's `Environment`: a task is a subclass with `default_params`,
  `step_env`, `reset_env`, `get_obs`, `is_terminal`, `action_space`,
  `observation_space` and `num_actions`. The instance holds only what fixes array
  shapes (which task); everything a user may change per call is in `EnvParams`.
  """

  @property
  def default_params(self):
    """The task's `EnvParams` as shipped."""
    raise NotImplementedError

  @functools.partial(jax.jit, static_argnames=("self",))
  def step(self, key, state, action, params=None):
    """One step, and a reset in the same call where the episode ended (gymnax's
    auto-reset): the observation and state returned are then the new episode's
    start, drawn from the second half of `key`; the reward and `done` are the last
    step's, and `info` its own (`terminated`, `truncated`, `discount`, ...)."""
    if params is None:
      params = self.default_params
    obs, state, _, reward, done, info = self.step_keeping_end(key, state, action, params)
    return obs, state, reward, done, info

  def step_keeping_end(self, key, state, action, params):
    """`step`'s work (not jitted: a learner's loop jits it), also returning the ended
    step's own observation before the reset: `(obs, state, obs_end, reward, done,
    info)`, for a learner's bootstrap of a time limit (`hpg_mj.jax.ppo`)."""
    key_step, key_reset = jax.random.split(key)
    obs_st, state_st, reward, done, info = self.step_env(key_step, state, action, params)
    obs_re, state_re = self.auto_reset(key_reset, params, done)
    state = jax.tree.map(lambda x, y: jax.lax.select(done, x, y), state_re, state_st)
    obs = jax.lax.select(done, obs_re, obs_st)
    return obs, state, obs_st, reward, done, info

  @functools.partial(jax.jit, static_argnames=("self",))
  def reset(self, key, params=None):
    """A start drawn from `key`: `(obs, state)`."""
    if params is None:
      params = self.default_params
    return self.reset_env(key, params)

  def auto_reset(self, key, params, done):
    """The start `step` puts in place of an episode that ended (`done`): `reset_env`'s
    from `key`, which gymnax computes for every copy, ended or not, and selects. A
    task whose start is costly overrides it to compute the start only where `done`
    (the regatta's course, the harbour's rays: `where_needed`); for a copy not done
    it may return anything of the start's shapes."""
    return self.reset_env(key, params)

  def step_env(self, key, state, action, params):
    """One step without the reset: `(obs, state, reward, done, info)`."""
    raise NotImplementedError

  def reset_env(self, key, params):
    """A start drawn from `key`: `(obs, state)`."""
    raise NotImplementedError

  def get_obs(self, state, params=None, key=None):
    """The observation of `state`."""
    raise NotImplementedError

  def is_terminal(self, state, params):
    """Whether the episode has ended in `state` (terminated or out of time)."""
    raise NotImplementedError

  def discount(self, state, params):
    """0 where the episode has ended, 1 otherwise (gymnax's)."""
    return jax.lax.select(self.is_terminal(state, params), 0.0, 1.0)

  @property
  def name(self):
    """The environment's name (its id for hpg_mj's tasks)."""
    return type(self).__name__

  @property
  def num_actions(self):
    """The number of actions (1 for a continuous action)."""
    raise NotImplementedError

  def action_space(self, params=None):
    """Its actions: a `Discrete` or a `Box`."""
    raise NotImplementedError

  def observation_space(self, params=None):
    """Its observations: a `Box`."""
    raise NotImplementedError

  def state_space(self, params=None):
    """Its states (none of hpg_mj's tasks gives one)."""
    raise NotImplementedError


def where_needed(fn):
  """`fn` computed only where it is needed, also under vmap: the function returned,
  `lazy(needed, *args)`, is `fn(*args)` where `needed` is true and zeros of its
  shapes and dtypes where not. Unbatched that is a `lax.cond`; vmapped (where a
  `cond` would compute both branches for every copy) it calls `fn` once for each
  copy that needs it, one after another, and its loops then end with that copy's
  own work, not the batch's longest. For a costly start (the regatta's course, laid
  by rejection; the harbour's rays) that few copies need at a step: gymnax's `step`
  computes a reset for every copy at every step. Composes with jit, scan and nested vmap (an
  outer vmap batches the loop); not differentiable (`custom_vmap`'s limit)."""

  def skipped(*args):
    return jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), jax.eval_shape(fn, *args))

  @custom_batching.custom_vmap
  def lazy(needed, *args):
    return jax.lax.cond(needed, fn, skipped, *args)

  @lazy.def_vmap
  def lazy_batched(axis_size, in_batched, needed, *args):
    needed_batched, *args_batched = in_batched
    if not needed_batched:
      needed = jnp.broadcast_to(needed, (axis_size,))

    def copy(j):     # copy j's arguments: a batched leaf's row j, an unbatched leaf whole
      return fn(*(jax.tree.map(lambda leaf, batched: leaf[j] if batched else leaf, arg, flags)
                  for arg, flags in zip(args, args_batched)))

    shapes = jax.eval_shape(copy, 0)
    out = jax.tree.map(lambda s: jnp.zeros((axis_size, *s.shape), s.dtype), shapes)
    which = jnp.nonzero(needed, size=axis_size, fill_value=0)[0]

    def one(i, out):
      j = which[i]
      return jax.tree.map(lambda rows, row: rows.at[j].set(row), out, copy(j))
    out = jax.lax.fori_loop(0, jnp.sum(needed, dtype=jnp.int32), one, out)
    return out, jax.tree.map(lambda _: True, shapes)
  return lazy


def float_dtype():
  """The default float: float64 with `jax.config.update("jax_enable_x64", True)`,
  float32 otherwise (JAX's default)."""
  return jax.dtypes.canonicalize_dtype(jnp.float64)


def is_concrete(x):
  """Whether `x` holds values now (not a tracer under jit or vmap), so that they
  can be checked before the call."""
  return not isinstance(x, jax.core.Tracer)
