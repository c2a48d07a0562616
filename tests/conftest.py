"""Puts tests/ on the import path, for the shared test helpers (taxi_grid.py,
experiment_file.py, oracle.py);
the suite imports its test files with --import-mode=importlib."""
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).parent))


def pytest_pyfunc_call(pyfuncitem):
  """Each test runs on a roomy frame stack (`hpg_mj._stack.roomy`), as the command line
  and a program's first run do: numba compiles in most tests, and pytest's own frames
  put that compile at a depth where, on Python 3.11 and 3.12, the interpreter may map
  and unmap a frame-stack chunk at every call."""
  from hpg_mj import _stack
  function = pyfuncitem.obj
  names = pyfuncitem._fixtureinfo.argnames
  _stack.roomy(function, **{name: pyfuncitem.funcargs[name] for name in names})
  return True
