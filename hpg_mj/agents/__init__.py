"""Agents: every learner-on-a-task behind one interface (`base.Agent`), found by
name in a registry that other packages extend.

```python
from hpg_mj import agents
agents.register("my_agent", MyAgent)        # or the entry-point group below
task = agents.load_task("tasks/my_agent.toml")   # [task] kind = "my_agent"
agent = agents.build(task, seed=1)
record = agent.train(1000)
print(agent.metrics(record))
```

An agent of one's own is found in three ways, none of which edits hpg_mj: a task
file names its class by import path (`[task] kind = "my_pkg.agents:MyAgent"`); a
module that calls `register` is imported first (`hpg-mj --import my_pkg.agents ...`,
or `import_module`); or an installed package lists it in the entry-point group
`hpg_mj.agents` (in its pyproject.toml:
`[project.entry-points."hpg_mj.agents"] my_agent = "my_pkg.agents:MyAgent"`). A
saved agent records its class's import path, so another process finds it too.

Shipped: ship_hybrid, ship_beyond (past the paper's route, SPEC section 8),
ship_flat_pg, ship_actor_critic, ship_patrol (continuing, SPEC section 8), the hybrid,
flat PGRL and the option-critic on the task ladder (ship_ladder_hybrid,
ship_ladder_flat_pg, ship_ladder_option_critic: SPEC section 11, the task and level
named by the task file) and the waypoints (ship_ladder_waypoints, a parameterized
subtask, on the regatta, the goal and the current), taxi_hpg, taxi_maxq, taxi_flat_q,
the learned hierarchies ship_option_critic and taxi_option_critic (each one module
here); PPO and DQN in JAX (jax_ppo, jax_dqn, with `hpg_mj[jax]`; PPO on the task ladder
too, jax_ppo_ladder); and Stable-Baselines3's PPO and SAC on the ship, PPO and DQN on
the taxi (`hpg_mj.agents.sb3`, with the extra `pip install 'hpg_mj[sb3]'`).
"""
import importlib
import importlib.util
import pathlib
import sys
import time
import warnings

import numpy as np

from hpg_mj import storage
from hpg_mj import taskfile
from hpg_mj.agents.base import BACKENDS, POLICIES, Agent  # noqa: F401  (the interface)
from hpg_mj.taskfile import Section, TaskFileError, param, updated  # noqa: F401

def __getattr__(name):
  # The worlds' base classes, for agents of one's own (imported when first asked for).
  if name in ("ShipAgent", "ShipEnvironment"):
    from hpg_mj.agents import _ship
    return getattr(_ship, name)
  if name in ("ShipHierarchy", "HierarchyConfig", "TaxiHierarchy", "TaxiHierarchyConfig",
              "ShipLadderHierarchy", "LadderHierarchyConfig"):
    from hpg_mj.agents import hierarchy
    return getattr(hierarchy, name)
  if name == "LadderEnvironment":
    from hpg_mj.agents import _ladder
    return _ladder.LadderEnvironment
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
    "ship_option_critic": "hpg_mj.agents.ship_option_critic:ShipOptionCritic",
    "ship_patrol": "hpg_mj.agents.ship_patrol:ShipPatrol",
    # the task ladder's (SPEC section 11): each task and level named by its task file
    "ship_ladder_hybrid": "hpg_mj.agents.ship_ladder_hybrid:ShipLadderHybrid",
    "ship_ladder_flat_pg": "hpg_mj.agents.ship_ladder_flat_pg:ShipLadderFlatPG",
    "ship_ladder_option_critic":
        "hpg_mj.agents.ship_ladder_option_critic:ShipLadderOptionCritic",
    "ship_ladder_waypoints": "hpg_mj.agents.ship_ladder_waypoints:ShipLadderWaypoints",
    "taxi_hpg": "hpg_mj.agents.taxi_hpg:TaxiHPG",
    "taxi_maxq": "hpg_mj.agents.taxi_maxq:TaxiMAXQ",
    "taxi_flat_q": "hpg_mj.agents.taxi_flat_q:TaxiFlatQ",
    "taxi_option_critic": "hpg_mj.agents.taxi_option_critic:TaxiOptionCritic",
    # Stable-Baselines3's, with the extra `pip install 'hpg_mj[sb3]'`
    "ship_ppo": "hpg_mj.agents.sb3:ShipPPO",
    "ship_sac": "hpg_mj.agents.sb3:ShipSAC",
    "taxi_ppo": "hpg_mj.agents.sb3:TaxiPPO",
    "taxi_dqn": "hpg_mj.agents.sb3:TaxiDQN",
    # PPO, DQN and SAC in JAX, trained in one compiled loop, with the extra
    # `pip install 'hpg_mj[jax]'`
    "ship_ppo_jax": "hpg_mj.agents.jax_ppo:ShipPPOJax",
    "taxi_ppo_jax": "hpg_mj.agents.jax_ppo:TaxiPPOJax",
    "taxi_dqn_jax": "hpg_mj.agents.jax_dqn:TaxiDQNJax",
    "ship_sac_jax": "hpg_mj.agents.jax_sac:ShipSACJax",
    # PPO and SAC in JAX on the task ladder's JAX worlds, the task and level named by the file
    "ladder_ppo_jax": "hpg_mj.agents.jax_ppo_ladder:LadderPPOJax",
    "ladder_sac_jax": "hpg_mj.agents.jax_ppo_ladder:LadderSACJax",
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
  """The agent class registered as `name`, or at the import path `name`
  ("module:Class"); an unknown name lists the known ones."""
  _read_entry_points()
  if isinstance(name, str) and ":" in name and name not in _registered:
    _registered[name] = name             # imported, checked and named below
  if name not in _registered:
    raise KeyError(f"no agent {name!r} is registered; registered: {names()}")
  entry = _registered[name]
  if isinstance(entry, str):
    try:
      cls = _import_class(entry)
      _check_class(name, cls)
    except (AgentNotFound, TypeError) as err:
      if entry == name:                  # an import path that finds no agent
        del _registered[name]
      named = entry == name or isinstance(err, TypeError)   # the message names it already
      raise AgentNotFound(str(err) if named else f"agent {name!r}: {err}") from None
    cls.name = name
    _registered[name] = entry = cls
  return entry


