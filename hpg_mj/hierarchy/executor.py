"""Runs a task graph step by step over any environment (Algorithm 1).

```
Function HPG(Task i, State s)                          -> _execute(call, obs)
  if i is primitive: execute it, return its reward     -> adapter.step(action)
  while i has not terminated:                          -> termination(call, step)
    choose a with mu^i(s, theta^i)                     -> learner.act(view(call, obs))
    R = HPG(Task a, State s)                           -> child's rewards, summed
    observe s' and internal reward G^i(s'|s, a)        -> internal_reward(call, step)
    z, theta updates (Eq. 3)                           -> learner.observe(R + G)
```

Every subtask also returns when the environment's episode ends. Environments
are reached through an adapter (`GymAdapter`, `DmControlAdapter`) that turns
them into `reset(start) -> obs` and `step(action) -> Step`.
"""
import numpy as np

from hpg_mj.hierarchy import algorithm
from hpg_mj.hierarchy.graph import Call, Primitive, Step


class GymAdapter:
  """A Gymnasium environment; `reset(start)` uses `options={"state": start}` (a
  dictionary `start`: the options themselves, a ladder task's state and gate or course)."""

  def __init__(self, env):
    self.env = env
    self.values = env.step     # `step`'s fields as the environment gives them (`step_values`)

  def reset(self, start=None):
    """Starts an episode (at `start`, a state or the reset options, if given); returns
    its observation."""
    options = None if start is None else dict(start) if isinstance(start, dict) else \
        {"state": start}
    obs, _ = self.env.reset(options=options)
    return obs

  def step(self, action):
    """One primitive step: a `Step` (obs, reward, terminated, truncated, info)."""
    obs, reward, terminated, truncated, info = self.values(action)
    return Step(obs, float(reward), bool(terminated), bool(truncated), info)


class DmControlAdapter:
  """A dm_control environment; observations are flattened in their dict order.

  A fixed start is handed to the task through its `initial_state` attribute (a
  dictionary of reset options: "state" so, each other option to the task's attribute of
  its name, the ladder's `gate` or `course`).
  Positions sampled inside a step (the ship's) come from the physics: its
  `sampled_positions()`, a new array each step (`worlds.ship_model`), is handed on
  as it is.
  """

  def __init__(self, env):
    self.env = env
    # Read once: an environment keeps its physics and task.
    self._positions = getattr(env.physics, "sampled_positions", None)
    self._events = hasattr(env.task, "last_event")

  def _flat(self, timestep):
    values = timestep.observation.values()
    try:                             # vectors (the ship's): one call
      return np.concatenate(tuple(values), dtype=np.float64)
    except ValueError:               # a scalar among them
      return np.concatenate([np.ravel(v) for v in values]).astype(np.float64)

  def reset(self, start=None):
    """Starts an episode (at `start`, a state, if given); returns its observation
    flattened into one float64 vector."""
    if isinstance(start, dict):
      for key, value in start.items():
        setattr(self.env.task, "initial_state" if key == "state" else key, value)
    elif start is not None:
      self.env.task.initial_state = start
    return self._flat(self.env.reset())

  def step(self, action):
    """One primitive step: a `Step` (obs, reward, terminated, truncated, info)."""
    return Step(*self.values(action))

  def values(self, action):
    """`step`'s fields as a tuple (`step_values`)."""
    ts = self.env.step(np.array(action, ndmin=1))
    info = {}
    if self._positions is not None:
      info["positions"] = self._positions()
    if self._events:
      info["event"] = self.env.task.last_event
    last = ts.last()
    return (self._flat(ts), float(ts.reward), last and ts.discount == 0.0,
            last and ts.discount != 0.0, info)


def adapter_for(env):
  """The adapter of a Gymnasium environment or a dm_control one. The checks that
  `gymnasium.make` wraps around an environment (`PassiveEnvChecker`, `OrderEnforcing`)
  cost more than a step and are dropped where they are the outermost wrappers; any
  other wrapper (a user's reward shaping, a `TimeLimit`) is kept, with all it wraps."""
  if isinstance(env, (GymAdapter, DmControlAdapter)):
    return env
  if hasattr(env, "physics") and hasattr(env, "task"):
    return DmControlAdapter(env)
  if hasattr(env, "unwrapped") and hasattr(env, "step"):
    return GymAdapter(_without_checks(env))
  raise TypeError(f"{env!r} is neither a Gymnasium nor a dm_control environment")


def _without_checks(env):
  """`env` less the outermost wrappers that only check it (`gymnasium.make`'s)."""
  from gymnasium.wrappers import OrderEnforcing, PassiveEnvChecker
  while isinstance(env, (OrderEnforcing, PassiveEnvChecker)):
    env = env.env
  return env


def step_values(adapter):
  """`adapter.step` as a function of the action that returns the Step's fields as a
  tuple, (obs, reward, terminated, truncated, info): an adapter whose `step` is the
  one of these classes (not a subclass's own, which may watch each step) gives its
  `values`, without a Step made at each step (the step-by-step path's Python is a
  third of its time beside the MuJoCo ship); a GymAdapter's are its environment's
  own `step`'s, the reward and flags as the environment gives them."""
  if type(adapter).step in _PLAIN_STEPS:
    return adapter.values

  def values(action):
    step = adapter.step(action)
    return step.obs, step.reward, step.terminated, step.truncated, step.info
  return values


