"""The machine's boundary with a user's code: every value a rule or kind gives (a
view's state or features, a termination's event, an internal reward, a learner's
choice of a child, a binding's arguments) passes one of these checks before it
reaches an array, on both paths (fused and step by step: the same compiled code).

A value out of bounds or of the wrong type does not raise inside compiled code with
its value (numba's exceptions carry constants only in code compiled without
reference counting): the check writes what it saw into the program's `fault`
record, [what, value, which check failed, the length given], and raises `Fault`;
the program's Python side (`hierarchy.program`) turns that into one line naming the
node, the value and what was expected. The checks are chosen by the value's type
when compiled (`numba.extending.overload`), so a float where a state is due is a
refusal, not a truncation.

A rule that reads an argument its calls do not bind fails numba's typing of the
graph's module instead, at its first call: `typing_line` finds the subtask and the
rule in numba's message, for the same one line.
"""
import inspect
import math
import os
import re

import numba
import numpy as np
from numba import types
from numba.extending import overload

# What failed (the fault record's [2]).
(OUT_OF_RANGE, NOT_AN_INTEGER, WRONG_LENGTH, NOT_FINITE, NOT_NUMBERS, NOT_AN_EVENT,
 NOT_A_CHOICE) = range(1, 8)
FAULT_MESSAGE = "hpg_mj: a rule's value was refused at the machine's boundary (see the fault)"
# The type numba saw where a rule gave something that is not numbers, by check
# (filled when the check is compiled; empty when it came from the cache).
SEEN_TYPES = {}
# A check is compiled once for each type it is given and called, not inlined into the
# graph's operations: inlined, numba typed its body again at every call site (LLVM
# still inlines the call).
_CALLED = {"error_model": "numpy", "_nrt": False, "no_cpython_wrapper": True,
           "no_cfunc_wrapper": True}


@numba.njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
             no_cfunc_wrapper=True)
def fail(fault, what, value, code, length):
  """Writes the fault record and raises (the Python side reads the record)."""
  fault[0] = what
  fault[1] = value
  fault[2] = code
  fault[3] = length
  raise ValueError(FAULT_MESSAGE)


def _number(t):
  return isinstance(t, (types.Integer, types.Float, types.Boolean))


def as_state(value, n_states, fault, what):
  """`value` as a table's state: an integer in [0, n_states)."""


@overload(as_state, jit_options=_CALLED)
def _as_state(value, n_states, fault, what):
  if isinstance(value, (types.Integer,)) and not isinstance(value, types.Boolean):
    def state(value, n_states, fault, what):
      s = np.int64(value)
      if s < 0 or s >= n_states:
        fail(fault, what, float(value), np.int64(OUT_OF_RANGE), 0.0)
      return s
    return state
  if isinstance(value, types.Float):
    def not_integer(value, n_states, fault, what):
      fail(fault, what, float(value), np.int64(NOT_AN_INTEGER), 0.0)
      return np.int64(0)
    return not_integer
  SEEN_TYPES[("state", str(value))] = str(value)

  def not_numbers(value, n_states, fault, what):
    fail(fault, what, np.nan, np.int64(NOT_NUMBERS), 0.0)
    return np.int64(0)
  return not_numbers


def as_features(value, out, fault, what):
  """`value` (a number, or a tuple of numbers of `out`'s length) written into `out`."""


@overload(as_features, jit_options=_CALLED)
def _as_features(value, out, fault, what):
  if _number(value):
    def one(value, out, fault, what):
      if out.shape[0] != 1:
        fail(fault, what, np.nan, np.int64(WRONG_LENGTH), 1.0)
      v = float(value)
      if not math.isfinite(v):
        fail(fault, what, v, np.int64(NOT_FINITE), 1.0)
      out[0] = v
    return one
  if isinstance(value, types.UniTuple) and _number(value.dtype):
    n = value.count

    def many(value, out, fault, what):
      if out.shape[0] != n:
        fail(fault, what, np.nan, np.int64(WRONG_LENGTH), float(n))
      for i in range(n):
        v = float(value[i])
        if not math.isfinite(v):
          fail(fault, what, v, np.int64(NOT_FINITE), float(n))
        out[i] = v
    return many
  if isinstance(value, types.Tuple) and all(_number(t) for t in value.types):
    return _unrolled(len(value.types) * (False,), into_out=True)

  def not_numbers(value, out, fault, what):
    fail(fault, what, np.nan, np.int64(NOT_NUMBERS), 0.0)
  return not_numbers


def as_event(value, fault, what):
  """`value` as a call's event: 0 go on, 1 success, -1 failure (a bool: True is 1)."""


