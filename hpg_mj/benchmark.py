"""Score any policy on hpg_mj's tasks under the reports' protocol (SPEC section 7).

```python
from hpg_mj import benchmark
result = benchmark.evaluate(lambda obs: 5.0, "ship")    # r = 5 deg/s everywhere
result.metrics["J"], result.metrics["J_normalized"], result.record["steps"]
```

`evaluate(policy, task)` takes
  - a function from one observation to one action (`batched=True`: from a batch
    of observations, shape (n, ...), to n actions),
  - any object with Stable-Baselines3's `predict(obs, deterministic=True)`
    (called with a batch of observations; its first return value is the actions;
    where it takes SB3's `state` and `episode_start` and returns a state, as
    sb3-contrib's RecurrentPPO does, it is called with every copy in order, its
    state handed back and `episode_start` marking the copies that begin an episode,
    as SB3's `evaluate_policy` calls it: `benchmark_spaces.Predicting`; one that
    declares an `observation_space` or `action_space` other than the task's is
    refused: a model trained on rescaled spaces is scored as
    `evaluate(rescaled(model, task), task)`, `hpg_mj.benchmark_spaces`),
  - or an hpg_mj agent (`hpg_mj.agents.Agent`: its own greedy episodes,
    `Agent.evaluate_fixed`),
and sails it greedily from the fixed seeded starts of every report (start i from
seed `GREEDY_SEED + i`, `hpg_mj.agents.base.seeded_starts`), stepping the native
vector environments (`gymnasium.make_vec`, `hpg_mj.envs.vector`) with up to
`num_envs` episodes at a time. A function must be one of the observation alone (no
memory between steps): the episodes of a batch run side by side, and a shrinking
batch of them is handed over as episodes end. A policy with memory is an object with
a recurrent `predict` (above) or an agent.

The tasks (`TASKS`): "ship" (SPEC section 2; observation `[x, y, theta_deg,
theta_dot_deg]`, action the turning rate r in deg/s, clipped to [-15, 15]),
"taxi_fuel" and "taxi" (SPEC section 5; observation `(row, col, passenger,
destination, fuel)`, fuel left out in the classic "taxi"; action an integer
0..6, 0..5 in the classic taxi), or a task file (its [environment]: a shipped
name such as "ship_hybrid", a path, or a loaded `TaskFile`). The task ladder's
(`LADDER`, SPEC section 11), each at a level of `LEVELS` (`level="hard"`, or
"ship_goal/hard"): "ship_current", "ship_goal", "ship_regatta" and "ship_harbour",
the Gymnasium environments' observations (the goal's a dictionary: `observation`,
`achieved_goal`, `desired_goal`, each (n, 4) in a batch, and `ranges`, (n, 7); the
harbour's the state and seven ranges, (n, 11)) and the turning rate; start i is the
episode the environment lays out at `reset(seed=GREEDY_SEED + i)`.

Metrics (one implementation each, shared with the agents' reports):
  ship   gate_pass_rate, steps_to_gate (mean control steps over the passes),
         mean_return (the task's rewards), J (MushroomRL's rewards, gamma 0.99,
         `agents._ship.mushroom_j`), control_steps; the same for the current,
         the goal (the pass: the goal reached) and the harbour (an obstacle
         touched ends the episode as leaving the field does)
  regatta finish_rate, gates_passed (the mean gates passed), steps_to_finish
         (mean control steps over the finishes), mean_return, control_steps
  taxi   mean_return, optimum (the mean exact optimal return V* from the same
         starts, `worlds.taxi_values`), fraction_of_optimum (mean_return /
         optimum), delivery_rate, primitive_steps
and each score of `SCORES` also normalized, `<score>_normalized` = 100 (score -
random) / (best known - random), against the bounds of `bounds()` (SPEC section
7.1; `hpg-mj bounds` computes them; the ladder's best known from `hpg_mj.planners`,
the harbour's from `hpg_mj.planners_harbour`).
`official` says whether the evaluation ran the whole protocol (all fixed starts, the
task's own step limit), the bounds'. The tasks and their fixed starts are
`hpg_mj.benchmark_tasks`'.
"""
import dataclasses
import importlib
import importlib.util
import math
import pathlib
import sys
import time

import numba
import numpy as np

from hpg_mj.agents import _ship
from hpg_mj.agents import base
from hpg_mj.experiments import bounds as bounds_mod
from hpg_mj.experiments.bounds import (KEYS, LADDER, LEVELS, SCORES, TASKS,  # noqa: F401
                                       bounds)                        # (public here)
from hpg_mj.benchmark_tasks import (ENV_IDS, Task, _count, _start_count,  # noqa: F401
                                    fixed_starts, optimal_returns, task_of)  # (public here)
