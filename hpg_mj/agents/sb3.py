"""Reference agents from an outside library: Stable-Baselines3's PPO and SAC on the
ship, PPO and DQN on taxi-fuel, registered like every agent, so that
`hpg-mj train`, `hpg-mj run` (checkpoints, resume), `hpg-mj evaluate`, the
figures and REPORT.md take them. They need the extra: `pip install 'hpg_mj[sb3]'`;
torch and SB3 are imported only when such an agent is built, so hpg_mj without
the extra loads (and validates) these task files and is never slowed.

Each learns through `hpg_mj.envs.sb3.NativeVecEnv`, SB3's VecEnv over the native
vector environment (all copies stepped in one compiled call), on the analytic
world with the task file's rewards. Deep RL budgets are control steps, so a run's
length is too: [protocol] control_steps, in record rows of `record_steps` = 1,000
control steps each (the mechanism of the continuing agents, hpg_mj.taskfile).
Row k sums the episodes that ended within control steps (1,000 k, 1,000 (k+1)]
of training, all copies together: `steps` (1,000), `episodes`, and per world
(ship: gates, gate_steps, return_sum, j_sum; taxi: return_sum, episode_steps,
deliveries); a greedy or evaluation record has one row per episode in the same
fields (`steps` its length, `episodes` 1). The metrics are the world's, over the
latest rows that hold at least 1,000 episodes. SB3 learns in fixed chunks of
control steps (`chunk_steps`: one PPO rollout); the episodes a chunk finishes past
the rows asked for wait for the next call, so that the learning never depends on
how training is cut into calls (nor on where a run was checkpointed). The model
has then learned from at most one chunk more than the rows hold.

The greedy measure (SPEC section 7) sails the fixed seeded starts of every
agent (`Agent.fixed_starts`) all at once through the native batch, the policy
acting deterministically (`model.predict(..., deterministic=True)`).

The saved state is SB3's own (`model.save`, the replay buffer's
`save_replay_buffer`) with what SB3 does not save: the batch's worlds and their
generators, the episodes waiting, and the generators of torch, numpy and Python
and the action space's. A run resumed from a checkpoint continues as the run never
stopped would, bit for bit on the same machine and torch (tests/test_sb3.py).
SB3 draws from process-wide generators: two of these agents trained in turn in one
process draw from the same ones (the runs of `hpg-mj run` are one per process);
evaluating leaves them as they were. Building one sets torch to one thread.
"""
import dataclasses
import io
import pickle
import random
import types
import zipfile

import numpy as np

from hpg_mj.agents import _ship
from hpg_mj.agents import _taxi
from hpg_mj import storage
from hpg_mj import taskfile
from hpg_mj.taskfile import param
from hpg_mj.worlds import taxi_rules as world_rules

EXTRA = "pip install 'hpg_mj[sb3]'"


def _sb3():
  """stable_baselines3 and torch, or an ImportError saying how to get them."""
  try:
    import stable_baselines3
    import torch
  except ImportError as err:
    raise ImportError(f"the Stable-Baselines3 agents need the sb3 extra: {EXTRA} ({err})") \
        from None
  return stable_baselines3, torch


# ---- the task files' sections: each algorithm's main hyper-parameters -------------

N_ENVS_DOC = "copies of the native vector environment, stepped together"
REWARD_SCALE_DOC = "SB3 learns from the task's rewards times this (the record keeps them unscaled)"
NET_ARCH_DOC = "hidden layers of the policy and value (or Q) networks"