@overload(as_event, jit_options=_CALLED)
def _as_event(value, fault, what):
  if isinstance(value, types.Boolean):
    # True is 1 (no branch: a conditional here made numba's inlining warn of its phi)
    return lambda value, fault, what: np.int64(value)
  if isinstance(value, types.Integer):
    def event(value, fault, what):
      e = np.int64(value)
      if e != 0 and e != 1 and e != -1:
        fail(fault, what, float(value), np.int64(NOT_AN_EVENT), 0.0)
      return e
    return event
  if isinstance(value, types.Float):
    def not_integer(value, fault, what):
      fail(fault, what, float(value), np.int64(NOT_AN_INTEGER), 0.0)
      return np.int64(0)
    return not_integer

  def not_numbers(value, fault, what):
    fail(fault, what, np.nan, np.int64(NOT_NUMBERS), 0.0)
    return np.int64(0)
  return not_numbers


def as_reward(value, fault, what):
  """`value` as an internal reward: a finite number."""


@overload(as_reward, jit_options=_CALLED)
def _as_reward(value, fault, what):
  if _number(value):
    def reward(value, fault, what):
      g = float(value)
      if not math.isfinite(g):
        fail(fault, what, g, np.int64(NOT_FINITE), 0.0)
      return g
    return reward

  def not_numbers(value, fault, what):
    fail(fault, what, np.nan, np.int64(NOT_NUMBERS), 0.0)
    return 0.0
  return not_numbers


def as_choice(value, n, fault, what):
  """`value`, a learner's choice, as a child's index: an integer-valued number in
  [0, n) (a kind's `choose` and `observe` return floats)."""


@overload(as_choice, jit_options=_CALLED)
def _as_choice(value, n, fault, what):
  if isinstance(value, (types.Integer, types.Boolean)):
    def index(value, n, fault, what):
      c = np.int64(value)
      if c < 0 or c >= n:
        fail(fault, what, float(value), np.int64(NOT_A_CHOICE), 0.0)
      return c
    return index
  if isinstance(value, types.Float):
    def whole(value, n, fault, what):
      # (NaN fails the first test: it is converted to an integer only when in range)
      if not (value >= 0.0 and value < n) or np.int64(value) != value:
        fail(fault, what, float(value), np.int64(NOT_A_CHOICE), 0.0)
      return np.int64(value)
    return whole

  def not_numbers(value, n, fault, what):
    fail(fault, what, np.nan, np.int64(NOT_NUMBERS), 0.0)
    return np.int64(0)
  return not_numbers


def as_bound(value, like, fault, what):
  """`value`, what a binding kind's `bind` gave, as its arguments: a tuple (or, for
  one argument, a number) of as many finite numbers as `like`, a tuple of zeros of
  the arguments' types (an integer argument's value a whole number)."""


def _unrolled(ints, into_out):
  """The check of a tuple of numbers of `ints`' length, unrolled (a tuple of mixed
  types is indexed by constants only; numba's `literal_unroll` is refused inside an
  overload): each finite, those where `ints` is True whole; written into `out` (a
  view's features) or the tuple returned as it is (a binding's arguments)."""
  n = float(len(ints))
  text = [f"def unrolled(value, {'out' if into_out else 'like'}, fault, what):"]
  if into_out:
    text += [f"  if out.shape[0] != {len(ints)}:",
             f"    fail(fault, what, np.nan, np.int64(WRONG_LENGTH), {n!r})"]
  for i, whole in enumerate(ints):
    text += [f"  f{i} = float(value[{i}])", f"  if not math.isfinite(f{i}):",
             f"    fail(fault, what, f{i}, np.int64(NOT_FINITE), {n!r})"]
    if whole:
      text += [f"  if f{i} != math.floor(f{i}):",
               f"    fail(fault, what, f{i}, np.int64(NOT_AN_INTEGER), {n!r})"]
    if into_out:
      text.append(f"  out[{i}] = f{i}")
  text.append("  return None" if into_out else "  return value")
  scope = {"math": math, "np": np, "fail": fail, "NOT_FINITE": NOT_FINITE,
           "NOT_AN_INTEGER": NOT_AN_INTEGER, "WRONG_LENGTH": WRONG_LENGTH}
  exec("\n".join(text), scope)
  return scope["unrolled"]


@overload(as_bound, jit_options=_CALLED)
def _as_bound(value, like, fault, what):
  ints = tuple(isinstance(t, types.Integer) for t in like.types)
  n = len(ints)
  if _number(value):
    if n != 1:
      def short(value, like, fault, what):
        fail(fault, what, np.nan, np.int64(WRONG_LENGTH), 1.0)
        return like
      return short

    def one(value, like, fault, what):
      f = float(value)
      if not math.isfinite(f):
        fail(fault, what, f, np.int64(NOT_FINITE), 1.0)
      if ints[0] and f != math.floor(f):
        fail(fault, what, f, np.int64(NOT_AN_INTEGER), 1.0)
      return (value,)
    return one
  if isinstance(value, types.BaseTuple) and all(_number(t) for t in value.types):
    if len(value.types) != n:
      given = float(len(value.types))

      def wrong(value, like, fault, what):
        fail(fault, what, np.nan, np.int64(WRONG_LENGTH), given)
        return like
      return wrong

    return _unrolled(ints, into_out=False)

  def not_numbers(value, like, fault, what):
    fail(fault, what, np.nan, np.int64(NOT_NUMBERS), 0.0)
    return like
  return not_numbers