from hpg_mj import benchmark_spaces
from hpg_mj.benchmark_spaces import (PolicyError, _agent_task, at_level,  # noqa: F401
                                     fixed_batch, rescaled)             # (public here)
from hpg_mj.hierarchy import ship_rules
from hpg_mj.worlds import ship_core
from hpg_mj.worlds import taxi_core
from hpg_mj.worlds import taxi_rules

RECORD_FIELDS = {"ship": ("passed", "steps", "return", "J"),
                 "regatta": ("finished", "gates", "steps", "return"),
                 "taxi": ("return", "steps", "outcome", "delivered", "optimal_return")}
DEFAULT_NUM_ENVS = 1000
RANDOM_POLICY_SEED = 0        # the random policy's own generator (bounds)


# ---- scoring ---------------------------------------------------------------------------

@dataclasses.dataclass
class Evaluation:
  """What `evaluate` returns: named metrics and the per-episode record (a numpy
  structured array, row i the episode from fixed start i; fields
  `RECORD_FIELDS[task.world]`)."""
  metrics: dict
  record: np.ndarray
  task: Task


def record_dtype(world):
  """The numpy dtype of a world's evaluation record: a float64 field per name of
  `RECORD_FIELDS[world]`."""
  return np.dtype([(name, np.float64) for name in RECORD_FIELDS[world]])


def evaluate(policy, task=None, episodes=base.GREEDY_STARTS, max_steps=None, *,
             level=None, seed=base.GREEDY_SEED, batched=None, num_envs=DEFAULT_NUM_ENVS,
             backend=None, progress=None):
  """Scores `policy` greedily on `episodes` fixed starts of `task` (see the module
  docstring); returns an `Evaluation`.

  `task`: a name of `TASKS`, a ladder task of `LADDER` at `level` (a name of
  `LEVELS`, default "easy"; or "ship_goal/hard" written at once), or a task file
  (default: an agent's own task, else "ship"). `max_steps`: a step cap (default the
  task's limit: the ships 5,000 control steps, taxi 200 primitive steps). An agent is
  scored at its own level, or at another `level` of its ladder task (`at_level`); the
  metrics' `trained_level` names the level it learned at.
  `batched`: whether a function takes a batch of observations (default: False for a
  function, True for an object with `predict`; one `jax.jit` made gets `fixed_batch`).
  `backend`: "analytic" (Equation 1) or "mujoco" (default: an agent's, else "analytic").
  `progress`: a progress bar on stderr (None: when stderr is a terminal).
  """
  _count("episodes", episodes)
  if episodes == 0:
    raise ValueError("episodes must be at least 1 (no episode has no score), got 0")
  _count("seed", seed)
  if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
    raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
  if backend is None:
    backend = policy.backend if isinstance(policy, base.Agent) else "analytic"
  if backend not in base.BACKENDS:
    raise ValueError(f"unknown backend {backend!r}; valid backends: {list(base.BACKENDS)}")
  trained = None            # the level an agent learned at (a ladder task's)
  if isinstance(policy, base.Agent):
    policy, task, trained = _agent_task(policy, task, level, max_steps)
  else:
    task = task_of("ship" if task is None else task, max_steps, level)
  starts = fixed_starts(task, episodes, seed)
  bar = _progress_bar(episodes, task, progress)
  try:
    if isinstance(policy, base.Agent):
      record = _agent_record(policy, task, episodes, seed, backend, bar)
    else:
      benchmark_spaces.check(policy, task)
      act, batched = benchmark_spaces.actor(policy, batched, min(num_envs, episodes))
      record = sail(act, batched, task, starts, num_envs=num_envs, backend=backend, bar=bar)
  finally:
    bar.close()
  if task.world == "ship":
    record["J"] = _ship.mushroom_j(record, task.max_steps, task.out_of_bounds_reward)
  elif task.world == "taxi":
    record["optimal_return"] = optimal_returns(task, starts)
    record["delivered"] = record["outcome"] == taxi_rules.DELIVERED
  official = episodes == base.GREEDY_STARTS and seed == base.GREEDY_SEED and task.standard
  level = {} if task.level is None else {"level": task.level}
  if trained is not None:
    level["trained_level"] = trained
  metrics = {"task": task.name, **level, "episodes": int(episodes),
             "max_steps": task.max_steps, **metrics_of(record, task),
             "official": bool(official)}
  metrics.update(normalized(task.key, metrics))
  return Evaluation(metrics, record, task)


