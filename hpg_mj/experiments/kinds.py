"""The agents a task file can declare (`[task] kind`), with their schemas,
training, evaluation, metrics and saved state."""
import time

import numpy as np

from hpg_mj.baselines import ship_flat
from hpg_mj.experiments import storage
from hpg_mj.experiments import taskfile
from hpg_mj.hierarchy import ship as ship_hierarchy
from hpg_mj.hierarchy import ship_compiled as sc
from hpg_mj.learners import rng
from hpg_mj.worlds import taxi_core

METRIC_WINDOW = 1000   # metrics are over the last 1,000 episodes

BACKENDS = ("analytic", "mujoco")


def _window(record):
  return record[-METRIC_WINDOW:]


_SHIP_ENVIRONMENT = {"world": ("choice", ("ship",)), "backend": ("choice", BACKENDS),
                     "gate_reward": "float", "out_of_bounds_reward": "float",
                     "max_steps": "int"}
_TASK = {"kind": "str", "description": "str"}
_PROTOCOL = {"episodes": "int", "seed": "int"}


def _require(task, checks):
  """Refuses out-of-range values, naming the file and the key."""
  for section, key, ok in checks:
    if not ok:
      raise taskfile.TaskFileError(f"{task.path}: [{section}] {key} = "
                                   f"{task.section(section)[key]!r} is out of range")


class _Kind:
  """What every agent kind shares: `self.agent` holds the learners, its
  generator (`rng_state`) and its count of learning episodes."""

  @property
  def episodes_trained(self):
    return self.agent.episodes

  @episodes_trained.setter
  def episodes_trained(self, value):
    self.agent.episodes = int(value)

  def set_seed(self, seed):
    self.agent.rng_state[:] = rng.make_state(seed)

  def run_with(self, adapter, episodes=1):
    """Greedy episodes through a given environment adapter."""
    return self.agent.train_stepwise(adapter, episodes, learn=False)


class _RecordingAdapter:
  """A Gymnasium adapter that also keeps a rendered frame of every step."""

  def __init__(self, env):
    from hpg_mj.hierarchy import executor
    self._inner = executor.GymAdapter(env)
    self.env = env
    self.frames = []

  def reset(self, start=None):
    obs = self._inner.reset(start)
    self.frames = [self.env.render()]
    return obs

  def step(self, action):
    step = self._inner.step(action)
    self.frames.append(self.env.render())
    return step


def render_agent(agent, path, seed=0, width=640, height=480, fps=None):
  """A video of one greedy episode of a trained agent on the MuJoCo world."""
  import gymnasium

  import hpg_mj  # noqa: F401
  from hpg_mj.render import video
  agent.set_seed(seed)
  if isinstance(agent, _ShipKind):
    env_cfg = agent.task.section("environment")
    env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="mujoco", render_mode="rgb_array",
                         width=width, height=height, max_steps=env_cfg["max_steps"],
                         gate_reward=env_cfg["gate_reward"],
                         out_of_bounds_reward=env_cfg["out_of_bounds_reward"]).unwrapped
    fps = fps or 20
  else:
    env = gymnasium.make("hpg_mj/TaxiFuel-v0" if agent.rules.fuel_enabled else "hpg_mj/Taxi-v0",
                         render_mode="rgb_array", width=width, height=height).unwrapped
    fps = fps or 4
  adapter = _RecordingAdapter(env)
  try:
    record = agent.run_with(adapter)
  finally:
    env.close()
  frames = adapter.frames[::2] if len(adapter.frames) > 400 else adapter.frames
  frames = frames + [frames[-1]] * 10
  return video.write_video(frames, path, fps=fps), record


class _ShipKind(_Kind):
  """What the ship agents share: the environment, backends, seeds and saving."""

  def __init__(self, task, seed):
    env = task.section("environment")
    _require(task, [("environment", "max_steps", env["max_steps"] >= 1)])
    self.task = task
    self.backend = env["backend"]
    self.seed = seed

  def _env(self, backend):
    import gymnasium

    import hpg_mj  # noqa: F401
    from hpg_mj.hierarchy import executor
    env = self.task.section("environment")
    gym_env = gymnasium.make("hpg_mj/ShipSteering-v0", backend=backend,
                             max_steps=env["max_steps"], gate_reward=env["gate_reward"],
                             out_of_bounds_reward=env["out_of_bounds_reward"]).unwrapped
    return executor.GymAdapter(gym_env)

  def run(self, episodes, backend, learn=True, sample=None):
    """Trains (or evaluates) for `episodes`; returns the per-episode record."""
    if backend == "analytic":
      return self.agent.train_compiled(episodes, learn=learn, sample=sample)
    if backend == "mujoco":
      return self.agent.train_stepwise(self._env("mujoco"), episodes, learn=learn, sample=sample)
    raise ValueError(f"unknown backend {backend!r}; valid backends: {list(BACKENDS)}")

  figure = "gate_pass_rate"      # what progress() reports, by its metric's name

  @staticmethod
  def progress(record):
    return {"gate": float(record[:, 0].mean())}



