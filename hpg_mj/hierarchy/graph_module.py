"""A graph's program as a module of its own (`hierarchy.program`): Algorithm 1's text
and the graph's operations written to a file in the cache folder (`cache_folder`),
named by a hash of everything it compiles, so that numba's cache keeps its machine
code between processes; a change to the algorithm, a kind or a user's file gives
another name. `link` compiles its operations before its entry points call them."""
import hashlib
import importlib.util
import inspect
import os
import sys

import numba

from hpg_mj.hierarchy import algorithm
from hpg_mj.learners import jit

_VERSION = "2"        # of the generated text's layout (2: a user's functions bounds checked)
_HEADER = ("from hpg_mj.hierarchy import boundary", "from hpg_mj.hierarchy import calls")


def cache_folder():
  """Where the graphs' modules (and numba's cache of them) are written:
  $HPG_MJ_CACHE/graphs, else ~/.cache/hpg_mj/graphs."""
  root = os.environ.get("HPG_MJ_CACHE") or os.path.join(os.path.expanduser("~"), ".cache",
                                                        "hpg_mj")
  return os.path.join(root, "graphs")


def _fingerprint(fn):
  """What identifies a compiled function's code: its module, name and the text of its
  file (a change to a helper beside it counts too), or its bytecode."""
  py = getattr(fn, "py_func", fn)
  h = hashlib.sha256(f"{py.__module__}.{py.__qualname__}".encode())
  try:
    with open(inspect.getsourcefile(py), "rb") as f:
      h.update(f.read())
  except (TypeError, OSError):
    code = py.__code__
    h.update(code.co_code)
    h.update(repr(code.co_consts).encode())
    h.update(repr(code.co_names).encode())
  return h.hexdigest()


def _importable(fn):
  """Whether another process finds `fn` again by its module's name (numba's cache
  rebuilds a compiled function's globals by importing its module)."""
  py = getattr(fn, "py_func", fn)
  module = sys.modules.get(py.__module__)
  return module is not None and getattr(module, "__file__", None) is not None


def load(text, functions, record_types):
  """(the module, its path, whether numba caches it) of `text` with `functions`
  ({global name: function}) as its globals; `record_types` the types of the records
  it is called with (part of its name). A rule from code that no module holds (a
  notebook's cell, an exec'd block) is compiled anew in each process: numba's cache
  could not find it again."""
  cached = all(_importable(fn) for fn in functions.values())
  if not cached:
    text = text.replace("cache=True", "cache=False")
  h = hashlib.sha256((_VERSION + text).encode())
  for global_name, fn in sorted(functions.items()):
    h.update(global_name.encode())
    h.update(_fingerprint(fn).encode())
  for t in record_types:
    h.update(repr(t).encode())
  name = f"hpg_mj_graph_{h.hexdigest()[:20]}"
  text = text.replace("import collections\n", "import collections\n" + "\n".join(_HEADER) +
                      "\n", 1)
  folder = cache_folder()
  os.makedirs(folder, exist_ok=True)
  path = os.path.join(folder, name + ".py")
  if not os.path.exists(path):
    tmp = f"{path}.{os.getpid()}.tmp"
    with open(tmp, "w") as f:
      f.write(text)
    os.replace(tmp, path)
  if name in sys.modules:
    return sys.modules[name], path, cached
  spec = importlib.util.spec_from_file_location(name, path)
  module = importlib.util.module_from_spec(spec)
  module.__dict__.update(functions)
  sys.modules[name] = module
  try:
    spec.loader.exec_module(module)
  except BaseException:
    del sys.modules[name]
    raise
  return module, path, cached


def link(module, G, ops):
  """Compiles (or loads from numba's cache) the graph's operations in `module` for the
  types Algorithm 1 calls them with, each from the top of Python's stack, and writes
  into `ops` (`Frames.ops`) the addresses of `enter`, `resume` and `judge`, through
  which Algorithm 1 calls them (`learners.jit.call_at`). Left to numba, each was
  compiled inside its caller, every kind deep in Python's stack (`learners.jit`:
  CPython's frame-stack chunks mapped and unmapped again), and its code was linked
  into the entry point's and optimized by LLVM once more: 1.7 s of the ship hybrid's
  first compile of 10.4 s."""
  g, i, b, f = numba.typeof(G), numba.int64, numba.boolean, numba.float64
  for op, signature in ((module.judge, (g, i)), (module.chosen, (g, i)),
                        (module.schedule_run, (g, i, b)), (module.schedule_episode, (g, i)),
                        (module.schedule_decided, (g,)), (module.enter, (g, i)),
                        (module.resume, (g, i, f, b, b, b))):
    op.compile(signature)
  for at, op, example in ((algorithm.OP_ENTER, module.enter, (G, 0)),
                          (algorithm.OP_RESUME, module.resume, (G, 0, 0.0, False, False, False)),
                          (algorithm.OP_JUDGE, module.judge, (G, 0))):
    ops[at] = jit.address_of(op, example)
