"""Folders import one way only: worlds and learners at the bottom knowing nothing of
each other, hierarchies above them, agents above those, experiments and the
command line on top; no folder-level cycle. (Top-level `_` modules are shared
utilities: the assets, validation, headless imports, the render worker, the checks
of user-given paths.)"""
import ast
import pathlib

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "hpg_mj"
# folder -> the hpg_mj folders (and top-level modules) it may import
ALLOWED = {
    "learners": set(),
    "worlds": {"_assets", "_validation", "_headless", "_render_worker"},
    "envs": {"worlds", "render", "_validation", "_assets", "_headless"},
    "render": {"worlds", "_assets", "_validation", "_headless", "_render_worker"},
    "hierarchy": {"learners", "worlds"},
    "agents": {"hierarchy", "learners", "worlds", "envs", "suite", "render", "provenance",
               "_paths"},
    "experiments": {"agents", "hierarchy", "learners", "worlds", "envs", "suite", "render",
                    "provenance", "_paths"},
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


def test_there_is_no_folder_level_cycle():
  graph = {f: {d for p in (PACKAGE / f).glob("*.py") for d in _imports(p)} & set(ALLOWED) - {f}
           for f in ALLOWED}

  def reach(start, seen):
    for nxt in graph[start]:
      assert nxt != seen[0], f"cycle through {' -> '.join(seen + [nxt])}"
      reach(nxt, seen + [nxt])
  for folder in graph:
    reach(folder, [folder])
