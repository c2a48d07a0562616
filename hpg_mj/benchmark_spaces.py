"""The scorer's input contract: a policy that declares its spaces (a Stable-Baselines3
model's `observation_space` and `action_space`) is scored only on a task whose
spaces they are, and `rescaled` adapts one trained on rescaled spaces; an agent of a
ladder task acts at another level only where the levels' spaces are one (`at_level`).

A model trained through `gymnasium.wrappers.RescaleAction` (or
`hpg_mj.envs.sb3.make_vec_env(rescale=True)`) acts on [-1, 1]; scored as it is, its
actions would be taken as turning rates of -1 to 1 deg/s. `benchmark.evaluate`
refuses it in one line; `rescaled(model, task)` maps the task's observations onto
the model's observation space and its actions back onto the task's, each bounded
Box component affinely (low to low, high to high), as the wrappers did in training (a
dictionary observation's, the goal's, each key's).
A policy that raises or acts outside the task is a `PolicyError`. `actor` reads what
kind of policy it is given; `fixed_batch` gives a batched policy the same batch size at
every call (a jitted JAX function then compiles once; `evaluate` gives it one itself).
"""
import inspect
import warnings

import numpy as np

from hpg_mj.agents import base


class PolicyError(ValueError):
  """A policy that raised or returned an action the task cannot take; the
  message names the episode (its index in the fixed start set) and the step."""


def raised(where, err, obs):
  """The PolicyError for a policy that raised at `where`; reading a dictionary
  observation (the goal's) as an array is said so."""
  hint = ""
  if isinstance(obs, dict) and isinstance(err, (TypeError, KeyError, IndexError)):
    hint = f" (the observation is a dictionary of {', '.join(map(repr, obs))})"
  return PolicyError(f"the policy raised at {where}: {type(err).__name__}: {err}{hint}")


def task_spaces(task):
  """(observation space, action space) of one copy of the task's Gymnasium
  environment (`benchmark_tasks.Task`), on the analytic backend."""
  import gymnasium

  import hpg_mj  # noqa: F401  (registers the ids)
  env = gymnasium.make(task.env_id, **task.env_kwargs("analytic"))
  try:
    return env.observation_space, env.action_space
  finally:
    env.close()


def _same(a, b):
  """Whether two spaces are one: of one kind and shape, with the same bounds (a Box)
  or count (Discrete) or components (Dict, MultiDiscrete); the dtypes may differ."""
  if type(a) is not type(b):
    return False
  kind = type(a).__name__
  if kind == "Box":
    return (a.shape == b.shape and np.allclose(a.low, b.low, equal_nan=True)
            and np.allclose(a.high, b.high, equal_nan=True))
  if kind == "Dict":
    return list(a.spaces) == list(b.spaces) and all(_same(a[k], b[k]) for k in a.spaces)
  return a == b


def _same_shape(a, b):
  """Whether two spaces hold the same numbers, whatever their bounds: of one kind and
  shape (a Dict: the same keys, each so); others the same space."""
  if type(a) is not type(b):
    return False
  kind = type(a).__name__
  if kind == "Box":
    return a.shape == b.shape
  if kind == "Dict":
    return list(a.spaces) == list(b.spaces) and all(_same_shape(a[k], b[k]) for k in a.spaces)
  return a == b


def _check_levels(agent, own, there):
  """One line (a ValueError) where `agent`, which learned at `own`'s level (a `Task`),
  cannot act at `there`'s: the two levels' spaces differ (for an agent that reads the
  observation's numbers as they are, `raw_observation`: in their shapes only)."""
  name, same = agent.name, _same_shape if agent.raw_observation else _same
  for which, a, b in zip(("observation", "action"), task_spaces(own), task_spaces(there)):
    if not same(a, b):
      if type(a).__name__ == type(b).__name__ == "Box" and a.shape == b.shape:
        at = [i for i in np.ndindex(a.shape) if not (np.isclose(a.low[i], b.low[i]) and
                                                     np.isclose(a.high[i], b.high[i]))]
        told = "; ".join(f"[{', '.join(map(str, i))}] [{a.low[i]:g}, {a.high[i]:g}] there "
                         f"[{b.low[i]:g}, {b.high[i]:g}]" for i in at[:3])
        told = f"its {which}'s bounds differ at {len(at)} of its numbers ({told})"
      else:
        told = f"its {which} space is {_describe(a)}, there {_describe(b)}"
      why = ("its policy reads the numbers as they are, and they are not the same ones" if
             agent.raw_observation else "its policy scales the observation by the bounds it "
             "learned with, so it acts only in the spaces it learned in")
      raise ValueError(f"agent {name!r} learned at {own.name}/{own.level}, and at "
                       f"{there.level} {told}: {why}")