def _gate_metrics(record, passed_col, steps_col, return_col):
  w = _window(record)
  passed = w[:, passed_col] > 0
  return {
      "episodes_measured": int(len(w)),
      "gate_pass_rate": float(passed.mean()),
      "steps_to_gate": float(w[passed, steps_col].mean()) if passed.any() else None,
      "mean_return": float(w[:, return_col].mean()),
      "control_steps": int(record[:, steps_col].sum()),
  }


class ShipHybridKind(_ShipKind):
  """The hierarchical hybrid on ship steering (paper section 5.2)."""

  name = "ship_hybrid"
  schema = {
      "task": _TASK,
      "environment": _SHIP_ENVIRONMENT,
      "root": {"learner": ("choice", ("q_lambda",)), "alpha": "float", "lambda": "float",
               "epsilon": "float", "epsilon_threshold": "float", "epsilon_window": "int",
               "epsilon_every": "int", "epsilon_divisor": "float"},
      "low_level": {"learner": ("choice", ("policy_gradient",)), "alpha": "float",
                    "trace_gamma": "float", "tilings": "int", "tiles": ("int_list", 4),
                    "max_steps": "int"},
      "protocol": _PROTOCOL,
  }

  def __init__(self, task, seed):
    super().__init__(task, seed)
    env, root, low = task.section("environment"), task.section("root"), task.section("low_level")
    _require(task, [("root", "alpha", root["alpha"] > 0), ("root", "lambda", 0 <= root["lambda"] <= 1),
              ("root", "epsilon", 0 <= root["epsilon"] <= 1),
              ("root", "epsilon_divisor", root["epsilon_divisor"] >= 1),
              ("root", "epsilon_window", root["epsilon_window"] >= 1),
              ("root", "epsilon_every", root["epsilon_every"] >= 1),
              ("low_level", "alpha", low["alpha"] > 0),
              ("low_level", "trace_gamma", 0 < low["trace_gamma"] <= 1),
              ("low_level", "tilings", low["tilings"] >= 1),
              ("low_level", "max_steps", low["max_steps"] >= 1)])
    self.config = ship_hierarchy.ShipHybridConfig(
        root_alpha=root["alpha"], root_lambda=root["lambda"], epsilon=root["epsilon"],
        epsilon_threshold=root["epsilon_threshold"], epsilon_window=root["epsilon_window"],
        epsilon_every=root["epsilon_every"], epsilon_divisor=root["epsilon_divisor"],
        low_alpha=low["alpha"], low_gamma=low["trace_gamma"], tilings=low["tilings"],
        tiles=low["tiles"], subtask_max_steps=low["max_steps"],
        episode_max_steps=env["max_steps"], gate_reward=env["gate_reward"],
        out_of_bounds_reward=env["out_of_bounds_reward"])
    self.agent = ship_hierarchy.ShipHybrid(self.config, seed=seed)

  # The agent's whole training state, for saving and exact resumption.
  def arrays(self):
    a = self.agent
    out = {"rng_state": a.rng_state, "root_q": a.root.q, "root_trace_index": a.root.index,
           "root_trace_value": a.root.value, "root_trace_count": a.root.count,
           "epsilon_schedule": a.schedule, "subtask_outcomes": a.outcomes,
           "subtask_counts": a.counts}
    for name, learner in (("diagonal", a.low[0]), ("straight", a.low[1])):
      for key, value in learner.trace.items():
        out[f"{name}_{key}"] = value
    return out

  @staticmethod
  def metrics(record):
    out = _gate_metrics(record, sc.PASSED, sc.STEPS, sc.RETURN)
    w = _window(record)
    diag_runs, str_runs = w[:, sc.DIAG_RUNS].sum(), w[:, sc.STRAIGHT_RUNS].sum()
    out.update({
        "calls_per_episode": float(w[:, sc.CALLS].mean()),
        "diagonal_success_rate": float(w[:, sc.DIAG_SUCCESS].sum() / diag_runs) if diag_runs else None,
        "straight_success_rate": float(w[:, sc.STRAIGHT_SUCCESS].sum() / str_runs) if str_runs else None,
    })
    return out


