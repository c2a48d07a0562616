"""Agents: every learner-on-a-task behind one interface (`base.Agent`), found by
name in a registry that other packages extend.

    from hpg_mj import agents
    agents.register("my_agent", MyAgent)        # or the entry-point group below
    task = agents.load_task("tasks/my_agent.toml")   # [task] kind = "my_agent"
    agent = agents.build(task, seed=1)
    record = agent.train(1000)
    print(agent.metrics(record))

A package adds agents without any edit to hpg_mj through the entry-point group
`hpg_mj.agents` (in its pyproject.toml:
`[project.entry-points."hpg_mj.agents"] my_agent = "my_pkg.agent:MyAgent"`).

Shipped: ship_hybrid, ship_beyond (past the paper's route, SPEC section 8),
ship_flat_pg, ship_actor_critic, ship_patrol (continuing, SPEC section 8), taxi_hpg,
taxi_maxq, taxi_flat_q (each one module here); and Stable-Baselines3's PPO and SAC on
the ship, PPO and DQN on the taxi (`hpg_mj.agents.sb3`, with the extra
`pip install 'hpg_mj[sb3]'`).
"""
import importlib
import pathlib
import time

import numpy as np

from hpg_mj.agents import storage
from hpg_mj.agents import taskfile
from hpg_mj.agents.base import BACKENDS, POLICIES, Agent  # noqa: F401  (the interface)
from hpg_mj.agents.taskfile import Section, TaskFileError, param, updated  # noqa: F401

def __getattr__(name):
  # The worlds' base classes, for agents of one's own (imported when first asked for).
  if name in ("ShipAgent", "ShipEnvironment"):
    from hpg_mj.agents import _ship
    return getattr(_ship, name)
  if name in ("TaxiAgent", "TaxiEnvironment"):
    from hpg_mj.agents import _taxi
    return getattr(_taxi, name)
  raise AttributeError(f"module 'hpg_mj.agents' has no attribute {name!r}")


ENTRY_POINT_GROUP = "hpg_mj.agents"

_SHIPPED = {
    "ship_hybrid": "hpg_mj.agents.ship_hybrid:ShipHybrid",
    "ship_beyond": "hpg_mj.agents.ship_beyond:ShipBeyond",
    "ship_flat_pg": "hpg_mj.agents.ship_flat_pg:ShipFlatPG",
    "ship_actor_critic": "hpg_mj.agents.ship_actor_critic:ShipActorCritic",
    "ship_patrol": "hpg_mj.agents.ship_patrol:ShipPatrol",
    "taxi_hpg": "hpg_mj.agents.taxi_hpg:TaxiHPG",
    "taxi_maxq": "hpg_mj.agents.taxi_maxq:TaxiMAXQ",
    "taxi_flat_q": "hpg_mj.agents.taxi_flat_q:TaxiFlatQ",
    # Stable-Baselines3's, with the extra `pip install 'hpg_mj[sb3]'` (issue 21)
    "ship_ppo": "hpg_mj.agents.sb3:ShipPPO",
    "ship_sac": "hpg_mj.agents.sb3:ShipSAC",
    "taxi_ppo": "hpg_mj.agents.sb3:TaxiPPO",
    "taxi_dqn": "hpg_mj.agents.sb3:TaxiDQN",
}
_registered = {}          # name -> class, or "module:Class" until first used
_entry_points_read = False


def _check_class(name, cls):
  if not (isinstance(cls, type) and issubclass(cls, Agent)):
    raise TypeError(f"agent {name!r}: {cls!r} is not a subclass of hpg_mj.agents.Agent")
  missing = [a for a in ("Config", "record_fields", "figure") if not getattr(cls, a, None)]
  if missing:
    raise TypeError(f"agent {name!r}: {cls.__name__} does not set {missing} "
                    "(see hpg_mj.agents.base)")


def register(name, cls, replace=False):
  """Makes `cls` (an `Agent` subclass) the agent of task files with `kind = name`."""
  if not isinstance(name, str) or not name.isidentifier():
    raise ValueError(f"agent name {name!r} must be an identifier (letters, digits, _)")
  _read_entry_points()
  if name in _registered and not replace and _registered[name] is not cls:
    raise ValueError(f"agent {name!r} is registered already ({_describe(name)}); pass "
                     "replace=True to replace it")
  _check_class(name, cls)
  if cls.name != name:
    cls.name = name
  _registered[name] = cls
  return cls