def at_level(agent, level):
  """`agent`'s policy at `level` of its ladder task: a new agent with its learned state
  (`agents.rebuilt`: its task file's [environment] level set), to score a learner at a
  level it did not learn at (`evaluate(agent, level=...)` makes it). `agent` itself at
  its own level; refused in one line where the agent's task has no levels, or where
  the two levels' observation or action spaces differ: in their bounds too (the
  current's, whose water runs faster, and the regatta's, whose courses have more gates)
  for an agent that scales the observation by them (PPO and SAC in JAX), in their
  shapes alone for one that reads its numbers as they are (`raw_observation`: the
  hierarchies on the machine)."""
  from hpg_mj.benchmark_tasks import LADDER, task_of
  own = task_of(agent)
  if own.level is None:
    raise ValueError(f"agent {agent.name!r} acts on {own.name!r}, which has no levels; the "
                     f"ladder's tasks have: {list(LADDER)}")
  there = task_of(own.name, level=level)
  if there.level == own.level:
    return agent
  _check_levels(agent, own, there)
  from hpg_mj import agents
  return agents.rebuilt(agent, [f"environment.level={there.level}"])


def _agent_task(agent, task=None, level=None, max_steps=None):
  """(the agent to score, its `Task`, the level it learned at: None on a task of none)
  for `evaluate(agent, task, level=..., max_steps=...)`: its own task, or another
  level of it (`at_level`); another task, or a step cap not its task file's, is
  refused in one line."""
  from hpg_mj.benchmark_tasks import task_of
  own = task_of(agent)
  asked = task_of(own.name if task is None else task, level=level)
  if asked.name != own.name:
    raise ValueError(f"agent {agent.name!r} acts on the task {own.name!r}, not {asked.name!r}")
  written = isinstance(task, str) and "/" in task         # "ship_goal/hard"
  trained = own.level
  if (level is not None or written) and asked.level != own.level:
    agent = at_level(agent, asked.level)
    own = task_of(agent)
  if max_steps is not None and int(max_steps) != own.max_steps:
    raise ValueError(f"agent {agent.name!r} runs its task file's max_steps = "
                     f"{own.max_steps}; set [environment] max_steps there, not max_steps")
  return agent, own, trained


def _describe(space):
  if type(space).__name__ == "Box":
    low, high = np.unique(space.low), np.unique(space.high)
    bound = (f"[{low[0]:g}, {high[0]:g}]" if low.size == high.size == 1 else
             f"low {np.round(space.low, 4).tolist()}, high {np.round(space.high, 4).tolist()}")
    return f"Box {bound} of shape {space.shape}"
  return repr(space)


def check(policy, task):
  """One line (a ValueError) if `policy` declares an observation or action space
  that is not the task's; nothing for a policy that declares none (a function)."""
  declared = {which: getattr(policy, f"{which}_space", None)
              for which in ("observation", "action")}
  if all(space is None for space in declared.values()):
    return
  own = dict(zip(("observation", "action"), task_spaces(task)))
  # A ladder task's spaces are its level's: the remedy names the level.
  name = task.name if task.level is None else f"{task.name}/{task.level}"
  for which, space in declared.items():
    if space is not None and not _same(space, own[which]):
      learned = None if isinstance(policy, Rescaled) else _level_of(space, which, task)
      if learned is not None:
        raise ValueError(
            f"the policy's {which}_space is {task.name}/{learned}'s and the task {name!r} "
            f"has {_describe(own[which])}: a model acts only in the spaces it learned in; "
            f"score it at {learned} (level={learned!r}), or train one at {task.level}")
      raise ValueError(
          f"the policy's {which}_space is {_describe(space)} and the task {name!r} has "
          f"{_describe(own[which])}: a model trained on rescaled spaces (RescaleAction, "
          f"make_vec_env(rescale=True)) is scored through benchmark.rescaled(model, {name!r}), "
          "which maps them back")


def _level_of(space, which, task):
  """The other level of `task`'s ladder task whose `which` space `space` is, or None."""
  from hpg_mj.benchmark_tasks import LEVELS, task_of
  if task.level is None:
    return None
  index = ("observation", "action").index(which)
  return next((level for level in LEVELS if level != task.level and
               _same(space, task_spaces(task_of(task.name, level=level))[index])), None)