def metrics_of(record, task):
  """The named metrics of a benchmark record (see the module docstring)."""
  task = task_of(task)
  if task.world == "ship":
    out = _ship.gate_metrics(record, task.max_steps, task.out_of_bounds_reward)
    out["control_steps"] = int(record["steps"].sum())
    return out
  n = len(record)
  if task.world == "regatta":
    finished = record["finished"] > 0
    return {"finish_rate": float(finished.mean()) if n else None,
            "gates_passed": float(record["gates"].mean()) if n else None,
            "steps_to_finish": float(record["steps"][finished].mean()) if finished.any()
                               else None,
            "mean_return": float(record["return"].mean()) if n else None,
            "control_steps": int(record["steps"].sum())}
  mean = float(record["return"].mean()) if n else None
  optimum = float(record["optimal_return"].mean()) if n else None
  return {"mean_return": mean, "optimum": optimum,
          "fraction_of_optimum": mean / optimum if n and optimum != 0 else None,
          "delivery_rate": float(record["delivered"].mean()) if n else None,
          "primitive_steps": int(record["steps"].sum())}


def _progress_bar(episodes, task, progress):
  from tqdm import tqdm
  disable = None if progress is None else not progress      # None: on a terminal only
  return tqdm(total=int(episodes), unit="ep", desc=f"evaluate {task.key}", disable=disable,
              dynamic_ncols=True, file=sys.stderr)


def _agent_record(agent, task, episodes, seed, backend, bar, chunk=50):
  """An hpg_mj agent's greedy episodes from the fixed starts, as a benchmark record."""
  parts = []
  for first in range(0, int(episodes), chunk):
    n = min(chunk, int(episodes) - first)
    parts.append(agent.evaluate_fixed(n, backend, "greedy", int(seed) + first))
    bar.update(n)
  got = np.concatenate(parts) if parts else agent.empty_record()
  record = np.zeros(len(got), dtype=record_dtype(task.world))
  # An agent that says how its record reads as the benchmark's (a ladder agent's
  # `scored`: the regatta's finish, its return under the task's rewards), else by name;
  # an agent whose training rows sum the episodes ended in them (the Stable-Baselines3
  # and JAX agents: gates, return_sum, ...) evaluates a row an episode in those fields.
  if hasattr(agent, "scored"):
    fields = agent.scored(got)
  else:
    summed = ({"passed": "gates", "finished": "gates", "gates": "gates_passed",
               "return": "return_sum"} if "return_sum" in got.dtype.names and
              task.world != "taxi" else {})
    fields = {name: got[summed.get(name, name)] for name in record.dtype.names
              if summed.get(name, name) in got.dtype.names}
  for name in record.dtype.names:
    if name in fields:
      record[name] = fields[name]
  return record


class Pilot:
  """A policy as `evaluate` takes it (a function, `batched` or not, or an object with
  `predict`), acting on one observation at a time, as a video's episode needs
  (`hpg-mj render --policy module:name`): its space checked against `task`'s first
  (`benchmark_spaces.check`). A recurrent `predict` gets its state back at each call
  and `episode_start` at the first step after `reset`."""

  def __init__(self, policy, task, batched=None):
    self.task = task_of(task)
    benchmark_spaces.check(policy, self.task)
    self.act, self.batched = benchmark_spaces.actor(policy, batched)

    self.steps = 0

  def reset(self):
    """A new episode: its steps are counted from 0 (for the error a raise gives, and
    a recurrent policy's `episode_start`)."""
    self.steps = 0

  def __call__(self, obs):
    try:
      if not self.batched:
        out = self.act(obs)
      else:
        batch = benchmark_spaces.batch_of_one(obs)
        remembers = getattr(self.act, "takes_state", False)   # a predict's memory
        out = self.act.step(batch, [self.steps == 0]) if remembers else self.act(batch)
        out = np.asarray(out)[0]
    except Exception as err:
      raise benchmark_spaces.raised(f"step {self.steps}", err, obs) from err
    self.steps += 1
    return out


def _rows(obs, index):
  """Rows `index` of a batch of observations (an array, or a dictionary of arrays)."""
  if isinstance(obs, dict):
    return {key: value[index] for key, value in obs.items()}
  return obs[index]


def _each(obs):
  """One observation after another out of a batch (an array or a dictionary of them)."""
  if isinstance(obs, dict):
    keys = list(obs)
    return [dict(zip(keys, values)) for values in zip(*(obs[k] for k in keys))]
  return obs


