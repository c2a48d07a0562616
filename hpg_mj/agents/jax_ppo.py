"""PPO in JAX on the ship and the taxi: the whole update (a rollout of every copy,
GAE, the minibatch epochs) one jitted function over the pure-JAX worlds
(`hpg_mj.jax`; SPEC section 7's reference agents, at budgets fair to the
hierarchies). The
learner is `hpg_mj.jax.ppo` (PureJaxRL's loop, written in one file); this module
is its agent: the task file's sections, the record, the greedy measure, the saved
state. It needs the extra `pip install 'hpg_mj[jax]'`; JAX is imported only when
such an agent is built, so hpg_mj without it loads these task files.

The same contract as Stable-Baselines3's agents (`hpg_mj.agents.sb3`), so that
their rows compare: a run's length in control steps ([protocol] control_steps),
record rows of `record_steps` = 1,000 control steps (all copies together) that sum
the episodes ended in them (ship: gates, gate_steps, return_sum, j_sum; taxi:
return_sum, episode_steps, deliveries), the same metrics over the last 100 rows,
and the greedy measure over the fixed seeded starts of every agent (SPEC section 7),
a row an episode. What the networks see (the ship's observation onto [-1, 1], the
taxi's one-hot) and how the ship's Gaussian acts (r = 15 u deg/s, clipped by the
world) is `hpg_mj.jax.ppo`'s docstring; the record and the metrics are in the
task's own units and rewards.

Differences from the SB3 agents: the worlds are the JAX ones in float32 (equal
to the numba worlds to 6.7e-3 m and deg over 2,100 control steps, docs/jax.md),
for training and for the greedy measure; the copies' starts are drawn from the
run's JAX key. Learning goes by whole updates (`n_envs` x `n_steps` control
steps); the episodes an update finishes past the rows asked for wait for the
next call, so the learning never depends on how training is cut into calls, nor
on where a run was checkpointed: a resumed run goes on bit for bit.
"""
import dataclasses

import numpy as np

from hpg_mj.agents import _ship
from hpg_mj.agents import _taxi
from hpg_mj.agents import base
from hpg_mj.agents import sb3
from hpg_mj import storage
from hpg_mj.taskfile import param

EXTRA = "pip install 'hpg_mj[jax]'"


@dataclasses.dataclass(frozen=True)
class PPOSection(sb3.PPOSection):
  """[ppo]: PPO (Schulman et al. 2017) as SB3's by the same names (constant step size
  and clip range), plus the two coefficients SB3 fixes at its defaults."""
  vf_coef: float = param(0.5, "weight of the value loss", low=0)
  max_grad_norm: float = param(0.5, "the gradient's global norm is clipped to this",
                               low=0, low_open=True)


def _check_batch(section):
  batch = section.n_envs * section.n_steps
  if batch % section.batch_size:
    raise ValueError(f"[ppo] batch_size = {section.batch_size} must divide n_envs x n_steps "
                     f"= {batch} (each epoch cuts the rollout into whole minibatches)")


def check_replay(name, section):
  """Refuses a replay learner's section ([sac], [dqn]) whose compiled call or buffer
  does not fit, in one line."""
  s = section
  if s.n_steps % s.train_freq:
    raise ValueError(f"[{name}] train_freq = {s.train_freq} must divide n_steps = {s.n_steps} "
                     "(the steps of one compiled call)")
  if s.buffer_size < s.n_envs:
    raise ValueError(f"[{name}] buffer_size = {s.buffer_size} must hold one step of every copy "
                     f"(n_envs = {s.n_envs})")


@dataclasses.dataclass(frozen=True)
class ShipPPOJaxConfig:
  """The task file's schema: its sections [environment] and [ppo]."""
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)
  ppo: PPOSection = dataclasses.field(default_factory=lambda: PPOSection(
      n_envs=64, n_steps=128, batch_size=2048, n_epochs=4, reward_scale=0.01))

  def __post_init__(self):
    _check_batch(self.ppo)


@dataclasses.dataclass(frozen=True)
class TaxiPPOJaxConfig:
  """The task file's schema: its sections [environment] and [ppo]."""
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)
  ppo: PPOSection = dataclasses.field(default_factory=lambda: PPOSection(
      n_envs=64, n_steps=128, batch_size=2048, n_epochs=4))

  def __post_init__(self):
    _check_batch(self.ppo)


