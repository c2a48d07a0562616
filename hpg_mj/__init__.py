"""hpg_mj: hierarchical policy gradient benchmarks on MuJoCo.

Importing the package registers the Gymnasium environments
(`hpg_mj/ShipSteering-v0`, ... see `hpg_mj.envs`). The dm_control suite is
`hpg_mj.suite`.

Importing hpg_mj changes no environment variable and loads no OpenGL library:
simulation never needs one, and rendering happens in a worker process
(`hpg_mj._render_worker`, SPEC section 9).

"SPEC section N" in comments and docstrings is section N of the project's
specification, docs/SPEC.md in the repository.
"""
__version__ = "0.1.0"

from hpg_mj import envs as _envs  # registers the Gymnasium ids

_envs.register_all()

# Imported on first use (PEP 562), so that `import hpg_mj` stays light and the front
# page's `hpg_mj.benchmark.evaluate(...)` works after `import hpg_mj` alone: it had
# raised AttributeError in a fresh interpreter. (The JAX extra stays an explicit
# `import hpg_mj.jax`.)
_SUBMODULES = ("agents", "benchmark", "experiments", "hierarchy", "learners", "planners",
               "render", "suite", "taskfile", "verify", "worlds")


def __getattr__(name):
  """A subpackage or module of `_SUBMODULES`, imported when first asked for."""
  if name in _SUBMODULES:
    import importlib
    return importlib.import_module(f"hpg_mj.{name}")
  raise AttributeError(f"module 'hpg_mj' has no attribute {name!r}")
