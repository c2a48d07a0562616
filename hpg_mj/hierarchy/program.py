"""The open machine: a task graph of blocks compiled into one program of its own.

`Program(graph)` finds each block's kind (`hierarchy.kinds`), checks the graph
against them (one line naming the node for anything that cannot run), lays out
their arrays by name, and writes the graph's operations (`enter`, `resume`, `judge`,
`chosen`: a chain over the graph's nodes calling each node's kinds, with its
arguments bound as constants) below the text of Algorithm 1 (`hierarchy.algorithm`),
as one module of its own that numba compiles: only the kinds the graph holds, a
user's rules and kinds among them, are typed at all, and the algorithm never asks
which kind a node holds. The module is a file in the cache folder (`cache_folder`),
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
import hashlib
import importlib.util
import inspect
import os
import sys

import numpy as np

from hpg_mj.hierarchy import algorithm
from hpg_mj.hierarchy import boundary
from hpg_mj.hierarchy import calls
from hpg_mj.hierarchy import kinds as kinds_mod
from hpg_mj.hierarchy.graph import GraphError, Primitive
from hpg_mj.hierarchy.kinds import rules as rules_mod
from hpg_mj.learners import banks
from hpg_mj.learners import eligibility as el
from hpg_mj.worlds import ship_core as core

_VERSION = "1"        # of the generated text's layout


def cache_folder():
  """Where the graphs' modules (and numba's cache of them) are written:
  $HPG_MJ_CACHE/graphs, else ~/.cache/hpg_mj/graphs."""
  root = os.environ.get("HPG_MJ_CACHE") or os.path.join(os.path.expanduser("~"), ".cache",
                                                        "hpg_mj")
  return os.path.join(root, "graphs")


def _identifier(name):
  out = "".join(c if c.isalnum() else "_" for c in name)
  return out if out and not out[0].isdigit() else "n_" + out


def _fingerprint(fn):
  """What identifies a compiled function's code: its module, name and the text of its
  file (a change to a helper beside it counts too), or its bytecode."""
  py = getattr(fn, "py_func", fn)
  h = hashlib.sha256(f"{py.__module__}.{py.__qualname__}".encode())
  try:
    with open(inspect.getsourcefile(py), "rb") as f:
      h.update(f.read())
  except (TypeError, OSError):
    code = py.__code__
    h.update(code.co_code)
    h.update(repr(code.co_consts).encode())
    h.update(repr(code.co_names).encode())
  return h.hexdigest()


def _importable(fn):
  """Whether another process finds `fn` again by its module's name (numba's cache
  rebuilds a compiled function's globals by importing its module)."""
  py = getattr(fn, "py_func", fn)
  module = sys.modules.get(py.__module__)
  return module is not None and getattr(module, "__file__", None) is not None


class _Node:
  """What the program knows of one subtask while it writes its operations."""

  def __init__(self, name, index, node):
    self.name, self.index, self.node = name, index, node
    self.ident = _identifier(name)