def _learner(algorithm="ppo"):
  """hpg_mj.jax.<algorithm> (ppo, dqn, sac), or an ImportError saying how to get JAX."""
  import importlib
  try:
    return importlib.import_module(f"hpg_mj.jax.{algorithm}")
  except ImportError as err:
    raise ImportError(f"the JAX agents need the jax extra: {EXTRA} ({err})") from None


class _JaxAgent:
  """What the JAX agents share (mixed into the world's agent class): a subclass sets
  `algorithm` (its learner `hpg_mj.jax.<algorithm>` and its task file's section) and
  gives `_world()`: the JAX environment, its parameters and its record row."""

  algorithm = "ppo"

  tags = ("reference", "jax")
  record_steps = 1000            # control steps of one training record row
  metric_window = 100            # the online metrics: the last 100,000 control steps
  measures_evaluation_whole = True
  per_episode_scores = True
  checkpoint_rows = 1000         # `hpg-mj run` checkpoints at least every 1 M control steps
  # As the SB3 agents' (rows of control steps; evaluations sail a batch of starts at
  # once through `_sail`): one implementation.
  _window = sb3._SB3Agent._window
  run = sb3._SB3Agent.run
  evaluate = sb3._SB3Agent.evaluate
  evaluate_fixed = sb3._SB3Agent.evaluate_fixed

  def _init_jax(self):
    if self.config.environment.backend != "analytic":
      raise ValueError(f"{self.name}: [environment] backend = "
                       f"{self.config.environment.backend!r}; the JAX agents train on the JAX "
                       "world (the analytic ship of Equation 1, the taxi's rules; allowed: "
                       "'analytic')")
    self.section = getattr(self.config, self.algorithm)
    self.control_steps = 0       # trained so far, all copies together
    self._trainer = None
    self._runner = None
    # Per-step sums (control steps so far, then the record's fields but `steps`) of
    # the episodes an update finished past the rows returned.
    self._pending = np.zeros((0, len(self.record_fields)))

  def final_metrics(self, record):
    """The control steps the learner trained, all copies together
    (`control_steps_trained`): whole updates, so up to one update past the record's
    rows (`control_steps`; a 2-row run of 64 copies x 128 steps trains 8,192); the
    episodes ended past the rows are the next call's."""
    return {"control_steps_trained": self.control_steps}

  @property
  def trainer(self):
    if self._trainer is None:
      env, params, row = self._world(_learner())
      self._trainer = _learner(self.algorithm).Trainer(env, params, self.section, row)
    return self._trainer

  def _compiled(self):
    return _learner(self.algorithm).compiled(self.trainer)

  @property
  def runner(self):
    """The run's whole state (`hpg_mj.jax.ppo.Runner`), made from the seed when first asked."""
    if self._runner is None:
      init = self._compiled()[0]
      self._runner = init(_learner().key(self.seed))
    return self._runner

  # ---- training ------------------------------------------------------------------

  def train(self, episodes, backend=None):
    """Learns for `episodes` record rows of `record_steps` control steps each."""
    if backend not in (None, "analytic"):
      raise ValueError(f"{self.name} trains on the analytic world only; got backend "
                       f"{backend!r}")
    base._check_count("rows", episodes)
    update = self._compiled()[1]
    first = self.episodes
    end = (first + int(episodes)) * self.record_steps
    runner, parts = self.runner, [self._pending]
    n_envs, n_steps = self.section.n_envs, self.section.n_steps
    while self.control_steps < end:
      runner, sums = update(runner)
      counts = self.control_steps + n_envs * np.arange(1, n_steps + 1, dtype=np.float64)
      parts.append(np.column_stack([counts, np.asarray(sums, dtype=np.float64)]))
      self.control_steps += n_envs * n_steps
    self._runner = runner
    steps = np.concatenate(parts)
    row = (steps[:, 0] - 1) // self.record_steps - first        # the row each step is in
    now = row < int(episodes)
    rows = np.zeros((int(episodes), len(self.record_fields)))
    rows[:, 0] = self.record_steps
    np.add.at(rows[:, 1:], row[now].astype(np.int64), steps[now, 1:])
    self._pending = steps[~now & (steps[:, 1] > 0)]             # only steps that ended episodes
    self.episodes += int(episodes)
    return self.as_record(rows)

  # ---- evaluation --------------------------------------------------------------------

  def _sail(self, starts, backend, policy):
    """One episode from each start, all at once, without learning: greedy (the
    Gaussian's mean, the most likely action) or sampled (from the agent's generator)."""
    if policy not in base.POLICIES:
      raise ValueError(f"policy {policy!r} is not known; allowed: {list(base.POLICIES)}")
    if (backend or "analytic") != "analytic":
      raise ValueError(f"{self.name} sails the JAX world (backend 'analytic'); got backend "
                       f"{backend!r}")
    if len(starts) == 0:
      return self.empty_record()
    sail = self._compiled()[2]
    seed = None if policy == "greedy" else int(self.rng_state[0] % (2 ** 31))
    rows, lengths = sail(self.trainer.acting(self.runner), np.asarray(starts),
                         _learner().key(0 if seed is None else seed), seed is not None)
    out = np.column_stack([np.asarray(lengths, np.float64), np.asarray(rows, np.float64)])
    return self.as_record(out)

  def graph(self):
    # A ValueError, so that `hpg-mj render --agent` refuses it in one line.
    raise ValueError(f"{self.name} is a flat JAX policy with no task graph to sail step by "
                     "step (render --agent draws those); score it with hpg-mj evaluate")

  # ---- saving ------------------------------------------------------------------------

  def state(self):
    ppo = _learner()
    arrays = {"rng_state": self.rng_state,
              "control_steps": np.array(self.control_steps, dtype=np.int64),
              "pending": self._pending}
    arrays.update({f"runner.{k}": v for k, v in ppo.to_arrays(self.runner).items()})
    return arrays

  def restore(self, arrays, where):
    ppo = _learner()
    mine = {"rng_state", "control_steps", "pending"}
    missing = mine - set(arrays)
    if missing:
      raise storage.AgentFileError(f"{where}: arrays do not fit {self.name} (missing "
                                   f"{sorted(missing)})")
    storage.restore_into({"rng_state": self.rng_state}, {"rng_state": arrays["rng_state"]},
                         where)
    pending = np.asarray(arrays["pending"], dtype=np.float64)
    if pending.ndim != 2 or pending.shape[1] != len(self.record_fields):
      raise storage.AgentFileError(f"{where}: array 'pending' has shape {pending.shape}, "
                                   f"needs (n, {len(self.record_fields)})")
    runner = {k[len("runner."):]: v for k, v in arrays.items() if k.startswith("runner.")}
    try:
      self._runner = ppo.from_arrays(self.runner, runner, where)
    except ValueError as err:
      raise storage.AgentFileError(str(err)) from None
    self.control_steps = int(arrays["control_steps"])
    self._pending = pending