_PLAIN_STEPS = (GymAdapter.step, DmControlAdapter.step)


def run_program(program, env, episodes, learn, sample, rng_state, start, ended, on_call=None):
  """A compiled graph's `program` (`hierarchy.program.Program`) for `episodes` episodes
  through `env` (any Gymnasium or dm_control environment), each from `start()`;
  `ended(last step)` gives the row's end (or a pair: the end and its ROW_ILLEGAL
  column). Rows as `Program.run`'s.
  `on_call(call)`, if given, is told of every subtask called below the root (a
  `graph.Call`: its node, its arguments, the observation where it was called)."""
  adapter = adapter_for(env)
  step = step_values(adapter)
  sample = learn if sample is None else (sample or learn)
  rows = np.zeros((int(episodes), algorithm.ROW_COUNTERS + 3 * len(program.names)))
  for i in range(int(episodes)):
    obs = adapter.reset(start())
    action = program.begin(obs, learn, sample, rng_state)
    over = False
    while not over:
      if on_call is not None:
        for call in program.calls_begun():
          on_call(call)
      obs, reward, terminated, truncated, info = step(action)
      over, action = program.advance(obs, reward, terminated, truncated, info, learn, sample,
                                     rng_state)
    end = ended(Step(obs, float(reward), bool(terminated), bool(truncated), info))
    if isinstance(end, tuple):             # (the row's end, its ROW_ILLEGAL column)
      end, rows[i, algorithm.ROW_ILLEGAL] = end
    rows[i, algorithm.ROW_END] = end
    rows[i, algorithm.ROW_STEPS] = program.episode_steps
    rows[i, algorithm.ROW_RETURN] = program.episode_return
    rows[i, algorithm.ROW_COUNTERS:] = program.counters()
  return rows


class Executor:
  """Executes episodes of `graph` on `adapter`, drawing randomness from `rng_state`;
  `on_call(call)`, if given, is told of every subtask called below the root."""

  def __init__(self, graph, adapter, rng_state, on_call=None):
    self.graph = graph
    self.adapter = adapter
    self.rng_state = rng_state
    self.primitive_steps = 0
    self.on_call = on_call

  def run_episode(self, start=None, learn=True, sample=None):
    """One episode from `start` (or the environment's own start). Returns
    (return, primitive steps, last Step). Without learning the policies are
    sampled (`sample=True`) or followed greedily (the default)."""
    self._learn = learn
    self._sample = learn if sample is None else (sample or learn)
    self._steps = 0
    self._over = False
    obs = self.adapter.reset(start)
    root = Call(self.graph.root, {}, obs)
    total, last, _ = self._execute(root, obs)
    if self.graph.on_episode_end is not None:
      self.graph.on_episode_end(last, learn)
    self.primitive_steps += self._steps
    return total, self._steps, last

  def _execute(self, call, obs):
    """Runs `call` from `obs`; returns (summed reward, last Step, last obs)."""
    node = self.graph.nodes[call.node]
    if isinstance(node, Primitive):
      raise TypeError("primitives are executed by their parent")
    learner = node.learner
    children = self.graph.children(node.name)
    learner.start()
    total = 0.0
    last = None
    while not self._over:
      mask = None
      if node.available is not None:
        mask = np.array([node.available(call, obs, i) for i in range(len(children))],
                        dtype=np.bool_)
        if not mask.any():
          raise RuntimeError(f"subtask {node.name!r} has no available child in state {obs!r}")
      try:
        choice = learner.act(node.view(call, obs), mask, self.rng_state, self._sample)
      except ValueError as e:          # a view's value refused by its learner
        raise ValueError(f"subtask {node.name!r}: {e}") from None
      if len(children) == 1 and isinstance(self.graph.nodes[children[0].node], Primitive) \
          and self.graph.nodes[children[0].node].action is None:
        child_reward, step = self._primitive(call, choice)
      else:
        ref = children[choice]
        child = self.graph.nodes[ref.node]
        if isinstance(child, Primitive):
          child_reward, step = self._primitive(call, child.action)
        else:
          args = ref.args if ref.bind is None else {**ref.args, **ref.bind(call, obs)}
          child_call = Call(ref.node, args, obs)
          if self.on_call is not None:
            self.on_call(child_call)
          child_reward, step, _ = self._execute(child_call, obs)
          call.steps += child_call.steps
      obs = step.obs
      last = step
      internal = node.internal_reward(call, step) if node.internal_reward is not None else 0.0
      seen = node.reward(call, step, child_reward) if node.reward is not None else child_reward
      done_here = node.termination(call, step)
      done = done_here or self._over
      try:
        learner.observe(seen + internal, None if step.terminated else node.view(call, obs),
                        done, step.terminated or done_here, self._learn)
      except ValueError as e:
        raise ValueError(f"subtask {node.name!r}: {e}") from None
      total += child_reward
      if done:
        break
    if node.on_exit is not None:
      node.on_exit(call, last, self._over)
    return total, last, obs

  def _primitive(self, call, action):
    step = self.adapter.step(action)
    self._steps += 1
    call.steps += 1
    if step.terminated or step.truncated:
      self._over = True
    return step.reward, step
