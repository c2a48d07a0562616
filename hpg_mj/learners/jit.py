"""Compiling the rules a fused loop calls before the loop itself.

numba compiles a function's callees while it types the function, one inside the
other, so the innermost rules of a deep loop compile with the Python stack
hundreds of frames deep. On Python 3.11 and 3.12 that is slow for an unrelated
reason (CPython gh-142183, fixed in later 3.13 and 3.14 releases): each time a
call crosses the boundary of the interpreter's 16 KB frame-stack chunks, the chunk
is mapped and unmapped again, and numba's compiler does so hundreds of thousands of
times. Compiled one by one from the bottom up, each function compiles near the top
of the stack, and the loop then finds its callees compiled (MAXQ-Q's first compile:
0.2 s of system time rather than 1.6 from the command line).
"""
import numba


def compile_first(loop, rules):
  """Before `loop`'s first call in this process, compiles (or loads from numba's
  cache) each `(dispatcher, example arguments)` of `rules()` in order, for the types
  of the example arguments: list the callees before their callers. The examples'
  types must be those the loop calls them with, or the loop compiles them again for
  its own (as it would have anyway)."""
  if loop.signatures:
    return
  for dispatcher, example in rules():
    dispatcher.compile(tuple(numba.typeof(value) for value in example))