class ShipPPOJax(_JaxAgent, _ship.ShipAgent):
  """PPO in JAX on the full ship task (SPEC section 2), the task file's rewards."""
  name = "ship_ppo_jax"
  Config = ShipPPOJaxConfig
  record_fields = sb3._SB3Ship.record_fields
  metrics = sb3._SB3Ship.metrics

  def __init__(self, config=None, seed=0, task=None):
    _ship.ShipAgent.__init__(self, config, seed, task)
    self._init_jax()

  def _world(self, ppo):
    from hpg_mj import jax as hpg_jax
    env = self.config.environment
    world, params = hpg_jax.make("ShipSteering-v0", max_steps_in_episode=env.max_steps,
                                 gate_reward=env.gate_reward,
                                 out_of_bounds_reward=env.out_of_bounds_reward)
    row = ppo.ShipRow(_ship.J_GAMMA, _ship.J_STEP_REWARD, _ship.J_GATE_REWARD,
                      _ship.J_OUT_OF_BOUNDS_REWARD)
    return world, params, row


class TaxiPPOJax(_JaxAgent, _taxi.TaxiAgent):
  """PPO in JAX on taxi-fuel (or the classic taxi, [environment] fuel = false)."""
  name = "taxi_ppo_jax"
  Config = TaxiPPOJaxConfig
  record_fields = sb3._SB3Taxi.record_fields
  metrics = sb3._SB3Taxi.metrics

  def __init__(self, config=None, seed=0, task=None):
    _taxi.TaxiAgent.__init__(self, config, seed, task)
    self._init_jax()

  def _world(self, ppo):
    from hpg_mj import jax as hpg_jax
    r = self.rules
    extra = {"capacity": r.capacity} if r.fuel_enabled else {}
    world, params = hpg_jax.make("TaxiFuel-v0" if r.fuel_enabled else "Taxi-v0",
                                 max_steps_in_episode=r.max_steps, **extra)
    return world, params, ppo.TaxiRow()
