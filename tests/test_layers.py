"""Folders import one way only: worlds and learners at the bottom knowing nothing of
each other, hierarchies above them, agents above those, experiments and the
command line on top; no folder-level cycle. (Top-level `_` modules are shared
utilities: the assets, validation, headless imports, the render worker, the checks
of user-given paths, the collector paused while numba compiles, a roomy frame stack.)"""
import ast
import pathlib

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "hpg_mj"
# folder -> the hpg_mj folders (and top-level modules) it may import
ALLOWED = {
    "learners": {"_collector", "_stack"},
    "worlds": {"_assets", "_validation", "_headless", "_render_worker", "_collector"},
    "envs": {"worlds", "render", "_validation", "_assets", "_headless"},
    "render": {"worlds", "_assets", "_validation", "_headless", "_render_worker"},
    "hierarchy": {"learners", "worlds", "_collector", "_stack"},
    # (hpg_mj.jax: the JAX agents' learner, imported when such an agent is built)
    "agents": {"hierarchy", "learners", "worlds", "envs", "suite", "render", "provenance",
               "_paths", "taskfile", "storage", "jax"},
    "experiments": {"agents", "hierarchy", "learners", "worlds", "envs", "suite", "render",
                    "provenance", "_paths", "taskfile", "storage", "_stack", "_compiling"},
    # The JAX worlds (the `jax` extra) take the numba worlds' constants, nothing else;
    # the MJX ship (the `mjx` extra) reads the shipped MJCF.
    "jax": {"worlds", "_assets"},
}


def _imports(path):
  """The hpg_mj folders or top-level modules a file imports."""
  found = set()
  for node in ast.walk(ast.parse(path.read_text())):
    names = []
    if isinstance(node, ast.Import):
      names = [a.name for a in node.names]
    elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
      names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
    for name in names:
      parts = name.split(".")
      if parts[0] == "hpg_mj" and len(parts) > 1:
        found.add(parts[1])
  return found


@pytest.mark.parametrize("folder", sorted(ALLOWED))
def test_a_folder_imports_only_the_layers_below_it(folder):
  for path in sorted((PACKAGE / folder).glob("*.py")):
    bad = _imports(path) - ALLOWED[folder] - {folder}
    # `import hpg_mj` (for the Gymnasium ids) is not a folder
    assert not bad, f"{path.relative_to(PACKAGE.parent)} imports {sorted(bad)}"


def _third_party_imports(path):
  """The top-level names of the outside packages a file imports, lazy imports included."""
  found = set()
  for node in ast.walk(ast.parse(path.read_text())):
    if isinstance(node, ast.Import):
      found.update(a.name.split(".")[0] for a in node.names)
    elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
      found.add(node.module.split(".")[0])
  return found


def test_only_hpg_mj_jax_imports_jax():
  """JAX is an optional extra (`pip install hpg_mj[jax]`): no module outside
  hpg_mj/jax imports it (nor gymnax), so that the core never needs it."""
  inside = PACKAGE / "jax"
  users = [str(p.relative_to(PACKAGE.parent)) for p in sorted(PACKAGE.rglob("*.py"))
           if inside not in p.parents and {"jax", "jaxlib", "gymnax"} & _third_party_imports(p)]
  assert users == []
  assert "jax" in _third_party_imports(inside / "ship.py")     # the rule sees imports


def test_there_is_no_folder_level_cycle():
  graph = {f: {d for p in (PACKAGE / f).glob("*.py") for d in _imports(p)} & set(ALLOWED) - {f}
           for f in ALLOWED}

  def reach(start, seen):
    for nxt in graph[start]:
      assert nxt != seen[0], f"cycle through {' -> '.join(seen + [nxt])}"
      reach(nxt, seen + [nxt])
  for folder in graph:
    reach(folder, [folder])


def _module_graph():
  """Every module of hpg_mj, top-level ones too, -> the hpg_mj modules it imports
  (`from package import module` is an import of the module), lazy imports included."""
  def name_of(path):
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
  modules = {name_of(p): p for p in PACKAGE.rglob("*.py")}
  graph = {}
  for name, path in modules.items():
    deps = set()
    for node in ast.walk(ast.parse(path.read_text())):
      if isinstance(node, ast.Import):
        deps.update(a.name for a in node.names if a.name in modules)
      elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
        for a in node.names:
          full = f"{node.module}.{a.name}"
          deps.add(full if full in modules else node.module)
    graph[name] = deps & set(modules) - {name}
  return graph


def test_no_module_imports_itself_through_others():
  """No import circle between modules, the top-level ones included (the MuJoCo ship's
  model is `worlds/ship_model.py`, which the render worker's drawing and the dm_control
  domain both import; the domain imports the worker, the model does not)."""
  graph = _module_graph()
  assert graph["hpg_mj.render.drawing"] >= {"hpg_mj.worlds.ship_model"}
  assert "hpg_mj._render_worker" not in graph["hpg_mj.worlds.ship_model"]
  # the task-file format and an agent's folder sit below the agents that use them
  for below in ("hpg_mj.taskfile", "hpg_mj.storage"):
    assert not {m for m in graph[below] if m.startswith(("hpg_mj.agents", "hpg_mj.experiments"))}
  done, cycles = set(), []

  def visit(name, path):
    for nxt in sorted(graph[name]):
      if nxt in path:
        cycles.append(path[path.index(nxt):] + [nxt])
      elif nxt not in done:
        visit(nxt, path + [nxt])
    done.add(name)
  for name in sorted(graph):
    if name not in done:
      visit(name, [name])
  assert cycles == []


def _agent_modules():
  """The modules of the shipped agents (the registry's import paths)."""
  from hpg_mj import agents
  return {spec.split(":")[0].split(".")[-1] for spec in agents._SHIPPED.values()}


def _imported_agent_modules(path):
  """The `hpg_mj.agents` submodules a file imports (`from hpg_mj.agents import x`,
  `import hpg_mj.agents.x`)."""
  found = set()
  for node in ast.walk(ast.parse(path.read_text())):
    if isinstance(node, ast.ImportFrom) and node.module == "hpg_mj.agents":
      found |= {a.name for a in node.names}
    elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("hpg_mj.agents."):
      found.add(node.module.split(".")[2])
    elif isinstance(node, ast.Import):
      found |= {a.name.split(".")[2] for a in node.names if a.name.startswith("hpg_mj.agents.")}
  return found


def test_experiments_reach_agents_only_through_the_registry():
  """An experiment names its agents by task file: it may use the registry and the
  agents' shared modules, never import a particular agent."""
  particular = _agent_modules()
  assert {"ship_hybrid", "taxi_hpg", "sb3"} <= particular
  for path in sorted((PACKAGE / "experiments").glob("*.py")):
    bad = _imported_agent_modules(path) & particular
    assert not bad, f"{path.relative_to(PACKAGE.parent)} imports the agent module(s) {sorted(bad)}"


def test_no_module_is_over_800_lines():
  """A module that grows past 800 lines is split by what it does (SPEC's layout)."""
  long = {str(p.relative_to(PACKAGE)): n for p in PACKAGE.rglob("*.py")
          if (n := len(p.read_text().splitlines())) > 800}
  assert long == {}
