"""The open machine: a task graph of blocks compiled into one program of its own.

`Program(graph)` finds each block's kind (`hierarchy.kinds`), checks the graph
against them (one line naming the node for anything that cannot run), lays out
their arrays by name, and writes the graph's operations (`enter`, `resume`, `judge`,
`chosen`: a chain over the graph's nodes calling each node's kinds, with its
arguments bound as constants) below the text of Algorithm 1 (`hierarchy.algorithm`),
as one module of its own that numba compiles: only the kinds the graph holds, a
user's rules and kinds among them, are typed at all, and the algorithm never asks
which kind a node holds. The module is a file in the cache folder (`graph_module`),
named by a hash of everything it compiles, so numba's cache keeps its machine code
between processes; a change to the algorithm, a kind or a user's file gives another
name.

Subtasks take named arguments: `Child("goto", x=300.0, y=700.0)` binds `x` and `y`
for that call, and the subtask's rules read `call.x`, `call.y` (`hierarchy.kinds.base`).
Every `Child` of one subtask binds the same names; an argument is an integer where
every binding of it is, else a float.

The learned arrays are saved and restored by name (`state()`, `parameters()`):
`"<node>.<field>"`, the node the first that holds the learner (the graph's order).
"""
import collections
import inspect
import os
import re

import numba
import numpy as np

from hpg_mj import _collector
from hpg_mj import _stack
from hpg_mj.hierarchy import algorithm
from hpg_mj.hierarchy import arguments
from hpg_mj.hierarchy import boundary
from hpg_mj.hierarchy import calls
from hpg_mj.hierarchy import graph_module
from hpg_mj.hierarchy import kinds as kinds_mod
from hpg_mj.hierarchy.graph import GraphError, Primitive
from hpg_mj.hierarchy.kinds import rules as rules_mod
from hpg_mj.learners import banks
from hpg_mj.worlds import ship_core as core

_F64 = np.dtype(np.float64)
_ROLES = {"view": "view", "termination": "termination", "reward": "internal reward",
          "available": "available", "binding": "binding"}
_ROWS = ("x", "args", "origin", "steps", "choice", "action", "mask")   # a node's rows of M
_VECTOR, _ROWS_OF_XY = (8,), (16, 8)          # the strides of a float64 vector, of rows of (x, y)


def _index(items, item):
  """The index of `item` in `items`, added at the end if it is not there."""
  if item not in items:
    items.append(item)
  return items.index(item)


def _identifier(name):
  out = "".join(c if c.isalnum() else "_" for c in name)
  return out if out and not out[0].isdigit() else "n_" + out


class _Node:
  """What the program knows of one subtask while it writes its operations."""

  def __init__(self, name, index, node):
    self.name, self.index, self.node = name, index, node
    self.ident = _identifier(name)


def _named(name, method, *args, **kwargs):
  """`method(*args, **kwargs)` of a kind at subtask `name`, its block's refusal (a
  GraphError, a ValueError) named there: a block alone cannot know where it is used."""
  try:
    return method(*args, **kwargs)
  except ValueError as err:
    if type(err) not in (GraphError, ValueError) or str(err).startswith("subtask "):
      raise
    raise type(err)(f"subtask {name!r}: {err}") from None