def explain(fault, whats):
  """The one line for a fault record; `whats[i]` = (node, what it is, what is allowed)."""
  node, what, allowed = whats[int(fault[0])]
  code, value, length = int(fault[2]), float(fault[1]), int(fault[3])
  if code == OUT_OF_RANGE or code == NOT_AN_EVENT:
    said = f"gave {value:g}"
  elif code == NOT_A_CHOICE:
    said = f"chose {value:g}"
  elif code == NOT_AN_INTEGER:
    said = f"gave {value!r} (a float)"
  elif code == WRONG_LENGTH:
    said = f"gave {length} number{'s' if length != 1 else ''}"
  elif code == NOT_FINITE:
    said = f"gave {value!r}"
  else:
    said = "gave a value that is not numbers"
  return f"subtask {node!r}: its {what} {said}; expected {allowed}"


_UNKNOWN = re.compile(r"Unknown attribute '(\w+)' of type (Call(?:_\w+)?)\(")


def typing_line(message, module_path, roles, names, arguments):
  """The one line for numba's typing error `message` from the graph's module at
  `module_path` where a rule reads an argument its calls do not bind ("Unknown
  attribute 'x' of type Call_2px_2py(...)"); None for any other. The subtask is the
  one whose branch of the module's operation holds the line numba names (else those
  whose calls are of that type); `roles` {a function's global name: its role, e.g.
  "view Features(aim)"}, `names` the nodes by index, `arguments` {node: its
  arguments}."""
  from hpg_mj.hierarchy import calls
  found = _UNKNOWN.search(message)
  if found is None:
    return None
  attr, record = found.groups()
  bound = list(calls._arguments(record)) if record != "Call" else []
  node, role = None, None          # (node: the names of the nodes)
  at = re.search(re.escape(os.path.basename(module_path)) + r" \((\d+)\)", message)
  if at is not None:
    with open(module_path) as f:
      lines = f.read().split("\n")
    number = int(at.group(1)) - 1
    used = re.findall(r"\b(_f\d+)\(", lines[number]) if number < len(lines) else []
    role = next((roles[g] for g in used if g in roles), None)
    for line in reversed(lines[:number]):
      branch = re.match(r"^  (?:if|elif) (node == \d+(?: or node == \d+)*):$", line)
      if branch is not None:        # (nodes of one shape share a branch: each reads it)
        node = [names[int(i)] for i in re.findall(r"\d+", branch.group(1))]
        break
      if line.startswith("def "):
        break
  if node is None:
    nodes = [n for n, args in arguments.items() if list(args) == bound]
    node = nodes[:1] if len(nodes) == 1 else None
  who = (f"a subtask whose calls bind {bound}" if node is None else
         f"subtask{'s' if len(node) > 1 else ''} {', '.join(map(repr, node))}")
  return (f"{who}: its {role or 'rule'} reads call.{attr}; its calls bind {bound} (and "
          "call.origin, call.steps)")


_AT = re.compile(r'File "([^"]+)", line (\d+)')
_NOT_A_REASON = ("Failed in ", "During:", "File ", "<source", "^", "Enable logging",
                 "This error may have been caused", "- Resolution", "- Of which",
                 "For more information", "Rewrite", "The function")


def user_typing_line(message, package_dir, module_path):
  """The one line for any other numba typing error in a user's compiled code (a rule, a
  binding or a learner kind of their own): where in their file it stopped and numba's
  innermost reason ("Unknown attribute 'gate_weight' of type ..."); None where the error
  names no file outside `package_dir` and the graph's module at `module_path`."""
  places = [(path, line) for path, line in _AT.findall(message)
            if _outside(path, package_dir, module_path)]
  if not places:
    return None
  reasons, quoting = [], False     # (a `File ...:` line quotes source up to a blank line)
  for line in message.splitlines():
    if line.startswith("File "):
      quoting = True
    elif not line.strip():
      quoting = False
    elif not quoting and not line.startswith(_NOT_A_REASON):
      reasons.append(line.strip())
  reason = reasons[0] if reasons else "numba could not type it"
  return _user_line(*places[0], reason)


def _user_line(path, line, reason):
  """The one line of a compile error in a user's own code: where, and numba's reason."""
  return (f"{path}, line {line}: your compiled code does not compile: {reason} (numba's "
          "reason; calling that function alone shows its whole message)")


