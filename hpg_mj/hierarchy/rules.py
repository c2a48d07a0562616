"""A graph's user rules (`blocks.CellRule`, `EndRule`, `RewardRule`) compiled into one
first-class function, `rules(which, obs, origin, arg, steps, event) -> float`, that the
machine calls for rule number `which`. The machine takes it as an argument of one
fixed type, so a user's rules compile on their own (well under a second) and the
machine itself is compiled once, cached, for every graph."""
import functools

import numba
import numpy as np
from numba import types
from numba.core import errors

from hpg_mj.hierarchy.graph import GraphError

SIGNATURE = types.float64(types.int64, types.float64[::1], types.float64[::1], types.int64,
                          types.int64, types.int64)
# What a rule is called with: (obs, origin, arg, steps), and the event for a RewardRule.
_STATE_ARGS = (types.float64[::1], types.float64[::1], types.int64, types.int64)
VIEW, END, REWARD = "CellRule", "EndRule", "RewardRule"


def _nothing(which, obs, origin, arg, steps, event):
  return 0.0


@functools.cache
def nothing():
  """The rules of a graph that has none (never called)."""
  return numba.cfunc(SIGNATURE, cache=True)(_nothing)


def _link(rest, which, kind, rule):
  """Rule number `which`, else the rules before it (`rest`)."""
  if kind == REWARD:
    @numba.njit
    def link(w, obs, origin, arg, steps, event):
      if w == which:
        return np.float64(rule(obs, origin, arg, steps, event))
      return rest(w, obs, origin, arg, steps, event)
  else:
    @numba.njit
    def link(w, obs, origin, arg, steps, event):
      if w == which:
        return np.float64(rule(obs, origin, arg, steps))
      return rest(w, obs, origin, arg, steps, event)
  return link


def check(node, kind, rule):
  """Refuses, naming the node, a rule that is not an `@numba.njit` function of
  the rule's arguments returning a number."""
  if not isinstance(rule, numba.core.registry.CPUDispatcher):
    raise GraphError(f"subtask {node!r}: its {kind}'s rule must be an @numba.njit function; "
                     f"got {rule!r}")
  args = _STATE_ARGS + ((types.int64,) if kind == REWARD else ())
  names = "obs, origin, arg, steps" + (", event" if kind == REWARD else "")
  try:
    rule.compile(args)
  except (errors.NumbaError, TypeError) as err:
    lines = [ln.strip() for ln in str(err).splitlines() if ln.strip()]
    first = next((ln for ln in lines if not ln.startswith("Failed in")), lines[0])
    raise GraphError(f"subtask {node!r}: its {kind}'s rule {rule.__name__} cannot be compiled "
                     f"for ({names}) = (float64 array, float64 array, int, int"
                     f"{', int' if kind == REWARD else ''}): {first}") from None
  returned = [c.signature.return_type for c in rule.overloads.values()
              if tuple(c.signature.args) == args][0]
  if not isinstance(returned, (types.Integer, types.Float, types.Boolean)):
    raise GraphError(f"subtask {node!r}: its {kind}'s rule {rule.__name__} returns {returned}; "
                     "a rule returns one number")


_compiled = {}      # (kind, rule) of each, in order -> their function, for this process


def compile_rules(rules):
  """The first-class function of `rules`, a list of (node, kind, rule), numbered by
  their place in it; compiled once a process for the same rules in the same order
  (an experiment builds its agents' graphs again and again)."""
  if not rules:
    return nothing()
  for node, kind, rule in rules:
    check(node, kind, rule)
  key = tuple((kind, rule) for _, kind, rule in rules)
  if key not in _compiled:
    chain = numba.njit(_nothing)
    for which, (kind, rule) in enumerate(key):
      chain = _link(chain, which, kind, rule)

    def entry(which, obs, origin, arg, steps, event):
      return chain(which, obs, origin, arg, steps, event)
    _compiled[key] = numba.cfunc(SIGNATURE)(entry)
  return _compiled[key]