class ShipFlatPGKind(_ShipKind):
  """Flat policy gradient on the full ship task (SPEC section 4)."""

  name = "ship_flat_pg"
  schema = {
      "task": _TASK,
      "environment": _SHIP_ENVIRONMENT,
      "policy": {"learner": ("choice", ("policy_gradient",)), "alpha": "float",
                 "trace_gamma": "float", "tilings": "int", "tiles": ("int_list", 4)},
      "protocol": _PROTOCOL,
  }

  def __init__(self, task, seed):
    super().__init__(task, seed)
    env, pol = task.section("environment"), task.section("policy")
    _require(task, [("policy", "alpha", pol["alpha"] > 0),
                    ("policy", "trace_gamma", 0 < pol["trace_gamma"] <= 1),
                    ("policy", "tilings", pol["tilings"] >= 1)])
    self.agent = ship_flat.FlatPolicyGradient(
        alpha=pol["alpha"], trace_gamma=pol["trace_gamma"], tilings=pol["tilings"],
        tiles=pol["tiles"], seed=seed, max_steps=env["max_steps"],
        gate_reward=env["gate_reward"], out_of_bounds_reward=env["out_of_bounds_reward"])

  def arrays(self):
    out = {"rng_state": self.agent.rng_state}
    out.update({f"policy_{k}": v for k, v in self.agent.learner.trace.items()})
    return out

  @staticmethod
  def metrics(record):
    return _gate_metrics(record, ship_flat.PASSED, ship_flat.STEPS, ship_flat.RETURN)


class ShipActorCriticKind(_ShipKind):
  """Konda's actor-critic on the full ship task (SPEC section 4)."""

  name = "ship_actor_critic"
  schema = {
      "task": _TASK,
      "environment": _SHIP_ENVIRONMENT,
      "actor": {"learner": ("choice", ("policy_gradient",)), "alpha": "float", "tilings": "int",
                "tiles": ("int_list", 4)},
      "critic": {"learner": ("choice", ("td_lambda",)), "alpha": "float", "lambda": "float",
                 "tilings": "int", "tiles": ("int_list", 5)},
      "protocol": _PROTOCOL,
  }

  def __init__(self, task, seed):
    super().__init__(task, seed)
    env, actor, critic = task.section("environment"), task.section("actor"), task.section("critic")
    _require(task, [("actor", "alpha", actor["alpha"] > 0), ("critic", "alpha", critic["alpha"] > 0),
                    ("critic", "lambda", 0 < critic["lambda"] <= 1),
                    ("actor", "tilings", actor["tilings"] >= 1),
                    ("critic", "tilings", critic["tilings"] >= 1)])
    self.agent = ship_flat.ActorCriticAgent(
        alpha_actor=actor["alpha"], alpha_critic=critic["alpha"], lam=critic["lambda"],
        actor_tilings=actor["tilings"], actor_tiles=actor["tiles"],
        critic_tilings=critic["tilings"], critic_tiles=critic["tiles"], seed=seed,
        max_steps=env["max_steps"], gate_reward=env["gate_reward"],
        out_of_bounds_reward=env["out_of_bounds_reward"])

  def arrays(self):
    lr = self.agent.learner
    out = {"rng_state": self.agent.rng_state, "actor_w": lr.actor_w}
    out.update({f"critic_{k}": v for k, v in lr.critic.items()})
    return out

  @staticmethod
  def metrics(record):
    return _gate_metrics(record, ship_flat.PASSED, ship_flat.STEPS, ship_flat.RETURN)


_TAXI_ENVIRONMENT = {"world": ("choice", ("taxi",)), "backend": ("choice", BACKENDS),
                     "fuel": "bool", "capacity": "int", "max_steps": "int"}