def sail(act, batched, task, starts, num_envs=DEFAULT_NUM_ENVS, backend="analytic", bar=None):
  """Runs `act` from each of `starts` (`fixed_starts`' rows, or its dictionary on the
  ladder) through `num_envs` copies of the task's native vector environment
  (autoreset off: a copy that ends is put at the next start); returns the record
  without its derived fields (J, optimum)."""
  import gymnasium

  import hpg_mj  # noqa: F401  (registers the ids)
  task = task_of(task)
  given = starts if isinstance(starts, dict) else {"state": starts}
  n = _start_count(given)
  record = np.zeros(n, dtype=record_dtype(task.world))
  if n == 0:
    return record
  num_envs = min(int(num_envs), n)
  env = gymnasium.make_vec(task.env_id, num_envs=num_envs, autoreset_mode="Disabled",
                           **task.env_kwargs(backend))
  check = _taxi_actions(env.single_action_space.n) if task.world == "taxi" else _ship_actions
  placed = {key: np.array(value[:num_envs]) for key, value in given.items()}
  episode = np.arange(num_envs)          # the episode each copy sails; -1: none left
  following = num_envs
  steps = np.zeros(num_envs, dtype=np.int64)
  returns = np.zeros(num_envs)
  actions = np.zeros(num_envs, dtype=np.int64 if task.world == "taxi" else np.float64)
  obs, _ = env.reset(options=placed)
  total_steps, loops, shown = 0, 0, time.monotonic()
  # A predict that may return a state (a recurrent policy's) is called with every copy,
  # in order, and told which begin an episode, while it returns one; the first call
  # (every copy live) says whether it does.
  remembering = batched and getattr(act, "takes_state", False)
  try:
    while (episode >= 0).any():
      live = np.flatnonzero(episode >= 0)
      actions[:] = 0
      if remembering:
        every = _act(lambda rows: act.step(rows, steps == 0), True, obs, episode, steps, check)
        actions[live] = every[live]
        remembering = act.state is not None
      else:
        actions[live] = _act(act, batched, _rows(obs, live), episode[live], steps[live], check)
      obs, reward, terminated, truncated, info = env.step(actions)
      steps[live] += 1
      returns[live] += reward[live]
      total_steps += live.size
      ended = np.flatnonzero(terminated | truncated)
      for i in ended.tolist():
        k = episode[i]
        if k < 0:
          continue                        # a copy with no episode left, sailing idle
        row = record[k]
        row["steps"], row["return"] = steps[i], returns[i]
        if task.world == "ship":
          row["passed"] = info["event"][i] == "gate"
        elif task.world == "regatta":
          row["finished"] = info["event"][i] == "finish"
          row["gates"] = info["gates_passed"][i]
        else:
          row["outcome"] = taxi_rules.outcome(bool(truncated[i]), float(reward[i]))
        if following < n:
          for key, value in placed.items():
            value[i] = given[key][following]
          episode[i] = following
          following += 1
        else:
          episode[i] = -1
        if bar is not None:
          bar.update(1)
      if ended.size:
        mask = np.zeros(num_envs, dtype=np.bool_)
        mask[ended] = True
        obs, _ = env.reset(options={"reset_mask": mask, **placed})
        steps[ended] = 0
        returns[ended] = 0.0
      loops += 1
      if bar is not None and loops % 16 == 0 and time.monotonic() - shown > 0.5:
        bar.set_postfix_str(f"{total_steps:,} steps")      # moves while no episode ends
        shown = time.monotonic()
  finally:
    env.close()
  if bar is not None:
    bar.set_postfix_str(f"{total_steps:,} steps")
  return record


def _act(act, batched, obs, episodes, steps, check):
  """The policy's actions for the live copies, checked."""
  if batched:
    where = (f"episode {int(episodes[0])}, step {int(steps[0])} (a batch of {len(episodes)} "
             f"episodes: {_few(episodes)})")
    try:
      out = act(obs)
    except Exception as err:
      raise benchmark_spaces.raised(where, err, obs) from err
    return check(out, len(episodes), lambda k: f"episode {int(episodes[k])}, step {int(steps[k])}",
                 where)
  def at(k):
    return f"episode {int(episodes[k])}, step {int(steps[k])}"
  outs, k = [], 0
  try:
    for k, one in enumerate(_each(obs)):
      outs.append(act(one))
  except Exception as err:
    raise benchmark_spaces.raised(at(k), err, obs) from err
  try:                # one conversion for the batch (the common case: a number each)
    arr = np.asarray(outs)
  except Exception:   # shapes that differ: checked one by one below
    arr = None
  n = len(episodes)
  if arr is not None and arr.shape in ((n,), (n, 1)) and arr.dtype.kind in "iuf":
    return check(arr, len(episodes), at, at(0))
  return np.array([check(a, None, lambda _, k=k: at(k), at(k))[0] for k, a in enumerate(outs)])


def _few(episodes, shown=5):
  items = [str(int(e)) for e in episodes[:shown]]
  return ", ".join(items) + (", ..." if len(episodes) > shown else "")


def _shaped(out, n, where, what, world):
  """A policy's output as a flat array: one action (`n` None: a number or shape
  (1,)) or `n` of them (shape (n,) or (n, 1)), numbers; else refused."""
  try:
    arr = np.asarray(out)
  except Exception as err:    # e.g. a ragged list
    raise PolicyError(f"the policy returned {out!r} at {where}, not {what}: {err}") from None
  shapes = ((), (1,)) if n is None else ((n,), (n, 1))
  if arr.shape not in shapes or arr.dtype.kind not in "iuf":
    raise PolicyError(f"the policy returned shape {arr.shape} dtype {arr.dtype} at {where}; "
                      f"the {world} needs {what}")
  return arr.reshape(-1)