class Program:
  """A task graph of blocks compiled by the open machine (see the module docstring).

  `root_args`: the root call's arguments, by name. `obs_size`: the length of the
  observation it runs on (4: the ship's x, y, theta, theta rate)."""

  def __init__(self, graph, root_args=None, obs_size=4):
    self.graph = graph
    self.obs_size = int(obs_size)
    # The root last, as `hierarchy.machine` numbers them (the agents' records read so).
    self.names = [n for n in graph.nodes if n != graph.root] + [graph.root]
    self.index = {name: i for i, name in enumerate(self.names)}
    self._functions = {}            # id -> (global name, function)
    self._whats = []                # fault record's `what` -> (node, what, allowed)
    self._learners = {}             # id(block) -> slot
    self._learner_blocks = []       # (block, kind, first node)
    self._records = []              # (field of G, value)
    self._lines = []
    self._arguments = self._collect_arguments(root_args or {})
    self._schedule()
    self._subtasks = [_Node(name, self.index[name], n) for name, n in graph.nodes.items()
                      if not isinstance(n, Primitive)]
    for s in self._subtasks:
      self._resolve(s)
    self._write()
    self._frames()
    self._module = self._load()
    # Each record, and the graph of them, as a struct the compiled code takes by
    # reference (`learners.banks`): passed by value, the hybrid's ~80 arrays were copied
    # at every call of the graph's operations, and it trained at a third of its speed.
    records = banks.as_structs(self.frames, *[value for _, value in self._records])
    self.G = banks.as_structs(self._module.Graph(*records))[0]

  # -- the graph, checked against its kinds --

  def _collect_arguments(self, root_args):
    """node -> {argument: (is integer)}; the bindings per (parent, choice)."""
    bound = {}
    self._bindings = {}
    for name, node in self.graph.nodes.items():
      if isinstance(node, Primitive):
        continue
      for k, ref in enumerate(self.graph.children(name)):
        if ref.bind is not None:
          raise GraphError(f"subtask {name!r}: its child {ref.node!r} binds its arguments "
                           "by a Python function (Child(bind=...)), which the open machine "
                           "cannot compile; give the arguments as numbers: "
                           f"Child({ref.node!r}, x=..., y=...)")
        for arg, value in ref.args.items():
          if not str(arg).isidentifier():
            raise GraphError(f"subtask {name!r}: its child {ref.node!r}'s argument {arg!r}: "
                             "must be a Python identifier")
          if isinstance(value, bool) or not isinstance(value, (int, float, np.integer,
                                                               np.floating)):
            raise GraphError(f"subtask {name!r}: its child {ref.node!r}'s argument "
                             f"{arg} = {value!r}: must be a number (int or float)")
          if not np.isfinite(value):
            raise GraphError(f"subtask {name!r}: its child {ref.node!r}'s argument "
                             f"{arg} = {value!r}: must be finite")
        if isinstance(self.graph.nodes[ref.node], Primitive):
          if ref.args:
            raise GraphError(f"subtask {name!r}: its child {ref.node!r} is a primitive, "
                             f"which takes no arguments; got {sorted(ref.args)}")
          continue
        bound.setdefault(ref.node, []).append((name, ref.args))
        self._bindings[(name, k)] = ref.args
    for arg, value in dict(root_args).items():
      if not str(arg).isidentifier() or isinstance(value, bool) or not isinstance(
          value, (int, float, np.integer, np.floating)) or not np.isfinite(value):
        raise GraphError(f"root_args: {arg} = {value!r}: an argument is a finite number named "
                         "by a Python identifier")
    bound.setdefault(self.graph.root, []).append(("the root call", dict(root_args)))
    out = {}
    for child, calls in bound.items():
      names = [sorted(args) for _, args in calls]
      if any(n != names[0] for n in names):
        said = "; ".join(f"{parent}: {sorted(args)}" for parent, args in calls)
        raise GraphError(f"subtask {child!r}: its calls bind different arguments ({said}); "
                         "every call of a subtask binds the same names")
      out[child] = {arg: all(isinstance(args[arg], (int, np.integer)) for _, args in calls)
                    for arg in names[0]}
      for arg in out[child]:
        if arg in ("origin", "steps"):
          raise GraphError(f"subtask {child!r}: an argument may not be named {arg!r} (the "
                           "call's own field); rename it")
    self._root_args = dict(root_args)
    return out

  def _schedule(self):
    """The graph's exploration schedule (a held epsilon of 0.1 by default, as
    `hierarchy.machine`'s), its watched subtasks checked."""
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
    if node.available is not None:
      raise GraphError(f"subtask {name!r}: `available` is not run by the open machine yet; "
                       "leave it None")
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
                       "needs a learner that draws values (GaussianCMAC)")
    if s.view.gives != s.learner.reads:
      raise GraphError(f"subtask {name!r}: its learner {type(node.learner).__name__} reads "
                       f"{s.learner.reads}, its view {rules_mod.rule_name(node.view)} gives "
                       f"{s.view.gives}")
    arguments = self._arguments.get(name, {})
    s.view.check(name, node.view, arguments)
    s.end.check(name, node.termination, arguments)
    if s.reward is not None:
      s.reward.check(name, node.internal_reward, arguments)
      if s.reward.from_termination and not s.end.gives_internal:
        raise GraphError(f"subtask {name!r}: its internal reward {type(node.internal_reward).__name__}"
                         f" is the G of its termination, and {type(node.termination).__name__} "
                         "gives none")
    size = s.view.size(node.view)
    s.learner.check(name, node.learner, s.n_children, size)
    s.size = s.learner.size(node.learner)

  # -- the text of the graph's operations --

  def _function(self, fn):
    """The global name the module gives `fn`."""
    if id(fn) not in self._functions:
      self._functions[id(fn)] = (f"_f{len(self._functions)}", fn)
    return self._functions[id(fn)][0]

  def _record(self, field, value):
    self._records.append((field, value))
    return f"G.{field}"

  def _what(self, node, what, allowed):
    self._whats.append((node, what, allowed))
    return len(self._whats) - 1

  def _call_record(self, s, L):
    args = self._arguments.get(s.name, {})
    cls = f"calls.{calls.name_of(tuple(args))}" if args else "calls.Call"
    L.append("@numba.njit(**_JIT)")
    L.append(f"def call_{s.index}(M):")
    L.append(f'  """The call record of subtask {s.name!r}."""')
    values = [f"np.int64(M.args[{s.index}, {k}])" if is_int else f"M.args[{s.index}, {k}]"
              for k, is_int in enumerate(args.values())]
    values += [f"M.origin[{s.index}]", f"M.steps[{s.index}]"]
    L.append(f"  return {cls}({', '.join(values)})")
    L.append("")
    L.append("")

  def _op(self, kind, block, field, s):
    """(the function's global name, its settings' text or None) of a view, end or reward."""
    fn = self._function(kind.operation(block))
    if not kind.takes_settings:
      return fn, None
    return fn, self._record(f"{field}{s.index}", kind.settings(s.name, block))

  def _view_text(self, s, L):
    node = s.node
    fn, settings = self._op(s.view, node.view, "V", s)
    args = ", ".join([settings, "M.obs", f"call_{s.index}(M)", "M.samples"] if settings else
                     ["M.obs", f"call_{s.index}(M)"])
    name = rules_mod.rule_name(node.view)
    L.append("@numba.njit(**_JIT)")
    L.append(f"def view_{s.index}(G):")
    L.append(f'  """Subtask {s.name!r} views the state ({name})."""')
    L.append("  M = G.M")
    if s.view.gives == "state":
      what = self._what(s.name, f"view {name}", f"an integer state in [0, {s.size})")
      L.append(f"  x = boundary.as_state({fn}({args}), {s.size}, M.fault, {what})")
      L.append(f"  M.x[{s.index}, 0] = x")
      L.append("  return x")
    else:
      what = self._what(s.name, f"view {name}",
                        f"a tuple of {s.size} finite numbers (its "
                        f"{type(node.learner).__name__} reads {s.size})")
      L.append(f"  x = M.x[{s.index}, :{s.size}]")
      if s.view.writes:
        L.append(f"  {fn}({args}, x)")
      else:
        L.append(f"  boundary.as_features({fn}({args}), x, M.fault, {what})")
      L.append("  return 0")
    L.append("")
    L.append("")

  def _x_text(self, s, fresh):
    """The text of the node's view of the state now (`fresh`), or as it last took it."""
    if s.view.gives == "state":
      return f"view_{s.index}(G)" if fresh else f"np.int64(G.M.x[{s.index}, 0])"
    return f"G.M.x[{s.index}, :{s.size}]"

  def _learner_text(self, s, L):
    block = s.node.learner
    if id(block) not in self._learners:
      slot = len(self._learner_blocks)
      self._learners[id(block)] = slot
      self._learner_blocks.append((block, s.learner, s.name))
      follows = "schedule" in inspect.signature(s.learner.settings).parameters
      self._record(f"P{slot}", s.learner.settings(s.name, block, self.schedule) if follows
                   else s.learner.settings(s.name, block))
      self._record(f"L{slot}", s.learner.learned(block, s.n_children))
    else:
      slot = self._learners[id(block)]
      first = self._learner_blocks[slot][2]
      fresh = s.learner.learned(block, s.n_children)
      same = self._records[[f for f, _ in self._records].index(f"L{slot}")][1]
      if any(np.shape(a) != np.shape(b) for a, b in zip(fresh, same)):
        raise GraphError(f"subtask {s.name!r} shares its learner with {first!r}, which has "
                         "another number of children or states; a shared learner serves "
                         "nodes of the same shape")
    self._record(f"N{s.index}", s.learner.scratch(block, s.n_children))
    start = self._function(s.learner.start)
    choose = self._function(s.learner.choose)
    observe = self._function(s.learner.observe)
    P, Lr, N = f"G.P{slot}", f"G.L{slot}", f"G.N{s.index}"
    settle = (f"  M.action[{s.index}] = v" if s.learner.continuous else
              f"  M.choice[{s.index}] = np.int64(v)")
    L += ["@numba.njit(**_JIT)", f"def enter_{s.index}(G):",
          f'  """Subtask {s.name!r} is called: z <- 0, its view, its first choice."""',
          "  M = G.M", f"  {start}({P}, {Lr}, {N})",
          *([] if s.view.gives == "state" else [f"  view_{s.index}(G)"]),
          f"  v = {choose}({P}, {Lr}, {N}, {self._x_text(s, True)}, {s.n_children}, M.rng, "
          "M.flags[0], M.flags[1])", settle, "", "",
          "@numba.njit(**_JIT)", f"def resume_{s.index}(G, signal, done, terminal):",
          f'  """Subtask {s.name!r}\'s learner takes R + G in s\' and chooses again."""',
          "  M = G.M",
          *([f"  x = {self._x_text(s, False)} if terminal else view_{s.index}(G)"]
            if s.view.gives == "state" else
            ["  if not terminal:", f"    view_{s.index}(G)", f"  x = {self._x_text(s, False)}"]),
          f"  v = {observe}({P}, {Lr}, {N}, x, signal, done, terminal, {s.n_children}, M.rng, "
          "M.flags[0], M.flags[1])",
          "  if not done:", "  " + settle, "", ""]

  def _judge_text(self, s, L):
    node = s.node
    end, end_settings = self._op(s.end, node.termination, "T", s)
    args = ", ".join([end_settings, "M.obs", "call", "M.samples"] if end_settings else
                     ["M.obs", "call"])
    what = self._what(s.name, f"termination {rules_mod.rule_name(node.termination)}",
                      "0 (go on), 1 (success), -1 (failure) or a bool")
    L += ["@numba.njit(**_JIT)", f"def judge_{s.index}(G):",
          f'  """Subtask {s.name!r}: (its event, G) after a child returned."""',
          "  M = G.M", f"  call = call_{s.index}(M)"]
    if s.end.gives_internal:
      L.append(f"  said, shaped = {end}({args})")
    else:
      L.append(f"  said = {end}({args})")
    L.append(f"  event = boundary.as_event(said, M.fault, {what})")
    if s.reward is None:
      L.append("  return event, 0.0")
    elif s.reward.from_termination:
      L.append("  return event, shaped")
    else:
      fn, settings = self._op(s.reward, node.internal_reward, "R", s)
      args = ", ".join([settings, "M.obs", "call", "event", "M.samples"] if settings else
                       ["M.obs", "call", "event"])
      what = self._what(s.name, f"internal reward {rules_mod.rule_name(node.internal_reward)}",
                        "a finite number")
      L.append(f"  return event, boundary.as_reward({fn}({args}), M.fault, {what})")
    L += ["", ""]

  def _schedule_text(self, L):
    """The schedule's hooks: a watched subtask's run ended, the episode, a decision."""
    kind = self.schedule_kind
    S = self._record("S", self.schedule)
    run, episode, decided = (self._function(f) for f in (kind.run_ended, kind.episode_ended,
                                                          kind.decided))
    L += ["@numba.njit(**_JIT)", "def schedule_run(G, node, success):",
          '  """A subtask\'s run ended: the schedule notes it if it watches the subtask."""']
    watched = kind.watch(self.schedule_block)
    for k, name in enumerate(watched):
      L.append(f"  {'if' if k == 0 else 'elif'} node == {self.index[name]}:")
      L.append(f"    {run}({S}, {k}, success)")
    L += ["  return None", "", "",
          "@numba.njit(**_JIT)", "def schedule_episode(G, learned):",
          f"  {episode}({S}, learned)", "", "",
          "@numba.njit(**_JIT)", "def schedule_decided(G):",
          f"  {decided}({S})", "", ""]

  def _chosen_text(self, s, L):
    L += ["@numba.njit(**_JIT)", f"def chosen_{s.index}(G):",
          f'  """The child subtask {s.name!r} chose, its arguments bound."""', "  M = G.M"]
    if s.learner.continuous:
      L += ["  return -1", "", ""]
      return
    L.append(f"  c = M.choice[{s.index}]")
    for k, ref in enumerate(self.graph.children(s.name)):
      child = self.graph.nodes[ref.node]
      L.append(f"  {'if' if k == 0 else 'elif'} c == {k}:")
      if isinstance(child, Primitive):
        L.append(f"    M.action[{s.index}] = {float(child.action)!r}")
        L.append("    return -1")
        continue
      c = self.index[ref.node]
      for j, arg in enumerate(self._arguments.get(ref.node, {})):
        L.append(f"    M.args[{c}, {j}] = {float(ref.args[arg])!r}")
      L.append(f"    return {c}")
    L += ["  return -1", "", ""]

  def _dispatch(self, L, op, params, call):
    L += ["@numba.njit(**_JIT)", f"def {op}(G, node{params}):"]
    for k, s in enumerate(self._subtasks):
      L.append(f"  {'if' if k == 0 else 'elif'} node == {s.index}:")
      L.append(f"    return {op}_{s.index}(G{call})")
    L += [f"  return {'(0, 0.0)' if op == 'judge' else '-1' if op == 'chosen' else 'None'}",
          "", ""]

  def _write(self):
    L = ["", "", "# ---- the graph's operations (hierarchy.program) ----", ""]
    for s in self._subtasks:
      self._call_record(s, L)
      self._view_text(s, L)
      self._learner_text(s, L)
      self._judge_text(s, L)
      self._chosen_text(s, L)
    self._dispatch(L, "enter", "", "")
    self._dispatch(L, "resume", ", signal, done, terminal", ", signal, done, terminal")
    self._dispatch(L, "judge", "", "")
    self._dispatch(L, "chosen", "", "")
    self._schedule_text(L)
    seen = tuple(bool(getattr(s, "seen_step", False)) for s in self._by_index())
    L.append(f"ROOT = {self.index[self.graph.root]}")
    L.append(f"SEEN_STEP = {seen!r}")
    fields = ["M"] + [f for f, _ in self._records]
    L.append(f"Graph = collections.namedtuple('Graph', {tuple(fields)!r})")
    self._text = "\n".join(L) + "\n"

  def _by_index(self):
    by = {s.index: s for s in self._subtasks}
    return [by.get(i) or _Node(n, i, None) for i, n in enumerate(self.names)]

  # -- the state and the module --

  def _frames(self):
    n = len(self.names)
    depth = self._depth(self.graph.root)
    n_args = max([len(a) for a in self._arguments.values()] + [1])
    size = max([s.size if s.view.gives == "features" else 1 for s in self._subtasks] + [1])
    self.frames = algorithm.Frames(
        stack=np.zeros(depth, dtype=np.int64), choice=np.zeros(n, dtype=np.int64),
        action=np.zeros(n), steps=np.zeros(n, dtype=np.int64),
        child_steps=np.zeros(n, dtype=np.int64), reward=np.zeros(n),
        origin=np.zeros((n, self.obs_size)), args=np.zeros((n, n_args)),
        x=np.zeros((n, size)), counters=np.zeros((n, 3)),
        episode=np.zeros(4, dtype=np.int64), total=np.zeros(1),
        flags=np.zeros(2, dtype=np.bool_), rng=np.zeros(4, dtype=np.uint64),
        fault=np.zeros(4), obs=np.zeros(self.obs_size),
        samples=np.zeros((core.SAMPLES_PER_CONTROL + 1, 2)))
    root = self.index[self.graph.root]
    for j, arg in enumerate(self._arguments.get(self.graph.root, {})):
      self.frames.args[root, j] = float(self._root_args[arg])

  def _depth(self, name):
    node = self.graph.nodes[name]
    if isinstance(node, Primitive):
      return 0
    return 1 + max(self._depth(r.node) for r in self.graph.children(name))

  def _load(self):
    with open(algorithm.__file__) as f:
      text = f.read() + self._text
    # A rule from code that no module holds (a notebook's cell, an exec'd block) is
    # compiled anew in each process: numba's cache could not find it again.
    self.cached = all(_importable(fn) for _, fn in self._functions.values())
    if not self.cached:
      text = text.replace("cache=True", "cache=False")
    header = ["from hpg_mj.hierarchy import boundary", "from hpg_mj.hierarchy import calls"]
    h = hashlib.sha256((_VERSION + text).encode())
    for global_name, fn in sorted(self._functions.values(), key=lambda p: p[0]):
      h.update(global_name.encode())
      h.update(_fingerprint(fn).encode())
    for _, value in self._records:
      h.update(repr(type(value)).encode())
    name = f"hpg_mj_graph_{h.hexdigest()[:20]}"
    text = text.replace("import collections\n", "import collections\n" + "\n".join(header) +
                        "\n", 1)
    folder = cache_folder()
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, name + ".py")
    if not os.path.exists(path):
      tmp = f"{path}.{os.getpid()}.tmp"
      with open(tmp, "w") as f:
        f.write(text)
      os.replace(tmp, path)
    if name in sys.modules:
      module = sys.modules[name]
    else:
      spec = importlib.util.spec_from_file_location(name, path)
      module = importlib.util.module_from_spec(spec)
      for global_name, fn in self._functions.values():
        module.__dict__[global_name] = fn
      sys.modules[name] = module
      try:
        spec.loader.exec_module(module)
      except BaseException:
        del sys.modules[name]
        raise
    self.module_path = path
    return module

  # -- running --

  def _flags(self, learn, sample):
    self.frames.flags[0] = bool(learn)
    self.frames.flags[1] = bool(sample)

  def _run(self, fn, *args):
    """A compiled entry point, a boundary fault raised as its one line."""
    try:
      return fn(self.G, *args)
    except ValueError as e:
      if str(e) == boundary.FAULT_MESSAGE:
        raise ValueError(boundary.explain(self.frames.fault, self._whats)) from None
      raise

  def start_schedule(self, learned_episodes):
    """The schedule where it stands after `learned_episodes` learning episodes (the
    agent's count, which a run resumes from); a held epsilon keeps its own state."""
    self.frames.episode[algorithm.E_LEARNED] = int(learned_episodes)
    self.schedule_kind.start(self.schedule, self.schedule_block, learned_episodes)

  def run(self, episodes, learn, sample, rng_state, world, start=None):
    """`episodes` episodes fused with the analytic ship; `world` = (gate reward,
    out-of-bounds reward, max steps). Rows as `hierarchy.machine`'s."""
    self._flags(learn, sample)
    rows = np.zeros((int(episodes), algorithm.ROW_COUNTERS + 3 * len(self.names)))
    fixed = np.zeros(0) if start is None else np.asarray(start, dtype=np.float64)
    self._run(self._module.run_ship, np.int64(episodes), rng_state,
              np.asarray(world, dtype=np.float64), rows, fixed)
    return rows

  def _observation(self, obs):
    obs = np.asarray(obs, dtype=np.float64).reshape(-1)
    if obs.shape[0] != self.obs_size:
      raise ValueError(f"Program: an observation of {obs.shape[0]} numbers; this program was "
                       f"built for obs_size = {self.obs_size}")
    return obs

  def begin(self, obs, learn, sample, rng_state):
    """The step-by-step path: an episode starts in `obs`; returns the first action."""
    self._flags(learn, sample)
    return self._run(self._module.begin_at, self._observation(obs), rng_state)

  _no_samples = np.zeros((0, 2))

  def advance(self, obs, reward, terminated, truncated, info, learn, sample, rng_state):
    """The step-by-step path: the environment's step gave (obs, reward, terminated,
    truncated, info); returns (episode over, the next action)."""
    self._flags(learn, sample)
    positions = (info or {}).get("positions") if isinstance(info, dict) else None
    samples = self._no_samples if positions is None else np.asarray(positions, np.float64)
    return self._run(self._module.advance, self._observation(obs), samples, float(reward),
                     bool(terminated), bool(truncated), rng_state)

  def counters(self):
    return self.frames.counters.reshape(-1).copy()

  @property
  def episode_steps(self):
    return int(self.frames.episode[algorithm.E_STEPS])

  @property
  def episode_return(self):
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
    """`episodes` episodes through `env` (any Gymnasium or dm_control environment),
    each from `start()`; `ended(last step)` gives the row's end. Rows as `run`'s.
    `on_call(call)`, if given, is told of every subtask called below the root (a
    `graph.Call`: its node, its arguments, the observation where it was called)."""
    from hpg_mj.hierarchy import executor
    adapter = executor.adapter_for(env)
    step = executor.step_values(adapter)
    sample = learn if sample is None else (sample or learn)
    rows = np.zeros((int(episodes), algorithm.ROW_COUNTERS + 3 * len(self.names)))
    for i in range(int(episodes)):
      obs = adapter.reset(start())
      action = self.begin(obs, learn, sample, rng_state)
      over = False
      while not over:
        if on_call is not None:
          for call in self.calls_begun():
            on_call(call)
        obs, reward, terminated, truncated, info = step(action)
        over, action = self.advance(obs, reward, terminated, truncated, info, learn, sample,
                                    rng_state)
      rows[i, algorithm.ROW_END] = ended(executor.Step(obs, float(reward), bool(terminated),
                                                       bool(truncated), info))
      rows[i, algorithm.ROW_STEPS] = self.episode_steps
      rows[i, algorithm.ROW_RETURN] = self.episode_return
      rows[i, algorithm.ROW_COUNTERS:] = self.counters()
    return rows

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
      learned = self._field(f"L{slot}")
      fields = learned._fields
      if all(f in fields for f in el.Trace._fields):
        out[f"{first}.theta"] = el.parameters(el.Trace(*[getattr(learned, f)
                                                         for f in el.Trace._fields]))
      for field in fields:
        if field in el.Trace._fields:
          continue
        if field.startswith("trace_"):
          continue
        out[f"{first}.{field}"] = np.array(getattr(learned, field))
    return out