class _TaxiKind(_Kind):
  """What the taxi agents share. Backend "analytic" is the compiled loop over the
  taxi rules; "mujoco" steps through the dm_control taxi (the MJCF board)."""

  def __init__(self, task, seed):
    env = task.section("environment")
    _require(task, [("environment", "capacity", env["capacity"] >= 1),
                    ("environment", "max_steps", env["max_steps"] >= 1)])
    self.task = task
    self.backend = env["backend"]
    self.seed = seed
    self.rules = taxi_core.TaxiRules(env["fuel"], capacity=env["capacity"],
                                     max_steps=env["max_steps"])
    self._optimal = None

  def _adapter(self):
    from hpg_mj import suite
    from hpg_mj.hierarchy import executor
    kwargs = {"random": 0, "max_steps": self.rules.max_steps}
    if self.rules.fuel_enabled:
      kwargs["capacity"] = self.rules.capacity
    env = suite.load("taxi", "fuel" if self.rules.fuel_enabled else "classic", kwargs)
    return executor.DmControlAdapter(env)

  figure = "mean_return"         # what progress() reports, by its metric's name

  @staticmethod
  def progress(record):
    return {"return": float(record[:, 0].mean())}

  def optimal_mean_return(self):
    if self._optimal is None:
      from hpg_mj.worlds import taxi_values
      self._optimal = taxi_values.optimal_mean_return(self.rules.fuel_enabled,
                                                      capacity=self.rules.capacity)
    return self._optimal

  def metrics(self, record):
    from hpg_mj.worlds import taxi_values
    w = _window(record)
    optimal = self.optimal_mean_return()
    mean = float(w[:, 0].mean())
    return {"episodes_measured": int(len(w)), "mean_return": mean,
            "optimal_mean_return": optimal,
            "reaches_95_percent": bool(mean >= taxi_values.performance_threshold(optimal, 0.95)),
            "primitive_steps": int(record[:, 1].sum())}



def _level():
  return {"learner": ("choice", ("policy_gradient",)), "alpha": "float",
          "start_fraction": "float", "delay": "int", "ramp": "int", "trace_gamma": "float",
          "baseline": "float"}


class TaxiHPGKind(_TaxiKind):
  """Tabular HPG (Algorithm 1) on taxi-fuel (paper section 5.1)."""

  name = "taxi_hpg"
  schema = {"task": _TASK, "environment": _TAXI_ENVIRONMENT, "root": _level(),
            "carry": _level(), "navigate": _level(), "protocol": _PROTOCOL}

  def __init__(self, task, seed):
    super().__init__(task, seed)
    from hpg_mj.hierarchy import taxi_compiled
    kwargs = {}
    checks = []
    for level in ("root", "carry", "navigate"):
      sec = task.section(level)
      checks += [(level, "alpha", sec["alpha"] >= 0),
                 (level, "start_fraction", 0 <= sec["start_fraction"] <= 1),
                 (level, "delay", sec["delay"] >= 0), (level, "ramp", sec["ramp"] >= 1),
                 (level, "trace_gamma", 0 < sec["trace_gamma"] <= 1),
                 (level, "baseline", 0 <= sec["baseline"] <= 1)]
      kwargs.update({f"alpha_{level}": sec["alpha"], f"start_{level}": sec["start_fraction"],
                     f"delay_{level}": sec["delay"], f"ramp_{level}": sec["ramp"],
                     f"gamma_{level}": sec["trace_gamma"], f"baseline_{level}": sec["baseline"]})
    _require(task, checks)
    self.agent = taxi_compiled.TaxiHPG(seed=seed, config=taxi_compiled.HPGConfig(**kwargs),
                                       task=self.rules)

  def arrays(self):
    out = {"rng_state": self.agent.rng_state}
    names = ("root", "get", "put", "refuel", "navigate")
    for name, trace, values in zip(names, self.agent.traces, self.agent.values):
      out.update({f"{name}_{k}": v for k, v in zip(
          ("w", "zs", "y", "touched", "marked", "count", "acc"), trace)})
      out[f"{name}_baseline"] = values
    return out

  def run_with(self, adapter, episodes=1):
    """Greedy episodes through a given taxi environment adapter."""
    from hpg_mj.hierarchy import taxi as taxi_hierarchy
    return taxi_hierarchy.TaxiHierarchy(self.agent).train_stepwise(adapter, episodes,
                                                                  learn=False)

  def run(self, episodes, backend, learn=True, sample=None):
    if backend == "analytic":
      return self.agent.run(episodes, learn=learn, greedy=not learn and not sample)
    if backend == "mujoco":
      from hpg_mj.hierarchy import taxi as taxi_hierarchy
      return taxi_hierarchy.TaxiHierarchy(self.agent).train_stepwise(
          self._adapter(), episodes, learn=learn, sample=sample)
    raise ValueError(f"unknown backend {backend!r}; valid backends: {list(BACKENDS)}")


