"""A call on a Python frame stack with room: `roomy(fn, *args)`.

On Python 3.11 and 3.12 the interpreter keeps its frames in chunks of 16 KB, maps a
chunk when a call crosses into it and unmaps it when that call returns (CPython
gh-142183, fixed in later 3.13 and 3.14 releases). numba's compiler recurses
hundreds of frames deep and back, millions of times in a first compile, so wherever
its depth swings across a chunk's boundary every call maps and unmaps a chunk. How
often depends on the depth the compile starts at: the ship hybrid's first train (empty
caches) took 14.1-14.5 s of CPU, 1.2 s of it in the kernel, started two frames deeper
than `hpg-mj train` starts it, and 9.1-9.2 s (0.28 s) through `roomy`.

`roomy` calls `fn(*args)` from a frame of ~2 MB (its code's stack size made large):
the interpreter gives that frame a chunk of 4 MB, and the frames of everything
`fn` calls fit in the chunk's other ~2 MB, so no call below it crosses a boundary.
Elsewhere (other Pythons) it is one larger frame. The entry points that compile
call through it: the command line, an experiment's worker processes (and Ray's), a
graph's program's first run, and the rules compiled leaves first
(`learners.jit.compile_first`).
"""
import types


def _call(fn, args, kwargs):
  return fn(*args, **kwargs)


# 270,000 slots of 8 bytes: the chunk is the next power of two above the frame, 4 MB.
_ROOMY = types.FunctionType(_call.__code__.replace(co_stacksize=270_000), globals(), "roomy")


def roomy(fn, *args, **kwargs):
  """fn(*args, **kwargs), everything it calls on one chunk of the frame stack."""
  return _ROOMY(fn, args, kwargs)