@dataclasses.dataclass(frozen=True)
class PPOSection(taskfile.Section):
  """[ppo]: SB3's PPO (Schulman et al. 2017), constant step size and clip range."""
  n_envs: int = param(8, N_ENVS_DOC, low=1)
  n_steps: int = param(256, "control steps per copy in each rollout", low=1)
  batch_size: int = param(256, "minibatch size", low=2)
  n_epochs: int = param(10, "passes over each rollout", low=1)
  learning_rate: float = param(3e-4, "Adam step size", low=0, low_open=True)
  gamma: float = param(0.99, "discount", low=0, high=1)
  gae_lambda: float = param(0.95, "GAE lambda", low=0, high=1)
  clip_range: float = param(0.2, "PPO's clip range", low=0, low_open=True)
  ent_coef: float = param(0.0, "entropy bonus", low=0)
  reward_scale: float = param(1.0, REWARD_SCALE_DOC, low=0, low_open=True)
  net_arch: tuple = param((64, 64), NET_ARCH_DOC, length=None, low=1)


@dataclasses.dataclass(frozen=True)
class SACSection(taskfile.Section):
  """[sac]: SB3's SAC (Haarnoja et al. 2018), entropy coefficient learned ("auto")."""
  n_envs: int = param(4, N_ENVS_DOC, low=1)
  learning_rate: float = param(3e-4, "Adam step size of actor, critics and entropy",
                               low=0, low_open=True)
  buffer_size: int = param(1_000_000, "replay buffer (transitions)", low=1)
  learning_starts: int = param(10_000, "control steps of uniform random actions first", low=0)
  batch_size: int = param(256, "minibatch size", low=1)
  tau: float = param(0.005, "target networks' soft update", low=0, high=1, low_open=True)
  gamma: float = param(0.99, "discount", low=0, high=1)
  train_freq: int = param(1, "steps of every copy between updates", low=1)
  gradient_steps: int = param(4, "gradient steps per update", low=1)
  reward_scale: float = param(0.01, REWARD_SCALE_DOC, low=0, low_open=True)
  net_arch: tuple = param((256, 256), "hidden layers of actor and critics", length=None, low=1)


@dataclasses.dataclass(frozen=True)
class DQNSection(taskfile.Section):
  """[dqn]: SB3's DQN (Mnih et al. 2015), epsilon decaying linearly over
  `exploration_steps` control steps, then held at `exploration_final_eps`."""
  n_envs: int = param(4, N_ENVS_DOC, low=1)
  learning_rate: float = param(1e-3, "Adam step size", low=0, low_open=True)
  buffer_size: int = param(100_000, "replay buffer (transitions)", low=1)
  learning_starts: int = param(1_000, "control steps before learning starts", low=0)
  batch_size: int = param(64, "minibatch size", low=1)
  gamma: float = param(0.99, "discount", low=0, high=1)
  train_freq: int = param(1, "steps of every copy between updates", low=1)
  gradient_steps: int = param(1, "gradient steps per update", low=1)
  target_update_interval: int = param(2_000, "control steps between target network copies",
                                      low=1)
  exploration_steps: int = param(200_000, "control steps of the linear epsilon decay",
                                 low=1)
  exploration_initial_eps: float = param(1.0, "epsilon at first", low=0, high=1)
  exploration_final_eps: float = param(0.05, "epsilon after the decay", low=0, high=1)
  reward_scale: float = param(1.0, REWARD_SCALE_DOC, low=0, low_open=True)
  net_arch: tuple = param((64, 64), NET_ARCH_DOC, length=None, low=1)


def _model_kwargs(algorithm, section):
  """SB3's constructor arguments from a section (same names, less ours)."""
  values = dataclasses.asdict(section)
  for ours in ("n_envs", "reward_scale", "net_arch", "exploration_steps"):
    values.pop(ours, None)
  values["policy_kwargs"] = {"net_arch": list(section.net_arch)}
  if algorithm == "dqn":
    values["exploration_fraction"] = 1.0     # over `exploration_steps` (the horizon below)
  return values


# ---- the agents -------------------------------------------------------------------