def _outside(path, package_dir, module_path):
  """Whether `path` is a user's file: neither hpg_mj's nor the graph's module."""
  return (not os.path.abspath(path).startswith(os.path.abspath(package_dir))
          and os.path.basename(path) != os.path.basename(module_path))


def is_users(fn):
  """Whether `fn` is a compiled function of a user's own (not of hpg_mj)."""
  module = getattr(getattr(fn, "py_func", None), "__module__", None) or ""
  return (isinstance(fn, numba.core.registry.CPUDispatcher) and module != "hpg_mj" and
          not module.startswith("hpg_mj."))


_CHECKED = {}


def bounds_checked(fn):
  """`fn` compiled with numba's bounds check where it is a user's own compiled function
  (a rule, a kind's operation): an index past an array's end (`obs[11]` of the
  harbour's 11 numbers) raises IndexError, caught as one line (`read_past`),
  where unchecked it read whatever memory lay there. Not cached by numba (the user's
  own dispatcher keeps its cache); the graph's module, which calls it, is. hpg_mj's
  own functions as they are."""
  if not is_users(fn):
    return fn
  if id(fn) not in _CHECKED:
    options = {k: v for k, v in fn.targetoptions.items()
               if k not in ("nopython", "boundscheck", "cache")}
    _CHECKED[id(fn)] = (fn, numba.njit(**{**options, "boundscheck": True})(fn.py_func))
  return _CHECKED[id(fn)][1]


def read_past(error, functions, roles, obs_size):
  """The IndexError a bounds-checked function raised (`bounds_checked`) as one line naming
  the user's code the graph compiles (`functions`: (global name, function) pairs;
  `roles`: a rule's role by global name) and the observation's length; `error` itself
  where the graph holds none of a user's."""
  users = [(roles.get(name, getattr(fn, "__name__", name)), fn) for name, fn in functions
           if is_users(fn)]
  if not users:
    return error
  fixed = [f"{role} reads {read}" for role, fn in users for read in _fixed_reads(fn, obs_size)]
  fixed = f"; past it at a fixed index: {'; '.join(fixed)}" if fixed else ""
  return IndexError(f"the graph's compiled program read past the end of an array ({error}); "
                    f"numba checks the bounds in your own code but does not say which read "
                    f"it; one of: {', '.join(role for role, _ in users)} (the "
                    f"observation holds {obs_size} numbers, obs[0] to obs[{obs_size - 1}])"
                    f"{fixed}")


def _fixed_reads(fn, obs_size):
  """Each read of the observation at a written index past its end in `fn`'s source,
  as "obs[11] (file.py, line 7)": the parameter named obs (or holding it in its name),
  else a rule's first, `rule(obs, call)`."""
  try:
    lines, first = inspect.getsourcelines(fn.py_func)
    path = os.path.basename(inspect.getsourcefile(fn.py_func))
    names = list(inspect.signature(fn.py_func).parameters)
  except (OSError, TypeError, ValueError):
    return []
  named = [n for n in names if "obs" in n.lower()]
  if not named and len(names) == 2:               # a rule(obs, call) by other names
    named = names[:1]
  found = []
  for i, line in enumerate(lines):
    for name in named:
      found += [f"{m.group(0)} ({path}, line {first + i})"
                for m in re.finditer(rf"\b{re.escape(name)}\[(\d+)\]", line.split("#")[0])
                if int(m.group(1)) >= obs_size]
  return found


def attribute_line(error, package_dir, module_path):
  """The one line for an AttributeError numba raised typing a user's compiled code (a
  module's name that is not there, `math.hypotenuse`: numba passes Python's own error
  on, without a place): the user's file and line where typing stopped (the innermost
  frame typing a place outside `package_dir` and the graph's module), or None."""
  place, tb = None, error.__traceback__
  while tb is not None:
    loc = getattr(tb.tb_frame.f_locals.get("self"), "loc", None)
    path = getattr(loc, "filename", None)
    if isinstance(path, str) and _outside(path, package_dir, module_path):
      place = (path, loc.line)
    tb = tb.tb_next
  return None if place is None else _user_line(*place, error)


def compile_error_line(error, module_path, roles, names, arguments):
  """The one line of an error from a graph's first compile, or None: a TypingError
  (`typing_line`; else, one in a user's own compiled code, `user_typing_line`: where,
  and why) or the AttributeError numba passes on from a user's code (`attribute_line`)."""
  package_dir = os.path.dirname(os.path.dirname(__file__))
  if isinstance(error, AttributeError):
    return attribute_line(error, package_dir, module_path)
  text = str(error)
  line = typing_line(text, module_path, roles, names, arguments)
  if line is None:
    line = user_typing_line(text, package_dir, module_path)
  return line
