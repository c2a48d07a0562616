"""The agents a task file can declare (`[task] kind`), with their schemas,
training, evaluation, metrics and saved state."""
import time

import numpy as np

from hpg_mj.experiments import storage
from hpg_mj.experiments import taskfile
from hpg_mj.hierarchy import ship as ship_hierarchy
from hpg_mj.hierarchy import ship_compiled as sc
from hpg_mj.learners import rng

METRIC_WINDOW = 1000   # metrics are over the last 1,000 episodes

BACKENDS = ("analytic", "mujoco")


def _window(record):
  return record[-METRIC_WINDOW:]


class ShipHybridKind:
  """The hierarchical hybrid on ship steering (paper section 5.2)."""

  name = "ship_hybrid"
  schema = {
      "task": {"kind": "str", "description": "str"},
      "environment": {"world": ("choice", ("ship",)), "backend": ("choice", BACKENDS),
                      "gate_reward": "float", "out_of_bounds_reward": "float",
                      "max_steps": "int"},
      "root": {"learner": ("choice", ("q_lambda",)), "alpha": "float", "lambda": "float",
               "epsilon": "float", "epsilon_threshold": "float", "epsilon_window": "int",
               "epsilon_every": "int", "epsilon_divisor": "float"},
      "low_level": {"learner": ("choice", ("policy_gradient",)), "alpha": "float",
                    "trace_gamma": "float", "tilings": "int", "tiles": ("int_list", 4),
                    "max_steps": "int"},
      "protocol": {"episodes": "int", "seed": "int"},
  }

  def __init__(self, task, seed):
    env, root, low = task.section("environment"), task.section("root"), task.section("low_level")
    checks = [("root", "alpha", root["alpha"] > 0), ("root", "lambda", 0 <= root["lambda"] <= 1),
              ("root", "epsilon", 0 <= root["epsilon"] <= 1),
              ("root", "epsilon_divisor", root["epsilon_divisor"] >= 1),
              ("root", "epsilon_window", root["epsilon_window"] >= 1),
              ("root", "epsilon_every", root["epsilon_every"] >= 1),
              ("low_level", "alpha", low["alpha"] > 0),
              ("low_level", "trace_gamma", 0 < low["trace_gamma"] <= 1),
              ("low_level", "tilings", low["tilings"] >= 1),
              ("low_level", "max_steps", low["max_steps"] >= 1),
              ("environment", "max_steps", env["max_steps"] >= 1)]
    for section, key, ok in checks:
      if not ok:
        raise taskfile.TaskFileError(f"{task.path}: [{section}] {key} = "
                                     f"{task.section(section)[key]!r} is out of range")
    self.task = task
    self.backend = env["backend"]
    self.config = ship_hierarchy.ShipHybridConfig(
        root_alpha=root["alpha"], root_lambda=root["lambda"], epsilon=root["epsilon"],
        epsilon_threshold=root["epsilon_threshold"], epsilon_window=root["epsilon_window"],
        epsilon_every=root["epsilon_every"], epsilon_divisor=root["epsilon_divisor"],
        low_alpha=low["alpha"], low_gamma=low["trace_gamma"], tilings=low["tilings"],
        tiles=low["tiles"], subtask_max_steps=low["max_steps"],
        episode_max_steps=env["max_steps"], gate_reward=env["gate_reward"],
        out_of_bounds_reward=env["out_of_bounds_reward"])
    self.agent = ship_hierarchy.ShipHybrid(self.config, seed=seed)
    self.seed = seed

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

  @property
  def episodes_trained(self):
    return self.agent.episodes

  @episodes_trained.setter
  def episodes_trained(self, value):
    self.agent.episodes = int(value)

  def _env(self, backend):
    import gymnasium

    import hpg_mj  # noqa: F401
    from hpg_mj.hierarchy import executor
    c = self.config
    env = gymnasium.make("hpg_mj/ShipSteering-v0", backend=backend, max_steps=c.episode_max_steps,
                         gate_reward=c.gate_reward,
                         out_of_bounds_reward=c.out_of_bounds_reward).unwrapped
    return executor.GymAdapter(env)

  def run(self, episodes, backend, learn=True, sample=None):
    """Trains (or evaluates) for `episodes`; returns the per-episode record."""
    if backend == "analytic":
      return self.agent.train_compiled(episodes, learn=learn, sample=sample)
    if backend == "mujoco":
      return self.agent.train_stepwise(self._env("mujoco"), episodes, learn=learn, sample=sample)
    raise ValueError(f"unknown backend {backend!r}; valid backends: {list(BACKENDS)}")

  @staticmethod
  def progress(record):
    return {"gate": float(record[:, sc.PASSED].mean())}

  @staticmethod
  def metrics(record):
    w = _window(record)
    passed = w[:, sc.PASSED] > 0
    diag_runs, str_runs = w[:, sc.DIAG_RUNS].sum(), w[:, sc.STRAIGHT_RUNS].sum()
    return {
        "episodes_measured": int(len(w)),
        "gate_pass_rate": float(passed.mean()),
        "steps_to_gate": float(w[passed, sc.STEPS].mean()) if passed.any() else None,
        "calls_per_episode": float(w[:, sc.CALLS].mean()),
        "diagonal_success_rate": float(w[:, sc.DIAG_SUCCESS].sum() / diag_runs) if diag_runs else None,
        "straight_success_rate": float(w[:, sc.STRAIGHT_SUCCESS].sum() / str_runs) if str_runs else None,
        "mean_return": float(w[:, sc.RETURN].mean()),
        "control_steps": int(record[:, sc.STEPS].sum()),
    }

  def set_seed(self, seed):
    self.agent.rng_state[:] = rng.make_state(seed)


KINDS = {k.name: k for k in (ShipHybridKind,)}


def schemas():
  return {name: kind.schema for name, kind in KINDS.items()}


def load_task(path):
  return taskfile.load(path, schemas())


def build(task, seed=None):
  """An agent for a loaded task file (seed: the file's unless given)."""
  seed = task.section("protocol")["seed"] if seed is None else seed
  return KINDS[task.kind](task, seed)


def train(task, episodes=None, seed=None, backend=None, progress=None, chunk=1000):
  """Trains a fresh agent; returns (agent, record, wall seconds).

  `progress(done, total, summary)` is called after each chunk of episodes.
  """
  agent = build(task, seed)
  episodes = task.section("protocol")["episodes"] if episodes is None else episodes
  if episodes < 1:
    raise ValueError(f"episodes must be positive, got {episodes}")
  backend = backend or agent.backend
  records = []
  start = time.perf_counter()
  done = 0
  if backend == "mujoco":
    chunk = min(chunk, 50)
  while done < episodes:
    n = min(chunk, episodes - done)
    records.append(agent.run(n, backend))
    done += n
    if progress is not None:
      progress(done, episodes, agent.progress(records[-1]))
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
