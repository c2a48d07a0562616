"""Python's cyclic collector is paused while numba compiles hpg_mj's code, and only
then (`hpg_mj._collector`), a graph's program's too."""
import gc

import numba
import pytest
from numba.core import event

import hpg_mj.learners  # noqa: F401  (registers the pause)


class _Seen(event.Listener):
  """Whether the collector was on when each compile started (after the pause's own
  listener, registered first, has run)."""

  def __init__(self):
    self.enabled = []

  def on_start(self, ev):
    self.enabled.append(gc.isenabled())

  def on_end(self, ev):
    pass


def _fresh(module):
  """A new dispatcher (so a new compile) of a function that calls another, as if
  defined in `module`."""
  def inner(x):
    return x * 2

  def outer(x):
    return inner_jit(x) + 1
  inner.__module__ = outer.__module__ = module
  inner_jit = numba.njit(inner)
  return numba.njit(outer)


def _compile(function):
  seen = _Seen()
  with event.install_listener("numba:compile", seen):
    assert function(3) == 7
  return seen.enabled


@pytest.fixture
def collector_on():
  was = gc.isenabled()
  gc.enable()
  yield
  if not was:
    gc.disable()


def test_the_collector_is_off_while_hpg_mj_code_compiles_callees_too_and_on_after(collector_on):
  assert _compile(_fresh("hpg_mj.hierarchy.probe")) == [False, False]
  assert gc.isenabled()


def test_a_compile_of_code_outside_hpg_mj_leaves_the_collector_on(collector_on):
  assert _compile(_fresh("users_lab.rules")) == [True, True]
  assert gc.isenabled()


def test_a_collector_the_process_turned_off_stays_off(collector_on):
  gc.disable()
  assert _compile(_fresh("hpg_mj.hierarchy.probe")) == [False, False]
  assert not gc.isenabled()


def test_the_collector_is_on_again_after_a_compile_that_fails(collector_on):
  def broken(x):
    return x.no_such_attribute
  broken.__module__ = "hpg_mj.hierarchy.probe"
  with pytest.raises(numba.core.errors.TypingError):
    numba.njit(broken)(1)
  assert gc.isenabled()


def test_a_graphs_program_compiles_with_the_collector_off(collector_on):
  assert _compile(_fresh("hpg_mj_graph_0123456789abcdef0123")) == [False, False]
  assert gc.isenabled()


def test_importing_either_bottom_layer_registers_the_pause():
  """In a fresh interpreter: the worlds alone, or the learners alone, pause it."""
  import subprocess
  import sys
  for layer in ("hpg_mj.worlds", "hpg_mj.learners"):
    code = (f"import {layer}, gc, numba\n"
            "def f(x):\n  return x + 1\n"
            "f.__module__ = 'hpg_mj.probe'\n"
            "seen = []\n"
            "from numba.core import event\n"
            "class L(event.Listener):\n"
            "  def on_start(self, ev): seen.append(gc.isenabled())\n"
            "  def on_end(self, ev): pass\n"
            "with event.install_listener('numba:compile', L()):\n"
            "  g = numba.njit(f)\n"
            "  g.compile((numba.int64,))\n"
            "print(seen, gc.isenabled())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[False] True", (layer, out.stdout, out.stderr)


def test_a_roomy_call_gives_what_the_function_gives_and_raises_what_it_raises():
  """`hpg_mj._stack.roomy`: the call through a frame of ~2 MB is the call itself."""
  from hpg_mj import _stack

  def deep(n, add=0):
    return add if n == 0 else deep(n - 1, add) + 1
  assert _stack.roomy(deep, 500, add=2) == 502
  with pytest.raises(ZeroDivisionError):
    _stack.roomy(lambda: 1 / 0)