class Program:
  """A task graph of blocks compiled by the open machine (see the module docstring).

  `root_args`: the root call's arguments, by name. `obs_size`: the length of the
  observation it runs on (4: the ship's x, y, theta, theta rate). `world`: the
  world's own settings, given to the kinds that read it (a kind whose `settings`
  takes a `world` parameter: the taxi's, `taxi_rules.world_config`), and to
  `run_taxi`. `fused`: a ladder task's world (`hierarchy.ladder.World`), whose functions
  the graph's module binds (`run_world`) and whose observation the program's."""

  def __init__(self, graph, root_args=None, obs_size=4, world=None, fused=None):
    self.graph, self.fused = graph, fused
    self.obs_size = int(obs_size if fused is None else fused.obs_size)
    self.world = world
    # The root last (the agents' records read the nodes' counters so).
    self.names = [n for n in graph.nodes if n != graph.root] + [graph.root]
    self.index = {name: i for i, name in enumerate(self.names)}
    self._functions = {}            # id -> (global name, function)
    self._whats = []                # fault record's `what` -> (node, what, allowed)
    self._roles = {}                # a rule's global name -> its role ("view Features(aim)")
    self._learners = {}             # id(block) -> slot
    self._learner_blocks = []       # (block, kind, first node)
    self._records = []              # (field of G, value)
    self._lines = []
    self._root_args = dict(root_args or {})
    self._arguments = arguments.collect(graph, self._root_args)
    self._schedule()
    self._subtasks = [_Node(name, self.index[name], n) for name, n in graph.nodes.items()
                      if not isinstance(n, Primitive)]
    for s in self._subtasks:
      self._resolve(s)
    self._frames()
    self._write()
    self._module = self._load()
    # Each record, and the graph of them, as a struct the compiled code takes by
    # reference (`learners.banks`): passed by value, the hybrid's ~80 arrays were copied
    # at every call of the graph's operations, and it trained at a third of its speed.
    records = banks.as_structs(self.frames, *[value for _, value in self._records])
    self.G = banks.as_structs(self._module.Graph(*records))[0]

  # -- the graph, checked against its kinds --

  def _schedule(self):
    """The graph's exploration schedule (a held epsilon of 0.1 by default, as
    the shipped hierarchies'), its watched subtasks checked."""
    from hpg_mj.hierarchy import blocks
    block = self.graph.schedule or blocks.HeldEpsilon()
    self.schedule_block = block
    self.schedule_kind = kinds_mod.kind_of(block, "schedule", "the graph's schedule")
    for name in self.schedule_kind.watch(block):
      if name not in self.graph.nodes or isinstance(self.graph.nodes[name], Primitive):
        raise GraphError(f"the epsilon schedule watches {name!r}, which is not a subtask of the "
                         f"graph; subtasks: {sorted(n.name for n in self.graph.subtasks())}")
    self.schedule = self.schedule_kind.record(block)

  def _resolve(self, s):
    """The node's kinds, checked against each other and its children."""
    node, name = s.node, s.name
    refs = self.graph.children(name)
    s.n_children = len(refs)
    s.learner = kinds_mod.kind_of(node.learner, "learner", name)
    s.view = kinds_mod.kind_of(node.view, "view", name)
    s.end = kinds_mod.kind_of(node.termination, "termination", name)
    s.reward = (None if node.internal_reward is None else
                kinds_mod.kind_of(node.internal_reward, "reward", name))
    s.offer = (None if node.available is None else
               kinds_mod.kind_of(node.available, "available", name))
    if s.offer is not None and not s.learner.masked:
      raise GraphError(f"subtask {name!r}: its learner {type(node.learner).__name__} chooses "
                       "among all its children; an `available` needs a learner that reads "
                       "a mask of them (a kind with masked = True: GibbsTable)")
    if s.offer is not None and s.learner.masked == "prefix" and not s.offer.prefix:
      raise GraphError(f"subtask {name!r}: its learner {type(node.learner).__name__} offers a "
                       "state's first k children, and its available "
                       f"{type(node.available).__name__} may offer any (a kind with prefix = "
                       "True: NearGateLine)")
    if node.on_exit is not None:
      raise GraphError(f"subtask {name!r}: `on_exit` is a Python function, which the open "
                       "machine cannot compile; leave it None")
    from hpg_mj.hierarchy import blocks
    if node.reward not in (None, blocks.SUMMED, blocks.STEP):
      raise GraphError(f"subtask {name!r}: reward = {node.reward!r}; allowed: "
                       f"{blocks.SUMMED!r} (the child's rewards summed), {blocks.STEP!r} (-1 "
                       "a primitive step)")
    s.seen_step = node.reward == blocks.STEP
    continuous = [isinstance(self.graph.nodes[r.node], Primitive) and
                  self.graph.nodes[r.node].action is None for r in refs]
    if s.learner.continuous:
      if len(refs) != 1 or not continuous[0]:
        raise GraphError(f"subtask {name!r}: its learner {type(node.learner).__name__} draws "
                         "a continuous action: its one child must be a Primitive without an "
                         f"action; children: {[r.node for r in refs]}")
    elif any(continuous):
      raise GraphError(f"subtask {name!r}: its learner {type(node.learner).__name__} chooses "
                       "among its children; a Primitive without an action (a continuous one) "
                       "needs a learner that draws values (GaussianCMAC); a discrete one "
                       "gives its action: Primitive(name, action=i)")
    if s.view.gives != s.learner.reads:
      raise GraphError(f"subtask {name!r}: its learner {type(node.learner).__name__} reads "
                       f"{s.learner.reads}, its view {rules_mod.rule_name(node.view)} gives "
                       f"{s.view.gives}")
    bound = self._arguments.get(name, {})
    if s.offer is not None:
      _named(name, s.offer.check, name, node.available, bound)
    _named(name, s.view.check, name, node.view, bound)
    _named(name, s.end.check, name, node.termination, bound)
    if s.reward is not None:
      _named(name, s.reward.check, name, node.internal_reward, bound)
      if s.reward.from_termination and not s.end.gives_internal:
        raise GraphError(f"subtask {name!r}: its internal reward {type(node.internal_reward).__name__}"
                         f" is the G of its termination, and {type(node.termination).__name__} "
                         "gives none")
    size = self._given(s.view.size, name, node.view, node.view)
    _named(name, s.learner.check, name, node.learner, s.n_children, size)
    s.size = kinds_mod.base.checked_size(name, node.learner, s.learner.size(node.learner))

  # -- the text of the graph's operations --

  def _function(self, fn):
    """The global name the module gives `fn` (a user's bounds checked: `boundary`)."""
    if id(fn) not in self._functions:
      self._functions[id(fn)] = (f"_f{len(self._functions)}", boundary.bounds_checked(fn))
    return self._functions[id(fn)][0]

  def _record(self, field, value):
    self._records.append((field, value))
    return f"G.{field}"

  def _what(self, node, what, allowed):
    self._whats.append((node, what, allowed))
    return len(self._whats) - 1

  # Each operation is one function whose branch for each node holds that node's code
  # (its variables suffixed with the node's number): written as functions of their
  # own, a node's pieces were ~6 a node more for numba to type and LLVM to compile,
  # a third of a graph's first compile.

  def _call_text(self, s):
    """The text of the call record of subtask `s` (its arguments, origin, steps)."""
    args = self._arguments.get(s.name, {})
    cls = f"calls.{calls.name_of(tuple(args))}" if args else "calls.Call"
    values = [f"np.int64(M.args[{s.index}, {k}])" if is_int else f"M.args[{s.index}, {k}]"
              for k, is_int in enumerate(args.values())]
    values += [f"M.origin[{s.index}]", f"M.steps[{s.index}]"]
    return f"{cls}({', '.join(values)})"

  def _given(self, method, name, block, *args):
    """`method(*args)` of a kind; one whose parameters include `schedule`, `world`,
    `learned_episodes` or `obs_size` is given the graph's schedule record, the program's
    world, the live count of learning episodes ended (an int64[1]: a step size's
    warm-up), or the observation's length (what a view may read of it)."""
    given = {"schedule": lambda: self.schedule, "world": lambda: self.world,
             "obs_size": lambda: self.obs_size,
             "learned_episodes": lambda: self.frames.episode[algorithm.E_LEARNED:][:1],
             "node": lambda: self.graph.nodes[name],
             "child_steps": lambda: self.frames.child_steps[self.index[name]:][:1]}
    asked = inspect.signature(method).parameters
    extra = {key: value() for key, value in given.items() if key in asked}
    if "world" in extra and self.world is None:
      raise GraphError(f"subtask {name!r}: its {type(block).__name__} reads the world's "
                       "settings, and this program was built without them (Program(graph, "
                       "world=...): the taxi's taxi_rules.world_config)")
    return _named(name, method, *args, **extra)

  def _settings(self, kind, name, block):
    """A kind's settings for `block` at subtask `name` (`_given`)."""
    return self._given(kind.settings, name, block, name, block)

  def _op(self, kind, block, field, s):
    """(the function's global name, its settings' text or None) of a view, end or reward."""
    fn = self._function(kind.operation(block))
    self._roles.setdefault(fn, f"{_ROLES[kind.role]} {rules_mod.rule_name(block)}")
    if not kind.takes_settings:
      return fn, None
    return fn, self._record(f"{field}{s.index}", self._settings(kind, s.name, block))

  def _view_lines(self, s):
    """Lines that view the state into `x<i>` (a state), or into M.x[i] (features)."""
    node, i = s.node, s.index
    if not hasattr(s, "_view_op"):
      s._view_op = self._op(s.view, node.view, "V", s)
      name = rules_mod.rule_name(node.view)
      s._view_what = self._what(
          s.name, f"view {name}", f"an integer state in [0, {s.size})" if s.view.gives == "state"
          else f"a tuple of {s.size} finite numbers (its {type(node.learner).__name__} reads "
          f"{s.size})")
    fn, settings = s._view_op
    call = self._call_text(s)
    args = ", ".join([settings, "M.obs", call, "M.samples"] if settings else ["M.obs", call])
    if s.view.gives == "state":
      return [f"x{i} = boundary.as_state({fn}({args}), np.int64({s.size}), M.fault, "
              f"_w{s._view_what})",
              f"M.x[{i}, 0] = x{i}"]
    if s.view.writes:
      return [f"{fn}({args}, M.x[{i}, :{s.size + s.view.reflects}])"]
    return [f"boundary.as_features({fn}({args}), M.x[{i}, :{s.size}], M.fault, "
            f"_w{s._view_what})"]

  def _x(self, s):
    """The node's view as its learner reads it (after `_view_lines`)."""
    return f"x{s.index}" if s.view.gives == "state" else f"M.x[{s.index}, :{s.size}]"

  def _learner(self, s):
    """(P, L, N) texts of the node's learner, its records made once per block."""
    block = s.node.learner
    if id(block) not in self._learners:
      slot = len(self._learner_blocks)
      self._learners[id(block)] = slot
      self._learner_blocks.append((block, s.learner, s.name))
      self._record(f"P{slot}", self._settings(s.learner, s.name, block))
      self._record(f"L{slot}", s.learner.learned(block, s.n_children))
    else:
      slot = self._learners[id(block)]
      first = self._learner_blocks[slot][2]
      fresh = s.learner.learned(block, s.n_children)
      same = dict(self._records)[f"L{slot}"]
      if any(np.shape(a) != np.shape(b) for a, b in zip(fresh, same)):
        raise GraphError(f"subtask {s.name!r} shares its learner with {first!r}, which has "
                         "another number of children or states; a shared learner serves "
                         "nodes of the same shape")
    self._record(f"N{s.index}", self._given(s.learner.scratch, s.name, block, block,
                                            s.n_children))
    return f"G.P{slot}", f"G.L{slot}", f"G.N{s.index}"

  def _settle(self, s):
    if s.learner.continuous and s.view.reflects:          # the action's sign, at x[size]
      return f"M.action[{s.index}] = v{s.index} * M.x[{s.index}, {s.size}]"
    if s.learner.continuous:
      return f"M.action[{s.index}] = v{s.index}"
    if not hasattr(s, "_choice_what"):
      s._choice_what = self._what(s.name, f"learner {type(s.node.learner).__name__}",
                                  f"a child's index in [0, {s.n_children})")
    return (f"M.choice[{s.index}] = boundary.as_choice(v{s.index}, np.int64({s.n_children}), "
            f"M.fault, _w{s._choice_what})")

  def _offer_lines(self, s):
    """Lines that write the children `s` may choose now into its mask (its `available`)."""
    if s.offer is None:
      return []
    if not hasattr(s, "_offer_op"):
      s._offer_op = self._op(s.offer, s.node.available, "A", s)
    fn, settings = s._offer_op
    args = ", ".join(([settings] if settings else []) +
                     ["M.obs", self._call_text(s), f"M.mask[{s.index}, :{s.n_children}]"])
    return [f"{fn}({args})"]

  def _n(self, s):
    """The learner's `n` (its number of children, a constant compiled into the kind's
    code), and its mask if it reads one."""
    return (f"{s.n_children}, M.mask[{s.index}, :{s.n_children}]" if s.learner.masked else
            f"{s.n_children}")

  def _enter_lines(self, s):
    i, (P, Lr, N) = s.index, s._records
    start, choose = self._function(s.learner.start), self._function(s.learner.choose)
    return [f"# {s.name}: z <- 0, its view, its first choice", f"{start}({P}, {Lr}, {N})",
            *self._view_lines(s), *self._offer_lines(s),
            f"v{i} = {choose}({P}, {Lr}, {N}, {self._x(s)}, {self._n(s)}, M.rng, "
            "M.flags[0], M.flags[1])", self._settle(s)]

  def _resume_lines(self, s):
    i, (P, Lr, N) = s.index, s._records
    observe = self._function(s.learner.observe)
    # A learner that bootstraps past its call's own end (an option's critic) sees s'
    # as terminal only where the world's episode ended.
    term = "terminated" if s.learner.bootstraps_at_own_end else "terminal"
    if s.view.gives == "state":
      view = [f"x{i} = np.int64(M.x[{i}, 0])", f"if not {term}:",
              *["  " + line for line in self._view_lines(s)]]
    else:
      view = [f"if not {term}:", *["  " + line for line in self._view_lines(s)]]
    offer = self._offer_lines(s)
    view += ["if not done:", *["  " + line for line in offer]] if offer else []
    return [f"# {s.name}: its learner takes R + G in s' and, unless done, chooses again",
            *view,
            f"v{i} = {observe}({P}, {Lr}, {N}, {self._x(s)}, signal, done, {term}, "
            f"{self._n(s)}, M.rng, M.flags[0], M.flags[1])",
            "if not done:", "  " + self._settle(s)]

  def _judge_lines(self, s):
    node, i = s.node, s.index
    end, end_settings = self._op(s.end, node.termination, "T", s)
    args = ", ".join([end_settings, "M.obs", f"call{i}", "M.samples"] if end_settings else
                     ["M.obs", f"call{i}"])
    if s.end.draws:
      args += ", M.rng"
    what = self._what(s.name, f"termination {rules_mod.rule_name(node.termination)}",
                      "0 (go on), 1 (success), -1 (failure) or a bool")
    lines = [f"# {s.name}: its event and G after a child returned",
             f"call{i} = {self._call_text(s)}",
             f"said{i}, shaped{i} = {end}({args})" if s.end.gives_internal else
             f"said{i} = {end}({args})",
             f"event{i} = boundary.as_event(said{i}, M.fault, _w{what})"]
    if s.reward is None:
      return lines + [f"return event{i}, 0.0"]
    if s.reward.from_termination:
      return lines + [f"return event{i}, shaped{i}"]
    fn, settings = self._op(s.reward, node.internal_reward, "R", s)
    args = ", ".join([settings, "M.obs", f"call{i}", f"event{i}", "M.samples"] if settings else
                     ["M.obs", f"call{i}", f"event{i}"])
    what = self._what(s.name, f"internal reward {rules_mod.rule_name(node.internal_reward)}",
                      "a finite number")
    return lines + [f"return event{i}, boundary.as_reward({fn}({args}), M.fault, _w{what})"]

  def _chosen_lines(self, s):
    if s.learner.continuous:
      return [f"# {s.name}: its continuous primitive", "return -1"]
    lines = [f"# {s.name}: the child it chose, its arguments bound"]
    for k, ref in enumerate(self.graph.children(s.name)):
      child = self.graph.nodes[ref.node]
      lines.append(f"{'if' if k == 0 else 'elif'} M.choice[{s.index}] == {k}:")
      if isinstance(child, Primitive):
        lines += [f"  M.action[{s.index}] = {float(child.action)!r}", "  return -1"]
        continue
      c = self.index[ref.node]
      names = []
      if ref.bind is not None:
        kind, names = arguments.binding(s.name, ref)
        fn, settings = self._op(kind, ref.bind, f"B{s.index}_{k}_", s)
        args = ", ".join(([settings] if settings else []) + ["M.obs", self._call_text(s)])
        like = "".join("0, " if is_int else "0.0, " for is_int in names.values())
        whole = [a for a, is_int in names.items() if is_int]
        what = self._what(s.name, f"child {k} ({ref.node!r}) bound by {type(ref.bind).__name__}",
                          f"a tuple of {len(names)} finite number{'s' if len(names) != 1 else ''}"
                          f", one for each of its names {list(names)}" +
                          (f" ({', '.join(whole)} whole)" if whole else ""))
        lines.append(f"  bound = boundary.as_bound({fn}({args}), ({like.rstrip(' ')}), M.fault, "
                     f"_w{what})")
        names = list(names)
      lines += [f"  M.args[{c}, {j}] = {float(ref.args[arg])!r}" if arg in ref.args else
                f"  M.args[{c}, {j}] = bound[{names.index(arg)}]"
                for j, arg in enumerate(self._arguments.get(ref.node, {}))]
      lines.append(f"  return {c}")
    return lines + ["return -1"]

  def _operation(self, L, op, params, doc, lines_of, otherwise):
    """The function `op` of the graph. Nodes whose code differs only in their row, their
    records and their fault codes share one branch, their records chosen by node: numba
    types it and LLVM compiles it once, not once a node (`_shared`)."""
    L += ["@numba.njit(**_JIT)", f"def {op}(G, node{params}):", f'  """{doc}"""', "  M = G.M"]
    branches = {}
    for s in self._subtasks:
      own = lines_of(s)
      text, records, whats = self._shared(s, own)
      types = tuple(numba.typeof(dict(self._records)[r[2:]]) for r in records)
      branches.setdefault((text, types), []).append((s, own, records, whats))
    for k, ((text, _), nodes) in enumerate(branches.items()):
      L.append(f"  {'if' if k == 0 else 'elif'} " +
               " or ".join(f"node == {s.index}" for s, *_ in nodes) + ":")
      if len(nodes) == 1:                     # its row, records and codes as constants
        L += ["    " + re.sub(r"\b_w(\d+)\b", r"np.int64(\1)", line) for line in nodes[0][1]]
        continue
      L.append(f"    # {', '.join(s.name for s, *_ in nodes)}{text[0][text[0].index(':'):]}")
      for j, (s, _, records, whats) in enumerate(nodes if nodes[0][2] or nodes[0][3] else []):
        L.append("    else:" if j == len(nodes) - 1 else
                 f"    {'if' if j == 0 else 'elif'} node == {s.index}:")
        L += [f"      r{n}_{k} = {r}" for n, r in enumerate(records)]
        L += [f"      w{n}_{k} = np.int64({w})" for n, w in enumerate(whats)]
      L += ["    " + line.replace("_@", f"_{k}") for line in text[1:]]
    L += [f"  return {otherwise}", "", ""]

  def _shared(self, s, lines):
    """(the text of `s`'s lines as nodes of its shape share it, its records, its fault
    codes): its row `node`, its variables `x_@`, ..., its records `r0_@`, ... and its
    codes `w0_@`, ... (its first line, a comment, names it)."""
    text, records, whats = "\n".join(lines), [], []
    text = re.sub(rf"(M\.(?:{'|'.join(_ROWS)}))\[{s.index}([,\]])", r"\1[node\2", text)
    text = re.sub(rf"\b(x|v|call|said|shaped|event){s.index}\b", r"\1_@", text)
    text = re.sub(r"\bG\.\w+", lambda m: f"r{_index(records, m.group(0))}_@", text)
    text = re.sub(r"\b_w(\d+)\b", lambda m: f"w{_index(whats, int(m.group(1)))}_@", text)
    lines = text.split("\n")
    return (lines[0].replace(s.name, "", 1), *lines[1:]), records, whats

  def _schedule_text(self, L):
    """The schedule's hooks: a watched subtask's run ended, the episode, a decision."""
    kind = self.schedule_kind
    S = self._record("S", self.schedule)
    # A graph without a schedule of its own whose learners follow none (flat PGRL, the
    # actor-critic) compiles none of the default's code: nothing would read it.
    followed = self.graph.schedule is not None or any(
        getattr(s.node.learner, "epsilon_schedule", False) for s in self._subtasks)
    if not followed:
      L += ["@numba.njit(**_JIT)", "def schedule_run(G, node, success):", "  return None",
            "", "", "@numba.njit(**_JIT)", "def schedule_episode(G, learned):",
            "  return None", "", "", "@numba.njit(**_JIT)", "def schedule_decided(G):",
            "  return None", "", ""]
      return
    run, episode, decided = (self._function(f) for f in (kind.run_ended, kind.episode_ended,
                                                          kind.decided))
    L += ["@numba.njit(**_JIT)", "def schedule_run(G, node, success):",
          '  """A subtask\'s run ended: the schedule notes it if it watches the subtask."""']
    for k, name in enumerate(kind.watch(self.schedule_block)):
      L.append(f"  {'if' if k == 0 else 'elif'} node == {self.index[name]}:")
      L.append(f"    {run}({S}, np.int64({k}), success)")
    L += ["  return None", "", "",
          "@numba.njit(**_JIT)", "def schedule_episode(G, learned):",
          f"  {episode}({S}, learned)", "", "",
          "@numba.njit(**_JIT)", "def schedule_decided(G):",
          f"  {decided}({S})", "", ""]

  def _write(self):
    L = ["", "", "# ---- the graph's operations (hierarchy.program) ----", ""]
    for s in self._subtasks:
      s._records = self._learner(s)
    self._operation(L, "enter", "", "The call of `node` begins: z <- 0, its view, its first "
                    "choice.", self._enter_lines, "None")
    self._operation(L, "resume", ", signal, done, terminal, terminated", "The learner of "
                    "`node` takes R + G = `signal` in s' and, unless `done`, chooses again.",
                    self._resume_lines, "None")
    self._operation(L, "judge", "", "After a child of `node` returned: (its event, G).",
                    self._judge_lines, "(0, 0.0)")
    self._operation(L, "chosen", "", "The child `node` chose (-1: a primitive, its action in "
                    "M.action[node]), its arguments bound.", self._chosen_lines, "-1")
    self._schedule_text(L)
    seen = tuple(bool(getattr(s, "seen_step", False)) for s in self._by_index())
    L.append(f"ROOT = {self.index[self.graph.root]}")
    L.append(f"SEEN_STEP = {seen!r}")
    root = next(s for s in self._subtasks if s.name == self.graph.root)
    L.append(f"CONTINUING = {bool(root.end.continuing)!r}")
    if self.fused is not None:              # only this world is compiled in (`run_world`)
      L += [f"{name} = {self._function(fn)}" for name, fn in self.fused.functions.items()]
    fields = ["M"] + [f for f, _ in self._records]
    L.append(f"Graph = collections.namedtuple('Graph', {tuple(fields)!r})")
    self._text = "\n".join(L) + "\n"

  def _by_index(self):
    by = {s.index: s for s in self._subtasks}
    return [by.get(i) or _Node(n, i, None) for i, n in enumerate(self.names)]

  # -- the state and the module --

  def _frames(self):
    n = len(self.names)
    depth = self.graph.depth()
    n_args = max([len(a) for a in self._arguments.values()] + [1])
    size = max([s.size + s.view.reflects if s.view.gives == "features" else 1
                for s in self._subtasks] + [1])
    self.frames = algorithm.Frames(
        stack=np.zeros(depth, dtype=np.int64), choice=np.zeros(n, dtype=np.int64),
        action=np.zeros(n), steps=np.zeros(n, dtype=np.int64),
        child_steps=np.zeros(n, dtype=np.int64), reward=np.zeros(n),
        origin=np.zeros((n, self.obs_size)), args=np.zeros((n, n_args)),
        x=np.zeros((n, size)), counters=np.zeros((n, 3)),
        episode=np.zeros(5, dtype=np.int64), total=np.zeros(1),
        flags=np.zeros(2, dtype=np.bool_), rng=np.zeros(4, dtype=np.uint64),
        fault=np.zeros(4), obs=np.zeros(self.obs_size),
        samples=np.zeros((core.SAMPLES_PER_CONTROL + 1, 2)), board=np.zeros(8, dtype=np.int64),
        mask=np.ones((n, max([s.n_children for s in self._subtasks] + [1])), dtype=np.bool_),
        restart=np.zeros(self.obs_size), ops=np.zeros(3, dtype=np.int64))
    root = self.index[self.graph.root]
    for j, arg in enumerate(self._arguments.get(self.graph.root, {})):
      self.frames.args[root, j] = float(self._root_args[arg])

  def _load(self):
    """The graph's module: Algorithm 1's text and the graph's operations, with the
    user's functions as its globals (`graph_module.load`)."""
    with open(algorithm.__file__) as f:
      text = f.read() + self._text
    module, self.module_path, self.cached = graph_module.load(
        text, dict(self._functions.values()), [type(v) for _, v in self._records])
    return module

  # -- running --

  def _flags(self, learn, sample):
    if (learn, sample) != self._flags_set:
      self.frames.flags[0] = bool(learn)
      self.frames.flags[1] = bool(sample)
      self._flags_set = (learn, sample)

  _flags_set = (None, None)

  def _run(self, fn, *args):
    """A compiled entry point, a boundary fault raised as its one line. The first in a
    process compiles the graph's operations before it (`graph_module.link`)."""
    try:
      if self._linked_in != os.getpid():
        with _collector.paused():              # (one collection after all the compiles)
          _stack.roomy(graph_module.link, self._module, self.G, self.frames.ops)
          self._linked_in = os.getpid()
          return _stack.roomy(fn, self.G, *args)
      return fn(self.G, *args)
    except (ValueError, IndexError) as e:
      self._explain(e)
    # (the first call compiles the module; an AttributeError is numba's, typing a user's
    # `math.no_such_name`)
    except (numba.core.errors.TypingError, AttributeError) as e:
      line = boundary.compile_error_line(e, self.module_path, self._roles, self.names,
                                         self._arguments)
      if line is None:
        raise
      raise GraphError(line) from None

  _linked_in = None     # the process whose addresses `Frames.ops` holds

  def _explain(self, error):
    """Raises a boundary fault (`hierarchy.boundary`), or a user's read past an array's
    end (`boundary.read_past`), as its one line; else `error`."""
    if isinstance(error, IndexError):
      raise boundary.read_past(error, self._functions.values(), self._roles,
                               self.obs_size) from None
    if str(error) == boundary.FAULT_MESSAGE:
      raise ValueError(boundary.explain(self.frames.fault, self._whats)) from None
    raise error

  def _stepwise(self, fn, *args):
    """`_run` of a step-by-step entry point, after its first call straight through the
    machine code numba compiled for these arguments' types: the dispatcher types every
    argument at each call (the graph's struct among them), a seventh of a control step
    through the MuJoCo ship. Only for arguments of the kinds `_arrays` makes (float64
    arrays in C order, Python's float and bool) and the generator state last seen (its
    kind read once): any other goes through the dispatcher."""
    rng_state = args[-1]
    entry = self._entry_points.get(fn) if rng_state is self._rng_seen else None
    if entry is None:
      out = self._run(fn, *args)
      found = fn.overloads.get(tuple(numba.typeof(a) for a in (self.G, *args)))
      if found is not None and rng_state.flags.c_contiguous and rng_state.flags.writeable:
        if rng_state is not self._rng_seen:
          self._entry_points = {}
          self._rng_seen = rng_state
        self._entry_points[fn] = found.entry_point
      return out
    try:
      return entry(self.G, *args)
    except (ValueError, IndexError) as e:
      self._explain(e)

  _entry_points = {}
  _rng_seen = None

  def start_schedule(self, learned_episodes):
    """The schedule where it stands after `learned_episodes` learning episodes (the
    agent's count, which a run resumes from); a held epsilon keeps its own state."""
    self.frames.episode[algorithm.E_LEARNED] = int(learned_episodes)
    self.schedule_kind.start(self.schedule, self.schedule_block, learned_episodes)

  def run(self, episodes, learn, sample, rng_state, world, start=None):
    """`episodes` episodes fused with the analytic ship; `world` = (gate reward,
    out-of-bounds reward, max steps). Rows as `algorithm.run_ship` writes them."""
    self._flags(learn, sample)
    rows = np.zeros((int(episodes), algorithm.ROW_COUNTERS + 3 * len(self.names)))
    fixed = np.zeros(0) if start is None else np.asarray(start, dtype=np.float64)
    self._run(self._module.run_ship, np.int64(episodes), rng_state,
              np.asarray(world, dtype=np.float64), rows, fixed)
    return rows

  def run_continuing(self, rows, learn, sample, rng_state, world, ship):
    """`rows` record rows of the continuing ship task (`algorithm.run_continuing`; a
    root whose termination is continuing, a Clock) from `ship`, the process's state
    (float64[4], sailed on in place); `world` = (gate reward, out-of-bounds reward)."""
    if not self._continuing:
      raise GraphError("Program.run_continuing: the root's termination "
                       f"{type(self.graph.nodes[self.graph.root].termination).__name__} is "
                       "not a continuing one (a Clock)")
    self._flags(learn, sample)
    out = np.zeros((int(rows), algorithm.ROW_COUNTERS + 3 * len(self.names)))
    self._run(self._module.run_continuing, np.int64(rows), rng_state,
              np.asarray(world, dtype=np.float64), out, ship)
    return out

  @property
  def _continuing(self):
    return bool(self._module.CONTINUING)

  def run_alone(self, episodes, learn, sample, rng_state):
    """`episodes` calls of the root as a stand-alone subtask of the ship, from the local
    starts of its `direction` argument (`root_args`). Rows as `run`'s, ROW_END the
    root's success."""
    direction = self._root_args.get("direction")
    if not isinstance(direction, (int, np.integer)) or not 0 <= direction < 8:
      raise GraphError("Program.run_alone: the root runs alone from the local start of its "
                       f"integer argument 'direction' (0-7); root_args = {self._root_args}")
    self._flags(learn, sample)
    rows = np.zeros((int(episodes), algorithm.ROW_COUNTERS + 3 * len(self.names)))
    self._run(self._module.run_alone, np.int64(episodes), rng_state, np.int64(direction), rows)
    return rows

  def run_taxi(self, episodes, learn, sample, rng_state, starts=None):
    """`episodes` episodes fused with the taxi of the program's `world`
    (`taxi_rules.world_config`), from `starts` (rows of taxi_rules' state, used in
    turn; None: drawn). Rows as `run`'s, ROW_END the outcome, ROW_ILLEGAL the illegal
    Pickups and Dropoffs."""
    if self.world is None or self.obs_size not in (4, 5):
      raise GraphError("Program.run_taxi: this program was built without a taxi world "
                       "(Program(graph, obs_size=5, world=taxi_rules.world_config(...)); 4 "
                       "in the classic task)")
    self._flags(learn, sample)
    rows = np.zeros((int(episodes), algorithm.ROW_COUNTERS + 3 * len(self.names)))
    starts = np.zeros((0, 5), dtype=np.int64) if starts is None else \
        np.ascontiguousarray(starts, dtype=np.int64).reshape(-1, 5)
    self._run(self._module.run_taxi, np.int64(episodes), rng_state,
              np.ascontiguousarray(self.world, dtype=np.int64), rows, starts)
    return rows

  def run_world(self, episodes, learn, sample, rng_state, starts=None):
    """`episodes` episodes fused with the program's world (`fused`), from `starts` (rows,
    used in turn; None: drawn). Rows as `run`'s (`algorithm.run_world`)."""
    if self.fused is None:
      raise GraphError("Program.run_world: this program was built without a world (fused=)")
    if self._world is None:                  # the world's state, and a start's row
      self._world = (self.fused.new_state(), np.zeros(self.fused.start_size))
    self._flags(learn, sample)
    rows = np.zeros((int(episodes), algorithm.ROW_COUNTERS + 3 * len(self.names)))
    starts = np.ascontiguousarray(np.zeros(0) if starts is None else starts,
                                  dtype=np.float64).reshape(-1, self.fused.start_size)
    self._run(self._module.run_world, np.int64(episodes), rng_state, self.fused.params,
              self._world[0], rows, starts, self._world[1])
    return rows

  _world = None

  def _observation(self, obs):
    """`obs` as a float64 vector in C order of the program's length (as it is, if it
    is one), else a one-line refusal."""
    if type(obs) is not np.ndarray or obs.dtype is not _F64 or obs.strides != _VECTOR:
      obs = np.ascontiguousarray(obs, dtype=np.float64)
      if obs.ndim != 1:
        raise ValueError(f"Program: obs must be a vector of numbers, got shape {obs.shape}")
    if obs.shape[0] != self.obs_size:
      raise ValueError(f"Program: an observation of {obs.shape[0]} numbers; this program was "
                       f"built for obs_size = {self.obs_size}")
    return obs

  def begin(self, obs, learn, sample, rng_state):
    """The step-by-step path: an episode starts in `obs`; returns the first action."""
    self._flags(learn, sample)
    return self._stepwise(self._module.begin_at, self._observation(obs), rng_state)

  _no_samples = np.zeros((0, 2))

  def advance(self, obs, reward, terminated, truncated, info, learn, sample, rng_state):
    """The step-by-step path: the environment's step gave (obs, reward, terminated,
    truncated, info); returns (episode over, the next action). The positions sampled
    in the step (`info["positions"]`, the ship's) reach the graph's kinds."""
    self._flags(learn, sample)
    samples = self._no_samples
    if info:
      positions = info.get("positions")
      if positions is not None:
        samples = positions
        if type(samples) is not np.ndarray or samples.dtype is not _F64 or \
            samples.strides != _ROWS_OF_XY:
          samples = np.ascontiguousarray(positions, dtype=np.float64)
        if samples.ndim != 2 or samples.shape[1] != 2:
          raise ValueError("Program: info['positions'] must be rows of (x, y) of numbers, got "
                           f"shape {samples.shape}")
      before = info.get("state_before_restart")
      if before is not None and self._continuing:   # restarted: the root sees `obs` next
        self.frames.restart[:] = self._observation(obs)
        self.frames.episode[algorithm.E_RESTART] = 1
        obs = before
    return self._stepwise(self._module.advance, self._observation(obs), samples, float(reward),
                          bool(terminated), bool(truncated), rng_state)

  def counters(self):
    """Each node's [calls, runs, successes] in this episode, flat (a copy)."""
    return self.frames.counters.reshape(-1).copy()

  @property
  def episode_steps(self):
    """The primitive steps of the step-by-step episode so far."""
    return int(self.frames.episode[algorithm.E_STEPS])

  @property
  def episode_return(self):
    """The return of the step-by-step episode so far."""
    return float(self.frames.total[0])

  def calls_begun(self):
    """The calls below the root that have just begun (no step taken in them), as
    `graph.Call`s with their arguments by name."""
    from hpg_mj.hierarchy.graph import Call
    M = self.frames
    out = []
    for d in range(1, int(M.episode[algorithm.E_DEPTH]) + 1):
      node = int(M.stack[d])
      if M.steps[node] == 0:
        name = self.names[node]
        args = {arg: (int(M.args[node, k]) if is_int else float(M.args[node, k]))
                for k, (arg, is_int) in enumerate(self._arguments.get(name, {}).items())}
        out.append(Call(name, args, M.origin[node].copy()))
    return out

  def run_stepwise(self, env, episodes, learn, sample, rng_state, start, ended, on_call=None):
    """`episodes` episodes through `env`, any Gymnasium or dm_control environment
    (`executor.run_program`: `start`, `ended` and `on_call` there)."""
    from hpg_mj.hierarchy import executor
    return executor.run_program(self, env, episodes, learn, sample, rng_state, start, ended,
                                on_call)

  # -- saved by name --

  def state(self):
    """Every learned array by name, `"<node>.<field>"` (the live arrays: writing into
    them restores a checkpoint)."""
    out = {}
    for slot, (block, kind, first) in enumerate(self._learner_blocks):
      learned = self._field(f"L{slot}")
      for field, value in learned._asdict().items():
        if isinstance(value, np.ndarray):
          out[f"{first}.{field}"] = value
    if self.graph.schedule is not None:         # (a graph without one has the default's)
      for field in ("state", "outcomes", "counts"):
        out[f"schedule.{field}"] = getattr(self.schedule, field)
    return out

  def _field(self, field):
    """A record of the graph by its field (`L0`, `S`, ...)."""
    return dict(self._records)[field]

  def parameters(self):
    """Each learner's parameters by its first node's name (copies): a table's values
    (`q`), a policy's theta with its pending Eq. 3 updates applied (`theta`)."""
    out = {}
    for slot, (block, kind, first) in enumerate(self._learner_blocks):
      for field, value in kind.parameters(self._field(f"L{slot}")).items():
        out[f"{first}.{field}"] = value
    return out