def _ship_actions(out, n, at, where):
  """Turning rates (deg/s) from a policy's output, finite. Out of [-15, 15] they
  are clipped, as the environment does."""
  what = ("one turning rate r (deg/s): a number or shape (1,)" if n is None else
          f"{n} turning rates r (deg/s): shape ({n},) or ({n}, 1)")
  arr = _shaped(out, n, where, what, "ship").astype(np.float64)
  bad = np.flatnonzero(~np.isfinite(arr))
  if bad.size:
    k = int(bad[0])
    raise PolicyError(f"the policy returned r = {float(arr[k])!r} at {at(k)}; the turning "
                      "rate must be finite")
  return arr


def _taxi_actions(n_actions):
  """The taxi's check of a policy's output: integers 0..n_actions - 1."""
  def check(out, n, at, where):
    what = (f"one action, an integer 0..{n_actions - 1}" if n is None else
            f"{n} actions, integers 0..{n_actions - 1}: shape ({n},) or ({n}, 1)")
    arr = _shaped(out, n, where, what, "taxi")
    with np.errstate(invalid="ignore"):
      bad = np.flatnonzero(~np.isfinite(arr) | (arr != np.round(arr)) | (arr < 0)
                           | (arr >= n_actions))
    if bad.size:
      k = int(bad[0])
      raise PolicyError(f"the policy returned action {arr[k].item()!r} at {at(k)}; allowed: "
                        + ", ".join(f"{a} {name}" for a, name in
                                    enumerate(taxi_core.ACTION_NAMES[:n_actions])))
    return arr.astype(np.int64)
  return check


# ---- policies of the bounds -------------------------------------------------------------

class RandomPolicy:
  """The random policy of the bounds: uniform over the task's actions (every ship's r
  uniform in [-15, 15] deg/s each control step), from its own seeded generator,
  drawn in the order the batches come."""

  def __init__(self, task="ship", seed=RANDOM_POLICY_SEED):
    self.task = task_of(task)
    self.random = np.random.default_rng(seed)

  def predict(self, obs, deterministic=True):
    """(actions, None) for a batch of observations, as SB3's `predict`: a uniform
    turning rate in deg/s for the ship, a uniform action for the taxi."""
    n = len(next(iter(obs.values())) if isinstance(obs, dict) else obs)
    if self.task.world != "taxi":
      return self.random.uniform(-ship_core.MAX_TURN_RATE, ship_core.MAX_TURN_RATE, n), None
    return self.random.integers(0, self.task.rules().num_actions, n), None


def helmsman_settings():
  """The gate target's settings: the shipped route's (`ship_rules.SHIPPED_TARGETS`:
  the posts moved in by 2 m)."""
  return ship_rules.SHIPPED_TARGETS


@numba.njit(cache=True)
def _helmsman_batch(obs, s, out):
  for i in range(obs.shape[0]):
    tx, ty = ship_rules.target_of(0, obs[i], 1.0, s.inset_m, s.approach_m)
    out[i] = ship_core.pilot_turn_rate(obs[i], tx, ty)


def helmsman(obs):
  """The scripted helmsman (`ship_core.pilot_turn_rate`) steering at the point of
  the gate nearest the ship (`ship_rules.target_of`'s gate target, the posts
  moved in by 2 m), for a batch of observations (n, 4): n turning rates."""
  obs = np.ascontiguousarray(obs, dtype=np.float64).reshape(-1, 4)
  out = np.empty(len(obs))
  _helmsman_batch(obs, helmsman_settings(), out)
  return out


helmsman.batched = True


class OptimalTaxiPolicy:
  """The exact optimal taxi policy: an action of greatest Q* (`worlds.taxi_values`;
  the first of equals). Any greedy policy on Q* earns V* from every start (the
  optimal actions form no cycle, `taxi_values.optimal_steps`)."""

  batched = True

  def __init__(self, task="taxi_fuel"):
    from hpg_mj.worlds import taxi_values
    self.task = task_of(task)
    self.fuel = self.task.name == "taxi_fuel"
    self.q = taxi_values.taxi_values(self.fuel, capacity=self.task.capacity).q

  def __call__(self, obs):
    obs = np.asarray(obs, dtype=np.int64).reshape(len(obs), -1)
    fuel = obs[:, 4] if self.fuel else np.full(len(obs), taxi_core.CLASSIC_FUEL)
    index = [taxi_core.encode_state(r, c, p, d, f, self.fuel)
             for (r, c, p, d), f in zip(obs[:, :4].tolist(), fuel.tolist())]
    return np.argmax(self.q[index], axis=1)