class _SB3Agent:
  """What the four agents share (mixed into the world's agent class). A subclass
  sets `algorithm` ("ppo", "sac", "dqn"), `env_id` and `rescale`, and turns a
  finished episode into the record's fields (`_episode`)."""

  algorithm = None
  env_id = None
  rescale = False
  tags = ("reference", "stable-baselines3")
  # The online metrics are over the last 100 rows (1,000 control steps each): the
  # episodes that ended in the last 100,000 control steps of training.
  metric_window = 100
  # An evaluation's record is a row an episode, measured whole (`_window`).
  measures_evaluation_whole = True
  # Rows of control steps, but scores over the benchmark task's episodes: they
  # are normalized against its bounds (SPEC section 7.1) like every episodic agent's.
  per_episode_scores = True
  CHUNK_PER_COPY = 1000          # control steps per copy in one off-policy `learn` call
  start_dtype = np.float64       # of the world's states

  def _init_sb3(self):
    if self.config.environment.backend != "analytic":
      raise ValueError(f"{self.name}: [environment] backend = "
                       f"{self.config.environment.backend!r}; the SB3 agents train on the "
                       "native vector environment of the analytic world (allowed: 'analytic')")
    self.section = getattr(self.config, self.algorithm)
    self.model = None
    self.env = None
    self._pending = []           # finished episodes (NativeVecEnv.finished) past the rows returned

  # ---- building ------------------------------------------------------------------

  def _env_kwargs(self, backend):
    raise NotImplementedError

  def _native(self, n_envs, backend="analytic"):
    from hpg_mj.envs import sb3 as sb3_env
    return sb3_env.make_vec_env(self.env_id, n_envs, rescale=self.rescale,
                                reward_scale=self.section.reward_scale,
                                **self._env_kwargs(backend))

  @property
  def chunk_steps(self):
    """Control steps (all copies) of one `learn` call: one PPO rollout, or
    `CHUNK_PER_COPY` steps of every copy off-policy."""
    n = self.section.n_envs
    return n * (self.section.n_steps if self.algorithm == "ppo" else self.CHUNK_PER_COPY)

  def _algorithm_class(self):
    sb3, torch = _sb3()
    torch.set_num_threads(1)     # runs go in parallel, one per core; a small MLP gains nothing
    return {"ppo": sb3.PPO, "sac": sb3.SAC, "dqn": sb3.DQN}[self.algorithm]

  def _build(self):
    cls = self._algorithm_class()
    self.env = self._native(self.section.n_envs)
    self.model = _without_log_folders(
        cls("MlpPolicy", self.env, seed=self.seed, device="cpu", verbose=0,
            **_model_kwargs(self.algorithm, self.section)))

  def _ensure_model(self):
    if self.model is None:
      self._build()
    return self.model

  def _callback(self):
    from stable_baselines3.common.callbacks import BaseCallback
    horizon = getattr(self.section, "exploration_steps", None)

    class Horizon(BaseCallback):
      """Puts SB3's schedules (DQN's epsilon) on our horizon in control steps, not
      on the length of one `learn` call."""

      def _on_training_start(self):
        if horizon is not None:
          self.model._total_timesteps = horizon

      def _on_step(self):
        return True

    return Horizon()

  # ---- the agent interface ----------------------------------------------------------

  record_steps = 1000            # control steps of one training record row
  checkpoint_rows = 250          # `hpg-mj run` checkpoints at least every 0.25 M steps

  def train(self, episodes, backend=None):
    """Learns for `episodes` record rows of `record_steps` control steps each."""
    if backend not in (None, "analytic"):
      raise ValueError(f"{self.name} trains on the analytic world only; got backend "
                       f"{backend!r}")
    _check_count("rows", episodes)
    model = self._ensure_model()
    first = self.episodes
    end = (first + int(episodes)) * self.record_steps
    while self.env.control_steps < end:
      model.learn(self.chunk_steps, reset_num_timesteps=False, callback=self._callback(),
                  progress_bar=False)
      self._pending.extend(self.env.finished())
    rows = np.zeros((int(episodes), len(self.record_fields)))
    rows[:, 0] = self.record_steps
    keep = []
    for ended in self._pending:
      k = (ended[0] - 1) // self.record_steps - first      # the row it ended in
      if k < int(episodes):
        rows[k, 1:] += self._episode(*ended[1:])[1:]
      else:
        keep.append(ended)
    self._pending = keep
    self.episodes += int(episodes)
    return self.as_record(rows)

  def run(self, episodes, backend=None, learn=True, sample=None):
    if learn:
      return self.train(episodes, backend)
    return self.evaluate(episodes, backend, "sampled" if sample else "greedy")

  def evaluate(self, episodes, backend=None, policy="greedy"):
    """`episodes` episodes from starts drawn from the agent's generator, one row each."""
    _check_count("episodes", episodes)
    starts = np.array([self.start_state() for _ in range(int(episodes))])
    return self._sail(starts, backend, policy)

  def evaluate_fixed(self, episodes=None, backend=None, policy="greedy", seed=None):
    """One episode from each of the fixed seeded starts of every agent (SPEC section 7)."""
    from hpg_mj.agents import base
    episodes = base.GREEDY_STARTS if episodes is None else episodes
    seed = base.GREEDY_SEED if seed is None else seed
    return self._sail(self.fixed_starts(episodes, seed), backend, policy)

  def _sail(self, starts, backend, policy):
    """One episode from each start, all at once, without learning."""
    from hpg_mj.agents import base
    if policy not in base.POLICIES:
      raise ValueError(f"policy {policy!r} is not known; allowed: {list(base.POLICIES)}")
    backend = backend or "analytic"
    if backend not in base.BACKENDS:
      raise ValueError(f"unknown backend {backend!r}; valid backends: {list(base.BACKENDS)}")
    if len(starts) == 0:
      return self.empty_record()
    model = self._ensure_model()
    env = self._native(len(starts), backend)
    env.seed(0)                  # the copies' later restarts, never recorded
    env.set_options({"state": np.asarray(starts, dtype=self.start_dtype)})
    obs = env.reset()
    rows = [None] * len(starts)
    saved = _generators()        # a sampled policy draws from them; training must not see it
    try:
      while any(r is None for r in rows):
        actions, _ = model.predict(obs, deterministic=policy == "greedy")
        obs, _, _, _ = env.step(actions)
        for ended in env.finished():
          if rows[ended[1]] is None:
            rows[ended[1]] = self._episode(*ended[1:])
    finally:
      _set_generators(saved)
    return self.as_record(np.array(rows, dtype=np.float64))

  def _window(self, record):
    """The rows `metrics` is over: a training record's last `metric_window` rows
    (each `record_steps` control steps); an evaluation's record (`_sail`: a row per
    episode, of its length) whole, so that the greedy measure is over every fixed
    start (SPEC section 7), as every agent's is."""
    evaluation = np.all(record["episodes"] == 1) and np.any(record["steps"] != self.record_steps)
    return record if evaluation else record[-self.metric_window:]

  def graph(self):
    # A ValueError, so that `hpg-mj render --agent` refuses it in one line.
    raise ValueError(f"{self.name} is a flat Stable-Baselines3 policy with no task graph to "
                     "sail step by step (render --agent draws those); score it with hpg-mj "
                     "evaluate")

  # ---- saving ---------------------------------------------------------------------------

  def state(self):
    return {"rng_state": self.rng_state,
            "sb3": np.frombuffer(self._snapshot(), dtype=np.uint8)}

  def _snapshot(self):
    model = self._ensure_model()
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_STORED) as archive:
      buffer = io.BytesIO()
      model.save(buffer)
      archive.writestr("model.zip", buffer.getvalue())
      if getattr(model, "replay_buffer", None) is not None:
        buffer = io.BytesIO()
        model.save_replay_buffer(buffer)
        archive.writestr("replay_buffer.pkl", buffer.getvalue())
      extra = {"env": self.env, "pending": self._pending, **_generators(),
               "action_space": model.action_space.np_random.bit_generator.state}
      archive.writestr("extra.pkl", pickle.dumps(extra))
    return out.getvalue()

  def restore(self, arrays, where):
    expected = {"rng_state", "sb3"}
    if set(arrays) != expected:
      raise storage.AgentFileError(f"{where}: arrays do not fit {self.name} (has "
                                   f"{sorted(arrays)}, needs {sorted(expected)})")
    storage.restore_into({"rng_state": self.rng_state}, {"rng_state": arrays["rng_state"]},
                         where)
    cls = self._algorithm_class()
    try:
      with zipfile.ZipFile(io.BytesIO(arrays["sb3"].tobytes())) as archive:
        names = set(archive.namelist())
        extra = pickle.loads(archive.read("extra.pkl"))
        model = cls.load(io.BytesIO(archive.read("model.zip")), env=extra["env"], device="cpu",
                         force_reset=False)   # keep the saved _last_obs: no reset
        if "replay_buffer.pkl" in names:
          model.load_replay_buffer(io.BytesIO(archive.read("replay_buffer.pkl")))
    except (zipfile.BadZipFile, KeyError, pickle.UnpicklingError) as err:
      raise storage.AgentFileError(f"{where}: its SB3 state does not load: {err}") from None
    _set_generators(extra)
    model.action_space.np_random.bit_generator.state = extra["action_space"]
    self.model, self.env = _without_log_folders(model), extra["env"]
    self._pending = list(extra["pending"])


