"""The call records a graph's rules read (`call.x`, `call.origin`, `call.steps`): one
namedtuple class per set of argument names, made on demand and named by them, so
that the same class stands for the same record in every process (numba's cache of a
rule compiled with one, in the rule's own file or a kind's, finds it again by name).
"""
import collections
import re

FIXED = ("origin", "steps")
_CLASSES = {}


def name_of(arguments):
  """The class name of the record with `arguments` (identifiers), e.g. `Call_1x_1y`."""
  return "Call" + "".join(f"_{len(a)}{a}" for a in arguments)


def record(arguments):
  """The namedtuple class of a call with `arguments` (then `origin`, `steps`)."""
  return __getattr__(name_of(tuple(arguments))) if arguments else Call


def _arguments(name):
  rest, out = name[len("Call"):], []
  while rest:
    m = re.match(r"_(\d+)", rest)
    if m is None:
      raise AttributeError(name)
    n = int(m.group(1))
    start = m.end()
    out.append(rest[start:start + n])
    rest = rest[start + n:]
  return tuple(out)


def __getattr__(name):
  if not name.startswith("Call_"):
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
  if name not in _CLASSES:
    arguments = _arguments(name)
    if name_of(arguments) != name or not all(a.isidentifier() for a in arguments):
      raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    cls = collections.namedtuple(name, arguments + FIXED)
    cls.__module__ = __name__
    _CLASSES[name] = cls
  return _CLASSES[name]


Call = collections.namedtuple("Call", FIXED)
Call.__doc__ = """The record of a call with no arguments: `origin`, the observation
where it began, and `steps`, the primitive steps taken in it."""