# ---- the ship's best known score: a search over first turns from each start -----------

FIRST_TURN_STEPS = 35       # full rudder one way for 0..34 control steps,
BACK_TURN_STEPS = 12        # then the other way for 0..11,
GATE_POINTS = 5             # then the helmsman to the gate's nearest point, one of 5
APPROACH_POINTS = 3         # points across it, or one of the route's 3 approach points
N_TARGETS = 1 + GATE_POINTS + APPROACH_POINTS


@numba.njit(cache=True)
def _sail_turns(state, rate, first, back, target, s, max_steps, gate_reward,
                out_of_bounds_reward, cap, samples):
  """One episode from `state` (changed in place): r = `rate` for `first` control
  steps, -`rate` for `back`, then the helmsman to `target`: 0, the gate's nearest
  point (followed); j = 1..GATE_POINTS, the j-th of equally spaced points across
  the gate; then the route's approach points before the gate line on the ship's
  side (its root's choices 1..3), until within its `radius_m`, then the gate's
  nearest point. Stops at the gate, off the field, at `max_steps` or at `cap`
  steps. Returns (event, control steps, return)."""
  steps, total = 0, 0.0
  width = ship_core.GATE[1, 0] - ship_core.GATE[0, 0]
  side = 1.0
  while True:
    if steps < first:
      r = rate
    elif steps < first + back:
      r = -rate
    else:
      if steps == first + back:
        side = ship_rules.side_of(state[1])
      if target > GATE_POINTS:
        tx, ty = ship_rules.target_of(target - GATE_POINTS, state, side, s.inset_m, s.approach_m)
        if math.hypot(state[0] - tx, state[1] - ty) <= s.radius_m:
          target = 0                        # reached: on through the gate
      if target == 0:
        tx, ty = ship_rules.target_of(0, state, side, s.inset_m, s.approach_m)
      elif target <= GATE_POINTS:
        tx, ty = ship_core.GATE[0, 0] + width * (target - 0.5) / GATE_POINTS, ship_core.GATE[0, 1]
      r = ship_core.pilot_turn_rate(state, tx, ty)
    ship_core.euler_control(state, r, samples)
    steps += 1
    event, reward = ship_core.global_outcome(samples, gate_reward, out_of_bounds_reward)
    total += reward
    if event != ship_core.NO_EVENT or steps >= max_steps or steps >= cap:
      return event, steps, total


@numba.njit(cache=True)
def _search_turns(starts, s, max_steps, gate_reward, out_of_bounds_reward, best, choice):
  """For each start, the fewest control steps to the gate over every first turn
  (`_sail_turns`); `best[i]` = (passed, steps, return) of that episode (of the
  plain helmsman's when none passes), `choice[i]` = (rate, first, back, target)."""
  samples = np.empty((ship_core.SAMPLES_PER_CONTROL + 1, 2))
  state = np.empty(4)
  for i in range(starts.shape[0]):
    state[:] = starts[i]
    event, steps, total = _sail_turns(state, 0.0, 0, 0, 0, s, max_steps, gate_reward,
                                      out_of_bounds_reward, max_steps, samples)
    passed = event == ship_core.SUCCESS
    best[i, 0], best[i, 1], best[i, 2] = passed, steps, total
    choice[i, 0], choice[i, 1], choice[i, 2], choice[i, 3] = 0.0, 0, 0, 0
    cap = steps if passed else max_steps
    for target in range(N_TARGETS):
      for sign in (1.0, -1.0):
        rate = sign * ship_core.MAX_TURN_RATE
        for first in range(FIRST_TURN_STEPS):
          for back in range(BACK_TURN_STEPS):
            if first == 0 and back == 0 and (target == 0 or sign < 0):
              continue                      # the plain helmsman, or a repeat
            state[:] = starts[i]
            event, steps, total = _sail_turns(state, rate, first, back, target, s, max_steps,
                                              gate_reward, out_of_bounds_reward, cap, samples)
            if event == ship_core.SUCCESS and (steps < cap or not best[i, 0]):
              best[i, 0], best[i, 1], best[i, 2] = 1.0, steps, total
              choice[i, 0], choice[i, 1], choice[i, 2], choice[i, 3] = rate, first, back, target
              cap = steps


