"""Task graphs: a hierarchy is a directed acyclic graph of subtasks over primitive
actions (the paper's section 2).

```python
graph = TaskGraph(root="root", nodes=[
    Primitive("north", action=1), Primitive("south", action=0), ...,
    Subtask("navigate", children=["north", "south", "east", "west"],
            termination=lambda call, step: at_target(call, step.obs),
            view=lambda call, obs: abstract_index(call, obs),
            learner=SoftmaxPolicyGradient(n_states=125, n_actions=4, alpha=0.1)),
    Subtask("root", children=[Child("navigate", target=0), ...], ...),
])
```

Each non-primitive subtask has its children, its termination, its own view of
the state (a state abstraction, or a map into a local frame), an optional
internal reward G that never propagates upward, an optional view of the reward
its learner sees, an optional initiation condition on its children, and the
learner that solves it. `hpg_mj.hierarchy.executor` runs a graph with the
stack discipline of Algorithm 1.
"""
import dataclasses
from typing import Any, Callable, Optional, Protocol, Sequence, runtime_checkable


@dataclasses.dataclass(frozen=True)
class Primitive:
  """A primitive action. `action` is what the environment receives; for a
  continuous primitive (`action=None`) the parent's learner supplies the value."""
  name: str
  action: Any = None


class Child:
  """A reference to a child node with its parameters: `Child("navigate", target=2)`,
  `Child("goto", x=300.0, y=700.0)`: integers or floats (on the compiled machine an
  argument is an integer where every binding of it is one, else a float; every `Child`
  of one subtask binds the same names).

  `bind` adds parameters decided when the child is called (MAXQ's parameter binding,
  e.g. Get calls Navigate(t) with t = the passenger's station): on the open machine a
  block of a `BindingKind` (`hierarchy.kinds.base`: its compiled `bind(P, obs, call)`
  gives a tuple of the values of its names), in the Python executor a callable
  `bind(call, obs) -> dict`."""

  def __init__(self, node: str, bind=None, **args):
    self.node = node
    self.bind = bind
    self.args = dict(args)

  def __repr__(self):
    args = ", ".join(f"{k}={v!r}" for k, v in self.args.items())
    return f"Child({self.node!r}{', ' if args else ''}{args})"


@dataclasses.dataclass
class Call:
  """One invocation of a subtask: its node, its parameters, the observation at
  which it was called, the primitive steps taken inside it, and scratch space
  (`memo`) for the subtask's own functions."""
  node: str
  args: dict
  origin: Any
  steps: int = 0
  memo: dict = dataclasses.field(default_factory=dict)


@dataclasses.dataclass
class Step:
  """What one primitive action did: the environment's observation after it, its
  reward, whether the episode ended (terminated) or was cut (truncated), and
  the environment's info (for the ship: the positions sampled every 0.2 s)."""
  obs: Any
  reward: float
  terminated: bool
  truncated: bool
  info: dict


@dataclasses.dataclass
class Subtask:
  """A non-primitive node (see the module docstring).

  Its `view`, `termination`, `learner` (and `available`, `internal_reward`, `reward`)
  are blocks on the open machine (`hierarchy.blocks`, a user's rules wrapped as
  `hierarchy.kinds.rules`' `Abstraction`, `Features`, `Termination`, `InternalReward`:
  compiled `rule(obs, call)` functions); the signatures below are the Python
  executor's, for a graph of Python callables.

  Functions receive the current `Call`; after each child returns the executor
  calls, in this order: `internal_reward(call, step)` (G), `reward(call, step,
  child_reward)` (the R its learner sees; default: the rewards summed over the
  child's run), `termination(call, step)`, then the learner's update with
  R + G. `step` is the last primitive step of the child's run. `available(call,
  obs, i)` says whether child i may be chosen (its initiation condition);
  `on_exit(call, step, episode_over)` runs when the call returns.
  """
  name: str
  children: Sequence
  termination: Callable[[Call, Step], bool]
  view: Callable[[Call, Any], Any]
  learner: Any
  available: Optional[Callable[[Call, Any, int], bool]] = None
  internal_reward: Optional[Callable[[Call, Step], float]] = None
  reward: Optional[Callable[[Call, Step, float], float]] = None
  on_exit: Optional[Callable[[Call, Optional[Step], bool], None]] = None


@runtime_checkable
class Learner(Protocol):
  """What a subtask's learner must answer when the Python executor runs its graph
  (`hierarchy.executor`; a graph of blocks needs none of this: the open machine
  runs it). Checked when the graph is built (`TaskGraph`), naming the node.

  start()
      The subtask is called (Algorithm 1: z <- 0 for Eq. 3; a trace cleared).
  act(features, mask, rng_state, sample) -> int or float
      Choose a child: its index among the node's children, or, for a node whose one
      child is a continuous primitive (`Primitive(name)` without an action), the
      action's value. `features` is the node's view of the state: the same array
      object may be reused and overwritten for the next state, so a learner that
      keeps it must copy it. `mask` is None or a bool array, one entry per child
      (the node's `available`): choose only where it is True. `rng_state` is the
      agent's generator (`learners.rng`): draw only from it, so that a seed gives
      the same numbers on every path. `sample` False: the greedy choice.
  observe(signal, next_features, done, terminal, learn)
      The child returned: `signal` is R + G (the child's rewards as the node sees
      them, plus its internal reward); `next_features` the view of the state now
      (None when the episode terminated); `done` whether this call ends (its own
      termination or the episode's end); `terminal` whether it ends in a terminal
      state (no bootstrapping); `learn` whether to update.

  A learner with `n_actions` (a discrete learner) must have one per child.
  """

  def start(self) -> None:
    """The subtask is called (z <- 0; a trace cleared)."""

  def act(self, features, mask, rng_state, sample):
    """A child's index among the node's children (or a continuous action's value),
    chosen in the state `features`."""

  def observe(self, signal, next_features, done, terminal, learn) -> None:
    """The child returned R + G = `signal`; learn from it if `learn`."""


