"""A graph's call arguments (`hierarchy.program`), checked where the graph is built:
what each `Child` binds (numbers, `Child("goto", x=300.0)`, or a binding block
whose kind decides them when the parent calls, `Child("goto", bind=block)`), and
that every call of one subtask binds the same names. Each refusal is one line naming
the subtask, the child (its parent and index) and the names.
"""
import collections

import numpy as np

from hpg_mj.hierarchy import kinds as kinds_mod
from hpg_mj.hierarchy.graph import GraphError, Primitive

FIXED = ("origin", "steps")       # a call's own fields (`hierarchy.calls`)


def check(where, arg, value):
  """A call's argument: a finite int or float named by an identifier; else one line."""
  if not str(arg).isidentifier():
    raise GraphError(f"{where} {arg!r}: must be a Python identifier")
  if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
    raise GraphError(f"{where} {arg} = {value!r}: must be a number (int or float)")
  if not np.isfinite(value):
    raise GraphError(f"{where} {arg} = {value!r}: must be finite")


def binding(name, ref):
  """(the kind, its arguments {name: whether an integer}) of the binding of `ref`, a
  `Child` of subtask `name`."""
  if callable(ref.bind) and not isinstance(ref.bind, type):
    try:
      kind = kinds_mod.kind_of(ref.bind, "binding", name)
    except GraphError:
      raise GraphError(f"subtask {name!r}: its child {ref.node!r} binds its arguments by a "
                       "Python function (Child(bind=...)), which the open machine cannot "
                       "compile; give the arguments as numbers, Child("
                       f"{ref.node!r}, x=..., y=...), or bind them by a block whose kind "
                       "is registered (hpg_mj.hierarchy.kinds.base.BindingKind)") from None
  else:
    kind = kinds_mod.kind_of(ref.bind, "binding", name)
  return kind, dict(kind.names(ref.bind))


def _label(parent, k, ref):
  """How a message names one call: `root's child 0 (x=300.0, yy=700.0)`, `root's
  child 1 (bind=GatePoint)`."""
  if ref is None:
    return "the root call"
  how = f"bind={type(ref.bind).__name__}" if ref.bind is not None else \
      ", ".join(f"{a}={v!r}" for a, v in ref.args.items()) or "no arguments"
  return f"{parent}'s child {k} ({how})"


def _differ(child, calls):
  """The one line for calls of `child` binding different names: which differ, and what
  the others bind."""
  names = [tuple(sorted(args)) for _, _, _, args in calls]
  common, count = collections.Counter(names).most_common(1)[0]
  if count > 1:
    odd = [(c, n) for c, n in zip(calls, names) if n != common]
    said = "; ".join(f"{_label(*c[:3])} binds {list(n)}" for c, n in odd)
    others = len(calls) - len(odd)
    said += f"; its other {others} call{'s' if others != 1 else ''} bind {list(common)}"
  else:
    said = "; ".join(f"{_label(*c[:3])} binds {list(n)}" for c, n in zip(calls, names))
  return (f"subtask {child!r}: its calls bind different arguments: {said}; every call of a "
          "subtask binds the same names")


def collect(graph, root_args):
  """node -> {argument: whether an integer} (in the order of its first call's names,
  sorted), every call of a node checked to bind the same names; `root_args` the root
  call's arguments."""
  bound = {}
  for name, node in graph.nodes.items():
    if isinstance(node, Primitive):
      continue
    for k, ref in enumerate(graph.children(name)):
      for arg, value in ref.args.items():
        check(f"subtask {name!r}: its child {ref.node!r}'s argument", arg, value)
      args = dict(ref.args)
      if ref.bind is not None:
        for arg, is_int in binding(name, ref)[1].items():
          if arg in args:
            raise GraphError(f"subtask {name!r}: its child {ref.node!r} gives {arg!r} "
                             "twice, as a number and by its binding; give it once")
          args[arg] = 0 if is_int else 0.0
      if isinstance(graph.nodes[ref.node], Primitive):
        if args:
          raise GraphError(f"subtask {name!r}: its child {ref.node!r} is a primitive, "
                           f"which takes no arguments; got {sorted(args)}")
        continue
      bound.setdefault(ref.node, []).append((name, k, ref, args))
  for name, node in graph.nodes.items():
    if not isinstance(node, Primitive) and name != graph.root and name not in bound:
      raise GraphError(f"subtask {name!r} is called by no node of the graph; call it "
                       f"(Child({name!r}, ...)) or leave it out")
  for arg, value in dict(root_args).items():
    check("root_args: the argument", arg, value)
  bound.setdefault(graph.root, []).append((None, None, None, dict(root_args)))
  out = {}
  for child, calls in bound.items():
    names = [sorted(args) for _, _, _, args in calls]
    if any(n != names[0] for n in names):
      raise GraphError(_differ(child, calls))
    out[child] = {arg: all(isinstance(args[arg], (int, np.integer)) for *_, args in calls)
                  for arg in names[0]}
    for arg in out[child]:
      if arg in FIXED:
        raise GraphError(f"subtask {child!r}: an argument may not be named {arg!r} (the "
                         "call's own field); rename it")
  for calls in bound.values():          # a binding's own refusals, knowing its parent's
    for parent, _, ref, _ in calls:     # call (what `bind` reads besides the observation)
      if ref is not None and ref.bind is not None:
        binding(parent, ref)[0].check(parent, ref.bind, out.get(parent, {}))
  return out