def search_first_turns(task="ship", starts=None):
  """The per-start search of the ship's best known score (SPEC section 7.1): from
  each start, full rudder either way for 0-34 control steps, then the other way
  for 0-11, then the helmsman to the gate's nearest point, one of five points
  across it or one of the shipped route's three approach points (then the gate);
  the episode with the fewest steps to the gate. Returns (a benchmark
  record, the choices (rate, first, back, target) per start)."""
  task = task_of(task)
  if task.world != "ship":
    raise ValueError(f"search_first_turns is for the ship, not {task.name!r}")
  starts = fixed_starts(task) if starts is None else np.asarray(starts, dtype=np.float64)
  best = np.zeros((len(starts), 3))
  choice = np.zeros((len(starts), 4))
  _search_turns(np.ascontiguousarray(starts), helmsman_settings(), task.max_steps,
                task.gate_reward, task.out_of_bounds_reward, best, choice)
  record = np.zeros(len(starts), dtype=record_dtype("ship"))
  record["passed"], record["steps"], record["return"] = best[:, 0], best[:, 1], best[:, 2]
  record["J"] = _ship.mushroom_j(record, task.max_steps, task.out_of_bounds_reward)
  return record, choice


# ---- bounds and normalized scores ------------------------------------------------------

BEST_IS = {
    "ship_current": ("per start, the fewest control steps to the gate over first turns "
                     "before a helmsman that heads down the least-time field of the level's "
                     "water (planners.plan)"),
    "ship_goal": ("per start, the fewest control steps to the episode's gate over first "
                  "turns before helmsmen lining up with it from a grid of approaches "
                  "(among obstacles, also down distance fields round them to the line-up "
                  "points; planners.plan, planners_goal)"),
    "ship_regatta": ("per start, a rollout of the scripted helmsman gate by gate over the "
                     "whole course, each gate's way of taking it chosen by sailing every "
                     "candidate to the finish (planners.plan)"),
    "ship_harbour": ("per start, the fewest control steps to the gate over first turns "
                     "before a helmsman that heads down a distance field to the gate round "
                     "the level's obstacles grown by a safety margin, one of five margins "
                     "(planners.plan, planners_harbour)"),
}
REFERENCE_IS = {
    "ship_current": "a ship that turns at once, the least time of the grid's paths",
    "ship_goal": "the straight line to the gate (a lower bound)",
    "ship_regatta": "the shortest polyline through the gates in order (a lower bound)",
    "ship_harbour": ("a point that turns at once on the shortest grid path round the "
                     "obstacles, no margin (at least the shortest path, ~1.3% above it in "
                     "open water)"),
}
CHECKED_STARTS = 5            # the first starts whose best known episodes the file keeps


def best_known(task, starts, actions=False):
  """The best known episodes of a ladder task from `starts` (`fixed_starts`): (a
  benchmark record, the planner's choices per start, and with `actions` the turning
  rates sailed, `planners.plan`)."""
  from hpg_mj import planners
  task = task_of(task)
  if task.name not in LADDER:
    raise ValueError(f"best_known is for the ladder's tasks {list(LADDER)}, not {task.name!r}")
  outcome, choice, rates = planners.plan(task.name, task.level, starts, task.max_steps,
                                         task.gate_reward, task.out_of_bounds_reward, actions)
  record = np.zeros(len(outcome), dtype=record_dtype(task.world))
  if task.world == "regatta":
    for k, field in enumerate(("finished", "gates", "steps", "return")):
      record[field] = outcome[:, k]
  else:
    record["passed"], record["steps"], record["return"] = outcome.T
    record["J"] = _ship.mushroom_j(record, task.max_steps, task.out_of_bounds_reward)
  return record, choice, rates


def ladder_helmsman(task):
  """The scripted helmsman of a ladder task (its level's; `planners.Helmsman`), a
  batched policy for `evaluate`."""
  from hpg_mj import planners
  task = task_of(task)
  return planners.Helmsman(task.name, task.level)