class AgentNotFound(taskfile.TaskFileError):
  """A user's agent module or class that cannot be imported; the message says why."""


# The three ways to a user's agent, for the errors that find none.
HOW_TO_ADD = ("or a class by its import path 'module:Class' (e.g. "
              "'my_pkg.agents:MyAgent'); a name is registered by a module that calls "
              "hpg_mj.agents.register, imported first with `hpg-mj --import MODULE`, or by an "
              f"installed package's entry-point group {ENTRY_POINT_GROUP!r}")


def _user_path():
  """sys.path with the current folder first, as `python -m` searches it."""
  import contextlib
  import os
  import sys

  @contextlib.contextmanager
  def searching():
    cwd = os.getcwd()
    added = cwd not in sys.path
    if added:
      sys.path.insert(0, cwd)
    try:
      yield
    finally:
      if added and cwd in sys.path:
        sys.path.remove(cwd)
  return searching()


def import_module(name):
  """Imports a user's module that registers agents (`hpg-mj --import MODULE`):
  a dotted module name, searched in the current folder and on sys.path, or a
  `.py` file's path. Refused with one line (AgentNotFound) when it cannot be."""
  import sys
  what = f"--import {name}"
  if not name.endswith(".py"):
    return _import(name, what)
  path = pathlib.Path(name)
  if not path.is_file():
    raise AgentNotFound(f"{what}: no such file")
  if not path.stem.isidentifier() or path.stem in sys.modules:    # never shadow a module
    raise AgentNotFound(f"{what}: its module name {path.stem!r} is not an identifier or is "
                        f"taken by a module imported already; rename the file")
  spec = importlib.util.spec_from_file_location(path.stem, path)
  module = importlib.util.module_from_spec(spec)
  sys.modules[path.stem] = module
  try:
    spec.loader.exec_module(module)
  except Exception as err:  # noqa: BLE001  (a user's module may raise anything)
    del sys.modules[path.stem]
    raise AgentNotFound(f"{what}: {import_error(err)}") from None
  return module


def _import(module_name, what):
  """A user's module, searched in the current folder and on sys.path; else
  AgentNotFound, `what` naming where it was asked for."""
  try:
    with _user_path():
      return importlib.import_module(module_name)
  except ModuleNotFoundError as err:
    if err.name and (module_name + ".").startswith(err.name + "."):
      raise AgentNotFound(f"{what}: no module {err.name!r} in the current folder or on "
                          f"sys.path: run from the folder that holds "
                          f"{err.name.replace('.', '/')}.py, or put that folder on PYTHONPATH"
                          ) from None
    raise AgentNotFound(f"{what}: {import_error(err)}") from None
  except Exception as err:  # noqa: BLE001  (a user's module may raise anything)
    raise AgentNotFound(f"{what}: {import_error(err)}") from None


def import_error(err):
  """'importing it raised NameError: ... (file.py, line 3)': one line on a failed import."""
  import traceback
  where = traceback.extract_tb(err.__traceback__)
  at = f" ({where[-1].filename}, line {where[-1].lineno})" if where else ""
  text = " ".join(str(err).split())
  return f"importing it raised {type(err).__name__}: {text}{at}"