class TaxiFlatQKind(_TaxiKind):
  """Flat Q-learning on taxi-fuel over the full state (SPEC section 5)."""

  name = "taxi_flat_q"
  schema = {"task": _TASK, "environment": _TAXI_ENVIRONMENT,
            "policy": {"learner": ("choice", ("q_learning",)), "alpha": "float",
                       "epsilon_start": "float", "epsilon_end": "float",
                       "epsilon_episodes": "int", "initial": "float"},
            "protocol": _PROTOCOL}

  def __init__(self, task, seed):
    super().__init__(task, seed)
    from hpg_mj.baselines import taxi_flat_q
    pol = task.section("policy")
    _require(task, [("policy", "alpha", 0 < pol["alpha"] <= 1),
                    ("policy", "epsilon_start", 0 <= pol["epsilon_start"] <= 1),
                    ("policy", "epsilon_end", 0 <= pol["epsilon_end"] <= 1),
                    ("policy", "epsilon_episodes", pol["epsilon_episodes"] >= 0)])
    self.agent = taxi_flat_q.FlatQ(pol["alpha"], pol["epsilon_start"], pol["epsilon_end"],
                                   pol["epsilon_episodes"], pol["initial"], seed=seed,
                                   task=self.rules)

  def arrays(self):
    lr = self.agent.learner
    return {"rng_state": self.agent.rng_state, "q": lr.q, "trace_index": lr.index,
            "trace_value": lr.value, "trace_count": lr.count}

  def run(self, episodes, backend, learn=True, sample=None):
    if backend == "analytic":
      return self.agent.train_compiled(episodes, learn=learn, sample=sample)
    if backend == "mujoco":
      return self.agent.train_stepwise(self._adapter(), episodes, learn=learn, sample=sample)
    raise ValueError(f"unknown backend {backend!r}; valid backends: {list(BACKENDS)}")


def _maxq_level(pseudo_reward=True):
  keys = {"learner": ("choice", ("maxq_q",)), "alpha": "float", "epsilon": "float",
          "epsilon_episodes": "int", "initial": "float"}
  if pseudo_reward:
    keys["pseudo_reward"] = "float"
  return keys


class TaxiMAXQKind(_TaxiKind):
  """MAXQ-Q (Dietterich 2000) on taxi-fuel over the task graph of SPEC section 5."""

  name = "taxi_maxq"
  schema = {"task": _TASK, "environment": _TAXI_ENVIRONMENT,
            "root": _maxq_level(pseudo_reward=False), "carry": _maxq_level(),
            "navigate": _maxq_level(),
            "primitive": {"alpha": "float", "all_states_updating": "bool"},
            "protocol": _PROTOCOL}

  def __init__(self, task, seed):
    super().__init__(task, seed)
    from hpg_mj.baselines import taxi_maxq
    kwargs, checks = {}, []
    for level in ("root", "carry", "navigate"):
      sec = task.section(level)
      checks += [(level, "alpha", 0 < sec["alpha"] <= 1),
                 (level, "epsilon", 0 <= sec["epsilon"] <= 1),
                 (level, "epsilon_episodes", sec["epsilon_episodes"] >= 0)]
      kwargs.update({f"alpha_{level}": sec["alpha"], f"epsilon_{level}": sec["epsilon"],
                     f"epsilon_episodes_{level}": sec["epsilon_episodes"],
                     f"initial_{level}": sec["initial"]})
      if level != "root":
        kwargs[f"pseudo_reward_{level}"] = sec["pseudo_reward"]
    prim = task.section("primitive")
    checks.append(("primitive", "alpha", 0 < prim["alpha"] <= 1))
    _require(task, checks)
    config = taxi_maxq.MAXQConfig(alpha_primitive=prim["alpha"],
                                  all_states=prim["all_states_updating"], **kwargs)
    self.agent = taxi_maxq.TaxiMAXQ(seed=seed, config=config, task=self.rules)

  def arrays(self):
    a = self.agent
    return {"rng_state": a.rng_state, "primitive_values": a.values,
            "completions_pseudo": a.c_tilde, "completions": a.c}

  def _graph(self):
    from hpg_mj.hierarchy import taxi_maxq as taxi_maxq_graph
    return taxi_maxq_graph.TaxiMAXQHierarchy(self.agent)

  def run_with(self, adapter, episodes=1):
    """Greedy episodes through a given taxi environment adapter."""
    return self._graph().train_stepwise(adapter, episodes, learn=False)

  def run(self, episodes, backend, learn=True, sample=None):
    if backend == "analytic":
      return self.agent.run(episodes, learn=learn, sample=sample)
    if backend == "mujoco":
      return self._graph().train_stepwise(self._adapter(), episodes, learn=learn, sample=sample)
    raise ValueError(f"unknown backend {backend!r}; valid backends: {list(BACKENDS)}")