class Rescaled:
  """A model trained on rescaled spaces, seen in the task's (`rescaled`): `predict`
  maps a batch of the task's observations onto the model's observation space, asks
  the model, and maps its actions onto the task's action space. Its
  `observation_space` and `action_space` are the task's."""

  def __init__(self, model, task_name, observation_space, action_space):
    self.model = model
    self.observation_space, self.action_space = observation_space, action_space
    self._obs = _affine(observation_space, model.observation_space, model.observation_space,
                        observation_space, "observation_space", task_name)
    self._act = _affine(model.action_space, action_space, model.action_space, action_space,
                        "action_space", task_name)

  def predict(self, obs, state=None, episode_start=None, deterministic=True):
    """The model's actions in the task's units for a batch of the task's observations,
    and the state the model returns (a recurrent model's: `Predicting`)."""
    mapped = _mapped(self._obs, obs)
    if takes_state(self.model.predict):     # `model` may be replaced: read at each call
      out = self.model.predict(mapped, state=state, episode_start=episode_start,
                               deterministic=deterministic)
    else:
      out = self.model.predict(mapped, deterministic=deterministic)
    actions, state = out if isinstance(out, tuple) else (out, None)
    return _mapped(self._act, actions), state


def _mapped(affine, x):
  """`x` through `_affine`'s map (a dictionary's, key by key)."""
  if affine is None:
    return x
  if isinstance(affine, dict):
    return {key: _mapped(affine.get(key), value) for key, value in x.items()}
  low, scale, target_low = affine
  return (np.asarray(x, dtype=np.float64) - low) * scale + target_low


def _affine(source, target, model_space, task_space, which, task_name):
  """(source low, scale, target low) taking `source` onto `target` (x' = (x - source
  low) * scale + target low), or None where the two are one, or a dictionary of those
  for Dict spaces of the same keys (the goal's observation); one line where no affine
  map of bounded Boxes of one shape takes one to the other."""
  if _same(source, target):
    return None
  if (type(source).__name__ == type(target).__name__ == "Dict"
      and list(source.spaces) == list(target.spaces)):
    return {key: _affine(source[key], target[key], model_space[key], task_space[key],
                         f"{which}[{key!r}]", task_name) for key in source.spaces}
  boxes = type(source).__name__ == type(target).__name__ == "Box"
  if not (boxes and source.shape == target.shape and
          all(np.isfinite(s.low).all() and np.isfinite(s.high).all() for s in (source, target))):
    raise ValueError(f"benchmark.rescaled: the model's {which} {_describe(model_space)} "
                     f"is no rescaling of the task {task_name!r}'s {_describe(task_space)}: "
                     "only bounded Boxes of one shape map onto each other")
  source_low = np.asarray(source.low, dtype=np.float64)
  target_low = np.asarray(target.low, dtype=np.float64)
  scale = (np.asarray(target.high, dtype=np.float64) - target_low) / \
      (np.asarray(source.high, dtype=np.float64) - source_low)
  return source_low, scale, target_low


def rescaled(model, task, level=None):
  """`model` (an object with SB3's `predict` and its `observation_space`,
  `action_space`), trained on rescaled spaces, as a policy on `task`'s own (a name,
  a ladder task at `level`, or a task file, as `benchmark.evaluate` takes them)."""
  from hpg_mj.benchmark_tasks import task_of
  for which in ("observation_space", "action_space"):
    if getattr(model, which, None) is None:
      raise ValueError(f"benchmark.rescaled: the model has no {which}; it needs both (an SB3 "
                       "model has them)")
  found = task_of(task, level=level)
  name = found.name if found.level is None else f"{found.name}/{found.level}"
  return Rescaled(model, name, *task_spaces(found))


class FixedBatch:
  """A batched policy called with `size` observations at every step (`fixed_batch`)."""
  batched = True

  def __init__(self, policy, size):
    if isinstance(size, bool) or not isinstance(size, int) or size < 1:
      raise ValueError(f"fixed_batch: size must be a positive integer, got {size!r}")
    self.policy, self.size = policy, size

  def __call__(self, obs):
    n = len(next(iter(obs.values())) if isinstance(obs, dict) else obs)
    if n > self.size:
      raise ValueError(f"fixed_batch: a batch of {n} observations, more than its size "
                       f"{self.size}; give evaluate num_envs <= {self.size}")

    def pad(rows):
      rows = np.asarray(rows)
      return np.concatenate([rows, np.repeat(rows[:1], self.size - n, axis=0)])
    padded = {k: pad(v) for k, v in obs.items()} if isinstance(obs, dict) else pad(obs)
    return np.asarray(self.policy(padded))[:n]


def batch_of_one(obs):
  """One observation (an array, or the goal's dictionary of them) as a batch of one."""
  if isinstance(obs, dict):
    return {key: np.asarray(value)[None] for key, value in obs.items()}
  return np.asarray(obs)[None]