def _without_log_folders(model):
  """`model` with a logger that writes nowhere. Without one of its own, SB3 makes a
  logger at every `learn` call, and a logger without a folder makes a new empty
  folder (SB3-<date-time>) in the temporary directory: one per chunk of training,
  ~170 per run of this project's tests. Its records (verbose=0) went nowhere anyway."""
  from stable_baselines3.common.logger import Logger
  model.set_logger(Logger(folder=None, output_formats=[]))
  return model


def _generators():
  """The process-wide generators SB3 draws from (torch, numpy's global, Python's)."""
  _, torch = _sb3()
  return {"torch": torch.get_rng_state(), "numpy": np.random.get_state(),
          "python": random.getstate()}


def _set_generators(states):
  _, torch = _sb3()
  torch.set_rng_state(states["torch"])
  np.random.set_state(states["numpy"])
  random.setstate(states["python"])


def _check_count(name, value):
  from hpg_mj.agents import base
  base._check_count(name, value)


# ---- the ship ---------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class ShipPPOConfig:
  """The task file's schema: its sections [environment] and [ppo]."""
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)
  ppo: PPOSection = dataclasses.field(default_factory=lambda: PPOSection(reward_scale=0.01))


@dataclasses.dataclass(frozen=True)
class ShipSACConfig:
  """The task file's schema: its sections [environment] and [sac]."""
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)
  sac: SACSection = dataclasses.field(default_factory=SACSection)


