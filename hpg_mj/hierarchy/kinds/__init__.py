"""Block kinds: one module each (`hierarchy.kinds.base` says what a kind is), found
through one registration. `register(kind)` adds a kind, ours or a user's; `kind_of`
finds the kind of a block by its class (or a base class of it, where the subclass adds no
field the base's kind would ignore)."""
import dataclasses

from hpg_mj.hierarchy import graph
from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.hierarchy.kinds import base

ROLES = ("learner", "view", "termination", "reward", "available", "binding", "schedule")
_KINDS = {}          # (role, block class) -> kind


def register(kind):
  """Registers `kind` (an instance of a `hierarchy.kinds.base.Kind` subclass) for the
  blocks of its class `kind.block` in its `kind.role`; returns it. A kind registered
  again for the same block and role replaces the earlier one (a user's module run
  twice in a notebook)."""
  if not isinstance(kind, base.Kind):
    raise TypeError(f"register: {kind!r} is not a hpg_mj.hierarchy.kinds.base.Kind")
  if kind.role not in ROLES:
    raise ValueError(f"register: {type(kind).__name__}.role = {kind.role!r}; allowed: "
                     f"{list(ROLES)}")
  if not isinstance(kind.block, type):
    raise TypeError(f"register: {type(kind).__name__}.block = {kind.block!r}: must be the "
                    "class of the blocks it runs")
  ops = {"learner": ("start", "choose", "observe"), "schedule": ("run_ended", "episode_ended",
                                                                  "decided")}.get(kind.role, ())
  for op in ops:
    if getattr(kind, op, None) is None:
      raise TypeError(f"register: {type(kind).__name__}.{op} is missing: a {kind.role} kind "
                      "gives its compiled operations (hpg_mj.hierarchy.kinds.base)")
  _KINDS[(kind.role, kind.block)] = kind
  if kind.role == "learner":
    graph.MACHINE_LEARNERS.add(kind.block)
  return kind


def kind_of(block, role, node):
  """The kind of `block` in `role` for subtask `node`; a one-line GraphError naming the
  node and the registered blocks when there is none."""
  for cls in type(block).__mro__:
    kind = _KINDS.get((role, cls))
    if kind is not None:
      _check_inherited(block, cls, kind, role, node)
      return kind
  known = sorted(cls.__name__ for (r, cls) in _KINDS if r == role)
  raise GraphError(f"subtask {node!r}: its {role} {type(block).__name__} has no kind on the "
                   f"open machine; registered {role}s: {known} "
                   "(hpg_mj.hierarchy.kinds.register adds one)")


def _check_inherited(block, cls, kind, role, node):
  """A subclass of a registered block runs by its base's kind only where it adds no
  field: a field of its own (a variant's new step size, say) would be ignored, the
  base's algorithm run as if it were not there."""
  if cls is type(block) or not dataclasses.is_dataclass(block):
    return
  base_fields = {f.name for f in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) \
      else set()
  own = [f.name for f in dataclasses.fields(block) if f.name not in base_fields]
  if own:
    raise GraphError(f"subtask {node!r}: its {role} {type(block).__name__} adds {own} to "
                     f"{cls.__name__}, whose kind ({type(kind).__name__}) would run it "
                     f"ignoring them; register a kind for {type(block).__name__} "
                     "(hpg_mj.hierarchy.kinds.register)")


def _register_shipped():
  from hpg_mj.hierarchy.kinds import (actor_critic, epsilon, gate_frame, gate_point,
                                      gate_route, gaussian_cmac, gibbs_table, grid_cell,
                                      local_frame, option_critic, option_critic_cmac, patrol,
                                      q_table, rules, state_tiles, taxi, tiled_q)
  for kind in (q_table.QTableKind(), gaussian_cmac.GaussianCMACKind(),
               actor_critic.ActorCriticKind(), gibbs_table.GibbsTableKind(),
               tiled_q.TiledQTableKind(), *gate_frame.KINDS, *gate_point.KINDS,
               *gate_route.KINDS, *patrol.KINDS, *option_critic.KINDS,
               *option_critic_cmac.KINDS, *rules.KINDS,
               grid_cell.GridCellKind(), local_frame.LocalTilesKind(), local_frame.LocalGoalKind(),
               local_frame.ShapingKind(), state_tiles.StateTilesKind(), *taxi.KINDS,
               epsilon.HeldEpsilonKind(), epsilon.LinearEpsilonKind()):
    register(kind)


_register_shipped()