def _describe(name):
  entry = _registered[name]
  return entry if isinstance(entry, str) else f"{entry.__module__}:{entry.__qualname__}"


def _read_entry_points():
  global _entry_points_read
  if _entry_points_read:
    return
  _entry_points_read = True
  _registered.update({k: v for k, v in _SHIPPED.items() if k not in _registered})
  from importlib import metadata
  for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
    _registered.setdefault(ep.name, ep.value)


def names():
  """The registered agents' names, sorted."""
  _read_entry_points()
  return sorted(_registered)


def lookup(name):
  """The agent class registered as `name`; an unknown name lists the known ones."""
  _read_entry_points()
  if name not in _registered:
    raise KeyError(f"no agent {name!r} is registered; registered: {names()}")
  entry = _registered[name]
  if isinstance(entry, str):
    module, _, attr = entry.partition(":")
    try:
      cls = getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError) as err:
      raise ImportError(f"agent {name!r}: cannot load {entry!r}: {err}") from err
    _check_class(name, cls)
    cls.name = name
    _registered[name] = entry = cls
  return entry


class _Registry:
  names = staticmethod(names)
  lookup = staticmethod(lookup)


# ---- task files ------------------------------------------------------------------

def shipped_tasks_dirs():
  """The folder of shipped task files: installed, else the checkout's."""
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
  if not pathlib.Path(path).exists() and str(path) in shipped_tasks():
    path = shipped_tasks()[str(path)]
  elif not pathlib.Path(path).exists():
    raise taskfile.TaskFileError(f"{path}: no such task file, and no shipped task of that "
                                 f"name; shipped: {sorted(shipped_tasks())}")
  return taskfile.load(path, _Registry)


def build(task, seed=None):
  """An agent for a loaded task file (seed: the file's unless given)."""
  seed = task.protocol.seed if seed is None else seed
  return lookup(task.kind)(task.config, seed=seed, task=task)


# ---- training in chunks ------------------------------------------------------------

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
    record = agent.train(n, backend)
    done += n
    yield done, record, time.perf_counter() - start


def train(task, episodes=None, seed=None, backend=None, progress=None):
  """Trains a fresh agent; returns (agent, record, wall seconds).

  `progress(done, total, summary)` is called after each chunk of episodes.
  """
  agent = build(task, seed)
  episodes = task.protocol.episodes if episodes is None else episodes
  if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 1:
    raise ValueError(f"episodes must be a positive integer, got {episodes!r}")
  records = []
  start = time.perf_counter()
  for done, record, _ in chunks(agent, episodes, backend):
    records.append(record)
    if progress is not None:
      progress(done, episodes, agent.progress(record))
  return agent, np.concatenate(records), time.perf_counter() - start


# ---- saving and loading --------------------------------------------------------------

def save(agent, directory, record, extra=None, compress=True):
  """Writes the agent's whole state, its record, its task file and what made it
  (`hpg_mj.provenance`) to `directory` (`compress`: see `storage.save`)."""
  from hpg_mj import provenance
  text = agent.task.text if agent.task else None
  meta = {"task_file": str(agent.task.path) if agent.task else None,
          "task_text": text, "seed": agent.seed, "episodes": agent.episodes,
          "provenance": provenance.collect(text, agent.seed)}
  meta.update(extra or {})
  arrays = dict(agent.state())
  arrays["record"] = record
  return storage.save(directory, agent.name, arrays, meta, compress)


def load(directory):
  """Loads a saved agent (and its training record) from `directory`; one made by
  another version of hpg_mj or of its libraries is loaded with a
  `provenance.VersionWarning` that says which."""
  from hpg_mj import provenance
  meta, arrays = storage.load(directory)
  provenance.warn_if_different(meta.get("provenance"), directory)
  kind = meta.get("kind")
  if kind not in names():
    raise storage.AgentFileError(f"{directory}: unknown agent kind {kind!r}; registered: "
                                 f"{names()}")
  path = pathlib.Path(meta.get("task_file") or "task.toml")
  task = taskfile.loads(meta.get("task_text") or "", path, _Registry)
  agent = build(task, meta.get("seed", 0))
  record = arrays.pop("record", None)
  agent.restore(arrays, directory)
  agent.episodes = meta.get("episodes", 0)
  return agent, record, meta