def _import_class(spec):
  """The object at an import path "module:Class" (the module searched in the
  current folder and on sys.path), or AgentNotFound naming the path."""
  module_name, _, attr = spec.partition(":")
  if not module_name or not attr or not all(p.isidentifier() for p in
                                            module_name.split(".") + attr.split(".")):
    raise AgentNotFound(f"{spec!r} is not an import path 'module:Class' (e.g. "
                        f"'my_pkg.agents:MyAgent')")
  obj = _import(module_name, repr(spec))
  for part in attr.split("."):
    if not hasattr(obj, part):
      raise AgentNotFound(f"{spec!r}: module {module_name!r} has no {attr!r}")
    obj = getattr(obj, part)
  return obj


def class_path(cls):
  """The import path "module:Class" that finds `cls` in another process."""
  return f"{cls.__module__}:{cls.__qualname__}"


class _Registry:
  names = staticmethod(names)
  lookup = staticmethod(lookup)
  how_to_add = HOW_TO_ADD


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


def load_task(path, assignments=()):
  """Loads a task file by path, or a shipped one by name (`ship_hybrid`), with keys set
  by `assignments` ("section.key=value" each, `taskfile.assigned`; `hpg-mj train --set`)."""
  if not pathlib.Path(path).exists() and str(path) in shipped_tasks():
    path = shipped_tasks()[str(path)]
  elif not pathlib.Path(path).exists():
    import difflib
    close = difflib.get_close_matches(str(path), shipped_tasks(), n=1)
    hint = f"did you mean {close[0]!r}? " if close else ""
    raise taskfile.TaskFileError(f"{path}: no such task file, and no shipped task of that "
                                 f"name; {hint}shipped: {sorted(shipped_tasks())}")
  task = taskfile.load(path, _Registry)
  return taskfile.assigned(task, assignments, _Registry) if assignments else task


def build(task, seed=None):
  """An agent for a loaded task file (seed: the file's unless given)."""
  seed = task.protocol.seed if seed is None else seed
  cls = lookup(task.kind)
  try:
    return cls(task.config, seed=seed, task=task)
  except ValueError as err:      # a world's own limit (e.g. the taxi's capacity): name the file
    raise taskfile.TaskFileError(f"{task.path}: {err}") from None


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

  The seconds include the first call's compile (numba's or XLA's, where no cache
  holds it); `hpg-mj train --json` and `hpg-mj bench train` give training apart from
  compiling. `progress(done, total, summary)` is called after each chunk of episodes.
  """
  agent = build(task, seed)
  episodes = task.protocol.episodes if episodes is None else episodes
  return (agent,) + train_further(agent, episodes, backend, progress)


def train_further(agent, episodes, backend=None, progress=None):
  """Trains `agent` (a fresh one, or one loaded from its folder: it goes on from its
  generator and learners as a run never stopped would) `episodes` more; returns (the
  record of these episodes alone, wall seconds, compiling included). `progress` as
  `train`'s."""
  if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 1:
    raise ValueError(f"episodes must be a positive integer, got {episodes!r}")
  records = []
  start = time.perf_counter()
  for done, record, _ in chunks(agent, episodes, backend):
    records.append(record)
    if progress is not None:
      progress(done, episodes, agent.progress(record))
  return np.concatenate(records), time.perf_counter() - start


# ---- saving and loading --------------------------------------------------------------

def _find_saved_class(kind, spec, directory):
  """Registers a saved agent's class as `kind`, found by its recorded import path
  `spec` (whose module may register it itself); refuses when it cannot be."""
  where = f"{directory}: agent kind {kind!r} is not registered here"
  if not isinstance(kind, str) or not (kind.isidentifier() or kind == spec):
    raise storage.AgentFileError(f"{where}; registered: {names()}")
  if not isinstance(spec, str) or spec.startswith("__main__:"):
    made = ("it was saved from a class defined in a script (__main__), which another "
            "process cannot import" if isinstance(spec, str) else "it records no class")
    raise storage.AgentFileError(f"{where}; {made}: put the class in a module and give "
                                 f"[task] kind as 'module:Class', or {HOW_TO_ADD[3:]}")
  try:
    cls = _import_class(spec)
  except AgentNotFound as err:
    raise storage.AgentFileError(f"{where}, and its class cannot be imported: {err}") from None
  if kind not in names():                # its module did not register it: register it here
    try:
      register(kind, cls)
    except (TypeError, ValueError) as err:
      raise storage.AgentFileError(f"{where}: {err}") from None


def _class_file(agent):
  """The file of the module that holds the agent's class (None: none, or hpg_mj's own,
  which the provenance's commit names)."""
  module = type(agent).__module__
  if module == "hpg_mj" or module.startswith("hpg_mj."):
    return None
  return getattr(sys.modules.get(module), "__file__", None)