def compute_bounds(episodes=base.GREEDY_STARTS, seed=base.GREEDY_SEED, progress=None,
                   say=None, tasks=None):
  """Each task's reference scores on the fixed starts (SPEC section 7.1): "random"
  (`RandomPolicy`), "best" (ship: the per-start search over first turns,
  `search_first_turns`; taxi: the exact optimum, `OptimalTaxiPolicy`; the ladder's:
  its planner, `best_known`) and, for the ship and the ladder, "helmsman" (`helmsman`,
  `ladder_helmsman`). `tasks`: names of `KEYS` (default all). What `hpg-mj bounds`
  writes."""
  say = say or (lambda line: None)
  tasks = KEYS if tasks is None else tuple(tasks)
  for name in tasks:
    if name not in KEYS:
      raise ValueError(f"no bounds for task {name!r}; allowed: {list(KEYS)}")
  out = {"protocol": {"episodes": int(episodes), "seed": int(seed),
                      "random_policy_seed": RANDOM_POLICY_SEED,
                      "num_envs": DEFAULT_NUM_ENVS,
                      "command": "hpg-mj bounds --out hpg_mj/benchmark_bounds.json"},
         "tasks": {}}
  for name in tasks:
    task = task_of(name)
    entry = {"max_steps": task.max_steps, "scores": list(SCORES[name])}

    def score(policy, label):
      say(f"{name}: {label} ...")
      result = evaluate(policy, task, episodes, seed=seed, progress=progress)
      return metrics_of(result.record, task)
    entry["random"] = score(RandomPolicy(task), "the random policy")
    if name == "ship":
      entry["helmsman"] = score(helmsman, "the scripted helmsman")
      say(f"{name}: the search over first turns from each start ...")
      record, _ = search_first_turns(task, fixed_starts(task, episodes, seed))
      entry["best"] = metrics_of(record, task)
      entry["best_is"] = ("per start, the fewest control steps to the gate over first turns "
                          "(search_first_turns)")
    elif task.name in LADDER:
      entry["helmsman"] = score(ladder_helmsman(task), "the scripted helmsman")
      say(f"{name}: the planner from each start ...")
      starts = fixed_starts(task, episodes, seed)
      record, _, _ = best_known(task, starts)
      entry["best"] = metrics_of(record, task)
      entry["best_is"] = BEST_IS[task.name]
      entry["best_of_first_starts"] = [[float(v) for v in row]
                                       for row in record[:CHECKED_STARTS].tolist()]
      done = record["finished" if task.world == "regatta" else "passed"] > 0
      reference = _reference_steps(task, starts)
      entry["reference"] = {
          "steps": float(reference[done].mean()) if done.any() else None,
          "best_steps": float(record["steps"][done].mean()) if done.any() else None,
          "is": REFERENCE_IS[task.name]}
    else:
      entry["best"] = score(OptimalTaxiPolicy(task), "the exact optimum")
      entry["best_is"] = "the exact optimal policy (worlds.taxi_values)"
    out["tasks"][name] = entry
  return out


def _reference_steps(task, starts):
  from hpg_mj import planners
  return planners.reference_steps(task.name, task.level, starts)


def normalized(task, metrics, published=None):
  """{"<score>_normalized": 100 (score - random) / (best known - random)} for the
  task's `SCORES` (0 = the random policy, 100 = the best known; D4RL's and
  Minari's normalized score); empty where no bounds are published. `task`: a name of
  `KEYS` ("ship", "ship_goal/hard", ...) or anything `task_of` takes."""
  name = task if isinstance(task, str) and task in KEYS else task_of(task).key
  return bounds_mod.normalized(name, metrics, published)


def format_bounds(published):
  """The bounds as lines of text, a table per task."""
  lines = []
  for name, entry in published["tasks"].items():
    rows = [k for k in ("random", "helmsman", "best") if k in entry]
    keys = [k for k in entry["best"] if k not in ("control_steps", "primitive_steps")]
    lines.append(f"{name} (max_steps {entry['max_steps']}; normalized: "
                 f"{', '.join(entry['scores'])}; best: {entry['best_is']})")
    lines.append("  " + f"{'':<10}" + "".join(f"{k:>20}" for k in keys))
    for row in rows:
      values = [entry[row][k] for k in keys]
      lines.append("  " + f"{row:<10}" + "".join(
          f"{'-' if v is None else format(v, '.4f'):>20}" for v in values))
    reference = entry.get("reference")
    if reference and reference["steps"] is not None:
      lines.append(f"  reference ({reference['is']}): {reference['steps']:.1f} control steps "
                   f"where the best known takes {reference['best_steps']:.1f} (over the starts "
                   "it completes)")
  return lines


def load_policy(spec):
  """A policy from "module:attribute" or "path/to/file.py:attribute" (the
  current directory is searched for modules)."""
  if not isinstance(spec, str) or spec.count(":") < 1:
    raise ValueError(f"--policy {spec!r}: give module:attribute (e.g. my_policies:steer) "
                     "or path/to/file.py:attribute")
  from hpg_mj import agents
  module_name, attribute = spec.rsplit(":", 1)
  if module_name.endswith(".py"):
    path = pathlib.Path(module_name)
    if not path.is_file():
      raise ValueError(f"--policy {spec!r}: no file {path}")
    loaded = importlib.util.spec_from_file_location(path.stem, path)

    def importing():
      module = importlib.util.module_from_spec(loaded)
      loaded.loader.exec_module(module)
      return module
  else:
    if "" not in sys.path and "." not in sys.path:
      sys.path.insert(0, "")

    def importing():
      return importlib.import_module(module_name)
  try:
    module = importing()
  except ModuleNotFoundError as err:
    raise ValueError(f"--policy {spec!r}: cannot import {module_name!r}: {err} (run from "
                     "its folder, or give path/file.py:name)") from None
  except Exception as err:  # noqa: BLE001  (a user's module may raise anything)
    # one line naming the module, not the error alone (it read as a bad option)
    raise ValueError(f"--policy {spec!r}: {agents.import_error(err)}") from None
  if not hasattr(module, attribute):
    raise ValueError(f"--policy {spec!r}: {module_name} has no attribute {attribute!r}")
  return getattr(module, attribute)
