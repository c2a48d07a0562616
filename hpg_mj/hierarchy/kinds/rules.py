"""A user's own rules as blocks: small `@numba.njit` functions of the observation and
the call (`call.<argument>`, `call.origin`, `call.steps`: `hierarchy.kinds.base`),
compiled into the graph's program, which runs them at the blocks' speed. Each value
they give is checked at the machine's boundary (`hierarchy.boundary`): a state out of
range, a float where an integer is due, a tuple of the wrong length or a NaN is one
line naming the node, the value and what was expected.

  Abstraction(rule)        a table learner's view: rule(obs, call) -> its state, an
                           integer in [0, n_states) (the paper's state abstraction)
  Features(rule)           a features learner's view (a GaussianCMAC's):
                           rule(obs, call) -> a tuple of numbers, as many as its
                           coder tiles (or one number)
  Termination(rule)        rule(obs, call) -> the call's event: 0 go on, 1 success,
                           -1 failure (a bool: True is a success)
  InternalReward(rule)     G: rule(obs, call, event) -> a number, after each child's
                           return (it never propagates to the parent)

and `blocks.Never()`, a termination that ends only with the episode (a root).
"""
import dataclasses

import numba

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base


def _check_rule(block):
  rule = block.rule
  if not isinstance(rule, numba.core.registry.CPUDispatcher):
    raise GraphError(f"{type(block).__name__}: rule {rule!r} is not a @numba.njit function; "
                     f"write it as {type(block).__name__}(numba.njit(your_function)) or "
                     "decorate it with @numba.njit")


@dataclasses.dataclass(frozen=True)
class Abstraction:
  """A table's state by `rule(obs, call)` -> an integer in [0, n_states)."""
  rule: object
  __post_init__ = _check_rule


@dataclasses.dataclass(frozen=True)
class Features:
  """The numbers a coder tiles, by `rule(obs, call)` -> a tuple of numbers."""
  rule: object
  __post_init__ = _check_rule


@dataclasses.dataclass(frozen=True)
class Termination:
  """The call's event by `rule(obs, call)` -> 0, 1 or -1 (or a bool)."""
  rule: object
  __post_init__ = _check_rule


@dataclasses.dataclass(frozen=True)
class InternalReward:
  """G by `rule(obs, call, event)` -> a number."""
  rule: object
  __post_init__ = _check_rule


def rule_name(block):
  """How a message names a rule block: `Features(goto_view)`."""
  rule = getattr(block, "rule", None)
  name = getattr(getattr(rule, "py_func", rule), "__name__", None)
  return f"{type(block).__name__}({name})" if name else type(block).__name__


class _Rule:
  """A kind whose operation is the user's rule itself (of (obs, call)), with no settings."""
  takes_settings = False

  def operation(self, block):
    return block.rule


class AbstractionKind(_Rule, base.ViewKind):
  """Runs an `Abstraction`: the user's rule gives a table's state."""
  block = Abstraction
  gives = "state"


class FeaturesKind(_Rule, base.ViewKind):
  """Runs a `Features`: the user's rule gives the numbers a coder tiles."""
  block = Features
  gives = "features"


class TerminationRuleKind(_Rule, base.TerminationKind):
  """Runs a `Termination`: the user's rule gives the call's event."""
  block = Termination


class InternalRewardKind(_Rule, base.RewardKind):
  """Runs an `InternalReward`: the user's rule gives G."""
  block = InternalReward


@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def never(P, obs, call, samples):
  """No event: the call goes on until the episode ends."""
  return 0


class NeverKind(base.TerminationKind):
  """Runs a `Never` termination (a root's)."""
  block = blocks.Never
  end = staticmethod(never)


KINDS = (AbstractionKind(), FeaturesKind(), TerminationRuleKind(), InternalRewardKind(),
         NeverKind())