class _SB3Ship(_SB3Agent, _ship.ShipAgent):
  """SB3 on the full ship task (SPEC section 2): observations and the turning rate
  rescaled to [-1, 1] (`NativeVecEnv(rescale=True)`), the task file's rewards."""

  env_id = "hpg_mj/ShipSteering-v0"
  rescale = True
  record_fields = ("steps", "episodes", "gates", "gate_steps", "return_sum", "j_sum")

  def __init__(self, config=None, seed=0, task=None):
    _ship.ShipAgent.__init__(self, config, seed, task)
    self._init_sb3()

  def _env_kwargs(self, backend):
    env = self.config.environment
    return {"backend": backend, "max_steps": env.max_steps, "gate_reward": env.gate_reward,
            "out_of_bounds_reward": env.out_of_bounds_reward}

  def _episode(self, copy, total, steps, ending, event, last_reward):
    """One episode as a row of the record's fields."""
    passed = float(event == "gate")
    one = {"passed": np.array([passed]), "steps": np.array([float(steps)]),
           "return": np.array([total])}
    return (float(steps), 1.0, passed, passed * steps, total, float(self.j(one)[0]))

  def metrics(self, record):
    """ShipAgent's metrics, from the row sums."""
    w = self._window(record)
    episodes, gates = w["episodes"].sum(), w["gates"].sum()
    return {
        "episodes_measured": int(episodes), "rows_measured": int(len(w)),
        "gate_pass_rate": float(gates / episodes) if episodes else None,
        "steps_to_gate": float(w["gate_steps"].sum() / gates) if gates else None,
        "mean_return": float(w["return_sum"].sum() / episodes) if episodes else None,
        "J": float(w["j_sum"].sum() / episodes) if episodes else None,
        "control_steps": int(record["steps"].sum()),
    }


