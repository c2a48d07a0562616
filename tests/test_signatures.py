"""No compiled function takes more than 15 parameters: state that belongs together
(an Eq. 3 trace, a tiling, a table, the hyper-parameters of a loop) travels as one
structure (named tuples the compiled code reads by field)."""
import importlib
import inspect
import pkgutil

import numba.core.registry

import hpg_mj

LIMIT = 15


def _compiled_functions():
  for info in pkgutil.walk_packages(hpg_mj.__path__, "hpg_mj."):
    if info.name.endswith(("_render_worker", "doctor")) or ".render." in info.name or \
        info.name.startswith("hpg_mj.jax"):     # JAX, not numba (and not imported here:
      continue                                  # see tests/jax)
    module = importlib.import_module(info.name)
    for name, value in vars(module).items():
      if isinstance(value, numba.core.registry.CPUDispatcher) and value.__module__ == info.name:
        yield f"{info.name}.{name}", value.py_func


def test_no_compiled_function_takes_more_than_fifteen_parameters():
  found = dict(_compiled_functions())
  assert len(found) > 50                      # the search sees the compiled code
  wide = {name: len(inspect.signature(f).parameters) for name, f in found.items()
          if len(inspect.signature(f).parameters) > LIMIT}
  assert not wide, wide