def takes_state(predict):
  """Whether `predict` takes Stable-Baselines3's `state` and `episode_start` (every SB3
  model's does; sb3-contrib's recurrent models use them), or any keyword."""
  try:
    params = inspect.signature(predict).parameters
  except (TypeError, ValueError):
    return False
  return ({"state", "episode_start"} <= set(params)
          or any(p.kind is p.VAR_KEYWORD for p in params.values()))


class Predicting:
  """An object with SB3's `predict` as `evaluate` calls it, deterministic=True.

  Called on a batch of observations alone, it is a function of them. `step(obs,
  episode_start)` also hands `predict` the state its previous call returned and
  `episode_start` (which rows begin an episode), as SB3's own `evaluate_policy` does:
  a recurrent model (sb3-contrib's RecurrentPPO, or a user's object with the same
  `predict(obs, state, episode_start, deterministic)` returning `(actions, state)`)
  carries its memory from step to step. `state` is what the last call returned: None
  for a policy of the observation alone. Called on one observation (`batched=False`),
  a policy that returns a state is refused: its memory would be lost between calls."""

  def __init__(self, policy):
    self.policy = policy
    self.takes_state = takes_state(policy.predict)
    self.state, self.warned = None, False

  def __call__(self, obs):
    out = self.policy.predict(obs, deterministic=True)
    return out[0] if isinstance(out, tuple) else out

  def step(self, obs, episode_start):
    """The actions for a batch that is the same copies at every call, in order."""
    out = self.policy.predict(obs, state=self.state, deterministic=True,
                              episode_start=np.asarray(episode_start, dtype=np.bool_))
    if isinstance(out, tuple) and len(out) == 2:
      actions, self.state = out
      return actions
    if not self.warned:
      self.warned = True
      warnings.warn(f"{type(self.policy).__name__}.predict takes a state but returned the "
                    "actions alone: it is scored as a policy of the observation alone; "
                    "return (actions, state) for its state to come back at the next step",
                    stacklevel=2)
    self.state = None
    return out

  def one(self, obs):
    """The action for one observation, from a policy with no memory; one whose
    predict takes a state is asked with a batch of one, to see whether it returns one."""
    if not self.takes_state:
      return self(obs)
    actions, state = self.step(batch_of_one(obs), np.ones(1, dtype=np.bool_)), self.state
    self.state = None
    if state is not None:
      raise ValueError(f"{type(self.policy).__name__}.predict returned a state (a recurrent "
                       "policy's memory), which one observation at a time would lose; "
                       "score it with batched=True (the default for an object with predict)")
    return np.asarray(actions)[0]


def actor(policy, batched, batch=None):
  """(a function from observations to actions, batched) for a policy as `evaluate` takes
  it; a jitted batched function given batches of `batch` rows (`one_batch_size`)."""
  if batched not in (None, True, False):
    raise ValueError(f"batched must be None, True or False, got {batched!r}")
  if isinstance(policy, type):
    raise ValueError(f"policy is the class {policy.__name__}, not an object of it; pass one: "
                     f"{policy.__name__}()")
  if hasattr(policy, "predict") and callable(policy.predict):
    predicting, batched = Predicting(policy), True if batched is None else batched
    return (predicting if batched else predicting.one), batched
  if callable(policy):
    batched = bool(getattr(policy, "batched", False)) if batched is None else batched
    return one_batch_size(policy, batched, batch), batched
  if isinstance(policy, tuple) and policy and isinstance(policy[0], base.Agent):
    raise ValueError(f"policy is a tuple of {len(policy)} (agents.load returns (agent, "
                     "record, metadata)); pass its agent, agents.load(path)[0]")
  shown = " ".join(repr(policy).split())
  shown = shown if len(shown) <= 80 else f"{shown[:77]}..."
  raise ValueError(f"policy {shown} (a {type(policy).__name__}) is not a function, an object "
                   "with predict(obs, deterministic=True) or an hpg_mj agent")


def one_batch_size(act, batched, size):
  """`act`, or where it is a batched function `jax.jit` made (which compiles once an
  input shape) and `size` is given, `fixed_batch(act, size)`: `evaluate`'s batches
  shrink as episodes end."""
  jitted = type(act).__module__.startswith("jaxlib") and hasattr(act, "lower")
  return fixed_batch(act, size) if batched and jitted and size is not None else act


def fixed_batch(policy, size=1000):
  """`policy`, a function of a batch of observations, called with exactly `size` of
  them at every step (`evaluate`'s default num_envs is 1,000): `evaluate` hands a
  batched policy its live episodes, a batch that shrinks as the last ones end (some
  460 sizes over the 1,000 fixed starts), and a jitted JAX function compiles once a
  size. The batch is padded with copies of its first row, whose actions are dropped,
  so a function of the observation alone scores the same. Use
  `evaluate(fixed_batch(jax.jit(f)), task)`."""
  return FixedBatch(policy, size)