class GraphError(ValueError):
  """A task graph that cannot be executed: the message names the node."""


# The learner classes of the kinds registered with `hierarchy.kinds.register`: the open
# machine runs them, so they need not answer the Python executor's calls.
MACHINE_LEARNERS = set()


def _check_learner(node):
  """A Python learner meets the `Learner` contract (a block is the machine's, and so is
  a learner of a registered kind, `hierarchy.kinds`)."""
  learner = node.learner
  if type(learner).__module__ == "hpg_mj.hierarchy.blocks":
    return
  if any(cls in MACHINE_LEARNERS for cls in type(learner).__mro__):
    return
  missing = [m for m in ("start", "act", "observe") if not callable(getattr(learner, m, None))]
  if missing:
    raise GraphError(f"subtask {node.name!r}: its learner {type(learner).__name__} has no "
                     f"{', '.join(missing)}; a learner answers start(), act(features, mask, "
                     "rng_state, sample) and observe(signal, next_features, done, terminal, "
                     "learn) (hpg_mj.hierarchy.graph.Learner), or is a block of "
                     "hpg_mj.hierarchy.blocks or of a kind registered with "
                     "hpg_mj.hierarchy.kinds.register")
  n_actions = getattr(learner, "n_actions", None)
  if n_actions is not None and int(n_actions) != len(node.children):
    raise GraphError(f"subtask {node.name!r}: its learner {type(learner).__name__} chooses "
                     f"among {n_actions} actions, the node has {len(node.children)} children")


class TaskGraph:
  """A validated hierarchy: every child exists, there is no cycle, every
  subtask has a termination, a view and a learner.

  `root` the root's name; `nodes` {name: its Subtask or Primitive}, in the order given;
  `schedule` the graph's exploration schedule. A node is changed by building a new
  graph: `TaskGraph(g.root, [dataclasses.replace(node, learner=...) if name == "option0"
  else node for name, node in g.nodes.items()], schedule=g.schedule)`."""

  def __init__(self, root: str, nodes: Sequence, on_episode_end=None, schedule=None):
    self.root = root
    self.schedule = schedule         # a graph-wide exploration schedule (blocks.HeldEpsilon)
    self.nodes = {}
    for node in nodes:
      if not isinstance(node, (Subtask, Primitive)):
        raise GraphError(f"node {node!r} is neither a Subtask nor a Primitive")
      if node.name in self.nodes:
        raise GraphError(f"node {node.name!r} is defined twice")
      self.nodes[node.name] = node
    self.on_episode_end = on_episode_end
    self._children = {}
    self._validate()

  def children(self, name):
    """The node's children as `Child` references."""
    return self._children[name]

  def depth(self, name=None):
    """The calls on the stack at most below `name` (the root): its own and its
    subtasks' (a primitive: 0)."""
    node = self.nodes[self.root if name is None else name]
    if isinstance(node, Primitive):
      return 0
    return 1 + max(self.depth(ref.node) for ref in self._children[node.name])

  def subtasks(self):
    """Its subtasks (the nodes that are not primitives), in the graph's order."""
    return [n for n in self.nodes.values() if isinstance(n, Subtask)]

  def _validate(self):
    if self.root not in self.nodes:
      raise GraphError(f"root {self.root!r} is not a node; nodes: {sorted(self.nodes)}")
    if not isinstance(self.nodes[self.root], Subtask):
      raise GraphError(f"root {self.root!r} must be a Subtask, not a primitive")
    for node in self.subtasks():
      for field in ("termination", "view", "learner"):
        if getattr(node, field) is None:
          raise GraphError(f"subtask {node.name!r} has no {field}")
      if not node.children:
        raise GraphError(f"subtask {node.name!r} has no children")
      _check_learner(node)
      refs = []
      for child in node.children:
        ref = child if isinstance(child, Child) else Child(child)
        if ref.node not in self.nodes:
          raise GraphError(f"subtask {node.name!r} names an unknown child {ref.node!r}; "
                           f"nodes: {sorted(self.nodes)}")
        refs.append(ref)
      self._children[node.name] = refs
    # Depth-first search for a cycle, naming the nodes on it.
    state = {}

    def visit(name, path):
      state[name] = "open"
      for ref in self._children.get(name, ()):
        if state.get(ref.node) == "open":
          cycle = path[path.index(ref.node):] + [ref.node]
          raise GraphError(f"task graph has a cycle through {' -> '.join(cycle)}; "
                           "a hierarchy must be acyclic")
        if ref.node not in state:
          visit(ref.node, path + [ref.node])
      state[name] = "done"

    for name in self.nodes:
      if name not in state:
        visit(name, [name])