def _file_sha256(path):
  """The SHA-256 of a file's bytes, or None where it cannot be read."""
  import hashlib
  try:
    return hashlib.sha256(pathlib.Path(path).read_bytes()).hexdigest() if path else None
  except OSError:
    return None


def _warn_if_edited(agent, meta, directory):
  """A VersionWarning when the file of a user's agent class differs from the one it was
  saved with: its rules, view and graph now run as edited, so its scores may change."""
  saved, path = meta.get("agent_file_sha256"), _class_file(agent)
  now = _file_sha256(path)
  if saved and now and saved != now:
    from hpg_mj import provenance
    warnings.warn(f"{directory}: the file of its class, {path}, has changed "
                  "since it was saved (its SHA-256 differs): it runs the code as it is now, "
                  "and its scores may differ from those it was saved with",
                  provenance.VersionWarning, stacklevel=3)


def _kind_and_text(agent):
  """The agent's kind as a task file names it, and its task file's text (one made in
  Python without a task file: a text that rebuilds its config)."""
  kind = agent.name if agent.name in names() else class_path(type(agent))
  if agent.task:
    return kind, agent.task.text
  return kind, taskfile.dumps(kind, agent.config, agent.episodes, agent.seed,
                              f"{type(agent).__name__}, saved from Python")


def rebuilt(agent, assignments):
  """A new agent of `agent`'s class with its learned state, under its task file with
  keys set (`assignments`: "section.key=value", as `hpg-mj train --set` takes them,
  checked as a task file is). `benchmark.at_level` makes with it the same policy at
  another level of its ladder task. `agent` is left as it is."""
  task = agent.task
  if task is None:                    # made in Python: the task file save would write
    task = taskfile.loads(_kind_and_text(agent)[1],
                          pathlib.Path(f"{type(agent).__name__}.toml"), _Registry)
  other = build(taskfile.assigned(task, assignments, _Registry), agent.seed)
  other.restore({name: np.array(value, copy=True) for name, value in agent.state().items()},
                f"agent {agent.name!r}")
  other.episodes = agent.episodes
  return other


def save(agent, directory, record, extra=None, compress=True):
  """Writes the agent's whole state, its record, its task file and what made it
  (`hpg_mj.provenance`) to `directory` (`compress`: see `storage.save`)."""
  from hpg_mj import provenance
  kind, text = _kind_and_text(agent)
  meta = {"task_file": str(agent.task.path) if agent.task else None,
          "task_text": text, "seed": agent.seed, "episodes": agent.episodes,
          "agent_class": class_path(type(agent)),      # found by `load` in a new process
          "agent_file": getattr(sys.modules.get(type(agent).__module__), "__file__", None),
          "agent_file_sha256": _file_sha256(_class_file(agent)),
          "provenance": provenance.collect(text, agent.seed)}
  meta.update(extra or {})
  arrays = dict(agent.state())
  arrays["record"] = record
  return storage.save(directory, kind if agent.task is None else agent.name, arrays, meta,
                      compress)


def load(directory):
  """Loads a saved agent from `directory`; returns (agent, record, metadata): the
  agent with its whole state restored, its training record (None if none was
  saved) and the metadata dict of its agent.json (task file, seed, episodes,
  provenance, metrics, ...). One made by another version of hpg_mj or of its
  libraries is loaded with a `provenance.VersionWarning` that says which. An agent
  of a kind not registered here is found by the import path of its class, which
  `save` records."""
  from hpg_mj import provenance
  meta, arrays = storage.load(directory)
  provenance.warn_if_different(meta.get("provenance"), directory)
  kind = meta.get("kind")
  script = isinstance(kind, str) and kind.startswith("__main__:") and not hasattr(
      sys.modules["__main__"], kind.partition(":")[2])      # a script's class, not this one
  if not isinstance(kind, str) or script or (kind not in names() and ":" not in kind):
    _find_saved_class(kind, meta.get("agent_class"), directory)
  path = pathlib.Path(meta.get("task_file") or "task.toml")
  try:
    task = taskfile.loads(meta.get("task_text") or "", path, _Registry)
  except taskfile.TaskFileError as err:
    where = meta.get("agent_file")
    if not where or "no module" not in str(err):
      raise
    raise taskfile.TaskFileError(f"{err} (its class was saved from {where})") from None
  agent = build(task, meta.get("seed", 0))
  _warn_if_edited(agent, meta, directory)
  record = arrays.pop("record", None)
  agent.restore(arrays, directory)
  agent.episodes = meta.get("episodes", 0)
  return agent, record, meta