class ShipPPO(_SB3Ship):
  """Stable-Baselines3 PPO on the full ship task."""
  name = "ship_ppo"
  algorithm = "ppo"
  Config = ShipPPOConfig


class ShipSAC(_SB3Ship):
  """Stable-Baselines3 SAC on the full ship task."""
  name = "ship_sac"
  algorithm = "sac"
  Config = ShipSACConfig
  checkpoint_rows = 5            # a few minutes of SAC on one core (a row: 50-85 s here)


# ---- taxi-fuel ---------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class TaxiPPOConfig:
  """The task file's schema: its sections [environment] and [ppo]."""
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)
  ppo: PPOSection = dataclasses.field(default_factory=PPOSection)


@dataclasses.dataclass(frozen=True)
class TaxiDQNConfig:
  """The task file's schema: its sections [environment] and [dqn]."""
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)
  dqn: DQNSection = dataclasses.field(default_factory=DQNSection)


class _SB3Taxi(_SB3Agent, _taxi.TaxiAgent):
  """SB3 on taxi (SPEC section 5): the observation (row, column, passenger,
  destination, fuel) one-hot per component (SB3's MultiDiscrete preprocessing),
  the seven actions."""

  record_fields = ("steps", "episodes", "return_sum", "episode_steps", "deliveries")
  start_dtype = np.int64

  def __init__(self, config=None, seed=0, task=None):
    _taxi.TaxiAgent.__init__(self, config, seed, task)
    self._init_sb3()

  @property
  def env_id(self):
    return "hpg_mj/TaxiFuel-v0" if self.rules.fuel_enabled else "hpg_mj/Taxi-v0"

  def _env_kwargs(self, backend):
    if backend != "analytic":
      raise ValueError(f"{self.name} sails the taxi's rules (backend 'analytic'); the "
                       f"dm_control board (backend {backend!r}) is not batched")
    extra = {"capacity": self.rules.capacity} if self.rules.fuel_enabled else {}
    return {"max_steps": self.rules.max_steps, **extra}

  def _episode(self, copy, total, steps, ending, event, last_reward):
    """One episode as a row of the record's fields."""
    from hpg_mj.envs import sb3 as sb3_env
    last = types.SimpleNamespace(truncated=ending == sb3_env.TRUNCATED, reward=last_reward)
    delivered = world_rules.outcome_of(last) == world_rules.DELIVERED
    return (float(steps), 1.0, total, float(steps), float(delivered))

  def metrics(self, record):
    """TaxiAgent's metrics, from the row sums."""
    from hpg_mj.worlds import taxi_values
    w = self._window(record)
    episodes = w["episodes"].sum()
    optimal = self.optimal_mean_return()
    mean = float(w["return_sum"].sum() / episodes) if episodes else None
    return {"episodes_measured": int(episodes), "rows_measured": int(len(w)),
            "mean_return": mean,
            "optimal_mean_return": optimal,
            "reaches_95_percent": bool(mean is not None and mean >=
                                       taxi_values.performance_threshold(optimal, 0.95)),
            "delivered": float(w["deliveries"].sum() / episodes) if episodes else None,
            "primitive_steps": int(record["steps"].sum())}


class TaxiPPO(_SB3Taxi):
  """Stable-Baselines3 PPO on taxi-fuel."""
  name = "taxi_ppo"
  algorithm = "ppo"
  Config = TaxiPPOConfig


class TaxiDQN(_SB3Taxi):
  """Stable-Baselines3 DQN on taxi-fuel."""
  name = "taxi_dqn"
  algorithm = "dqn"
  Config = TaxiDQNConfig