KINDS = {k.name: k for k in (ShipHybridKind, ShipFlatPGKind, ShipActorCriticKind, TaxiHPGKind,
                             TaxiFlatQKind, TaxiMAXQKind)}


def schemas():
  return {name: kind.schema for name, kind in KINDS.items()}


def shipped_tasks_dirs():
  """The folder of shipped task files: installed, else the checkout's."""
  import pathlib
  here = pathlib.Path(__file__).resolve().parents[1]
  for folder in (here / "tasks", here.parent / "tasks"):
    if folder.is_dir():
      return [folder]
  return []


def shipped_tasks():
  """The task files that come with hpg_mj, by name (e.g. "ship_hybrid")."""
  return {p.stem: p for folder in shipped_tasks_dirs() for p in sorted(folder.glob("*.toml"))}


def load_task(path):
  """Loads a task file by path, or a shipped one by name (`ship_hybrid`)."""
  import pathlib
  if not pathlib.Path(path).exists() and str(path) in shipped_tasks():
    path = shipped_tasks()[str(path)]
  elif not pathlib.Path(path).exists():
    raise taskfile.TaskFileError(f"{path}: no such task file, and no shipped task of that "
                                 f"name; shipped: {sorted(shipped_tasks())}")
  return taskfile.load(path, schemas())


def build(task, seed=None):
  """An agent for a loaded task file (seed: the file's unless given)."""
  seed = task.section("protocol")["seed"] if seed is None else seed
  return KINDS[task.kind](task, seed)


CHUNK = 1000          # episodes per chunk of training (50 through MuJoCo)


def chunks(agent, episodes, backend=None, done=0, every=None):
  """Trains `agent` from episode `done` to `episodes` in chunks that never cross
  a multiple of `every`; yields (episodes done, the chunk's record, its seconds)."""
  backend = backend or agent.backend
  chunk = min(CHUNK, 50) if backend == "mujoco" else CHUNK
  while done < episodes:
    n = min(chunk, episodes - done)
    if every:
      n = min(n, every - done % every)
    start = time.perf_counter()
    record = agent.run(n, backend)
    done += n
    yield done, record, time.perf_counter() - start


def train(task, episodes=None, seed=None, backend=None, progress=None):
  """Trains a fresh agent; returns (agent, record, wall seconds).

  `progress(done, total, summary)` is called after each chunk of episodes.
  """
  agent = build(task, seed)
  episodes = task.section("protocol")["episodes"] if episodes is None else episodes
  if episodes < 1:
    raise ValueError(f"episodes must be positive, got {episodes}")
  records = []
  start = time.perf_counter()
  for done, record, _ in chunks(agent, episodes, backend):
    records.append(record)
    if progress is not None:
      progress(done, episodes, agent.progress(record))
  return agent, np.concatenate(records), time.perf_counter() - start


def save(agent, directory, record, extra=None):
  meta = {"task_file": str(agent.task.path), "task_text": agent.task.text,
          "seed": agent.seed, "episodes": agent.episodes_trained}
  meta.update(extra or {})
  arrays = dict(agent.arrays())
  arrays["record"] = record
  return storage.save(directory, agent.name, arrays, meta)


def load(directory):
  """Loads a saved agent (and its training record) from `directory`."""
  import pathlib
  import tempfile
  meta, arrays = storage.load(directory)
  kind = meta.get("kind")
  if kind not in KINDS:
    raise storage.AgentFileError(f"{directory}: unknown agent kind {kind!r}; known: "
                                 f"{sorted(KINDS)}")
  with tempfile.TemporaryDirectory() as tmp:
    path = pathlib.Path(tmp) / pathlib.Path(meta.get("task_file", "task.toml")).name
    path.write_text(meta.get("task_text", ""))
    task = taskfile.load(path, schemas())
  agent = KINDS[kind](task, meta.get("seed", 0))
  record = arrays.pop("record", None)
  storage.restore_into(agent.arrays(), arrays, directory)
  agent.episodes_trained = meta.get("episodes", 0)
  return agent, record, meta
