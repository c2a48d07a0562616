"""What a block kind is: the one narrow interface between Algorithm 1
(`hierarchy.algorithm`) and the blocks a graph is built from.

A *block* is the data a user puts in a `Subtask` (`QTable(n_states=400)`,
`Features(my_rule)`); its *kind* is the one module that knows how to run it: its
Python side (the checks made when a graph is built, its arrays by name, what it
saves) and its compiled operations. A kind is registered once against its block's
class (`hierarchy.kinds.register`), and the program of a graph (`hierarchy.program`)
calls each node's kinds through the operations below, so Algorithm 1 never branches
on which kind a node holds. Adding a kind, ours or a user's, is one new module.

Roles and their compiled operations (each a `numba.njit` function; `P` the block's
settings, a namedtuple of numbers and arrays, `L` what it learns, a namedtuple of
arrays shared by the nodes that share the block, `N` the node's own scratch):

* a **learner** (`LearnerKind`) chooses among the node's children, or draws the value
  of its one continuous primitive:
    start(P, L, N)                                  the subtask is called (z <- 0)
    choose(P, L, N, x, n, rng, learn, sample)       -> the choice (float64: a child's
                                                       index, or the action's value; an
                                                       index outside [0, n), or not
                                                       whole, stops the run naming the
                                                       node: `hierarchy.boundary`)
    observe(P, L, N, x, signal, done, terminal, n, rng, learn, sample)
                                                    -> the next choice (any value when
                                                       `done`)
  `x` is the node's view of the state: an int64 state (`reads = "state"`) or a
  float64 vector (`reads = "features"`; the learner tiles it itself); in `observe`
  it is the view of s' (when s' is `terminal`, the view of the state the choice was
  made in: nothing bootstraps from a terminal state). `n` the node's children,
  `rng` the run's generator state (`learners.rng`: draw only from it; a module that
  imports `learners.rng` as `rng` names it `rng_state`, as the tutorial does), `signal`
  R + G.
* a **view** gives the node's learner its state: `view(P, obs, call, samples)` (or,
  for a user's rule, `rule(obs, call)`) -> an integer state, or a tuple of numbers; a
  features kind with `writes` writes its numbers instead: `view(P, obs, call,
  samples, out)`, `out` as long as its learner reads.
* a **termination**: `end(P, obs, call, samples)` (a user's rule: `rule(obs, call)`)
  -> the call's event: 0 go on, 1 success, -1 failure (a bool: True is a success);
  a kind with `gives_internal` returns (event, G), its G taken by a `Shaping` reward.
* an **internal reward** G: `reward(P, obs, call, event, samples)` (a user's rule:
  `rule(obs, call, event)`) -> a float.
* a node's **available** children: `offer(P, obs, call, mask)` writes True for each
  child it may choose now; its learner is a kind with `masked = True`, whose choose
  and observe take the mask after `n`: choose(P, L, N, x, n, mask, rng, learn,
  sample) (the taxi's GibbsTable).
* a `Child`'s **binding**, arguments decided when the parent calls it
  (`Child("navigate", bind=TaxiTarget("get"))`): `bind(P, obs, call)` -> a tuple of
  the values of `names(block)`, `call` the parent's (checked where they are bound:
  as many as its names, each finite, an integer argument's whole).
* a graph's **schedule** of exploration (`hierarchy.kinds.epsilon`): its learners with
  `epsilon_schedule=True` read its `epsilon`.

A kind whose `settings` (or `size`) takes a parameter `world`, `schedule`,
`learned_episodes` or `node` is given the program's world (the taxi's
`taxi_rules.world_config`), the graph's schedule record, the live count of
learning episodes ended (int64[1]: a step size's warm-up), or its node (the
`Subtask`, whose other blocks it may read); a learner's `scratch` that takes
`child_steps` is given the live count of its node's current child's steps
(int64[1]: an SMDP learner's tau, read in `observe`).

`samples` are the positions the ship's step sampled (the ship's local ends judge each
sampled segment); `P` of a view, termination or reward is the node's own.

`call` is the call's record: its named arguments (`call.x`, as the parent's
`Child("goto", x=...)` bound them), `call.origin` (the observation where the call
began) and `call.steps` (the primitive steps taken in it).
"""
import numba
import numpy as np

from hpg_mj.hierarchy.graph import GraphError
from hpg_mj.learners import arrays


# A shipped kind's operation that only forwards to the compiled rule below it (a
# learner's start, a table's choose and observe, a schedule's hooks, a termination that
# is one call) is inlined (`inline="always"`): numba compiles a function that is called
# as a library of its own, with everything it calls linked in and optimized again, so
# each such layer was the learner's code optimized and emitted once more (with the
# table's SMDP step, `qlambda.smdp_step`, ~4% of the hybrid's and taxi HPG's first
# train; flat Q-learning's steps/s +3%). A user's kind may be either.

@numba.njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def no_start(P, L, N):
  """A learner's `start` when a call's beginning resets nothing (no trace)."""


class Kind:
  """A block kind. `block`: the class of the blocks it runs; `role`: "learner",
  "view", "termination" or "reward"."""

  block = None
  role = None

  def settings(self, name, block):
    """The block's settings as the compiled operations take them (a namedtuple, or
    None for none). A kind that reads the world's own settings (the taxi's
    `taxi_rules.world_config`) takes a `world` parameter, `settings(self, name, block,
    world)`, and is given the program's (`Program(graph, world=...)`); `size` too. One
    that reads the observation at places of its own takes `obs_size`, the observation's
    length, and refuses a place past its end (`gate_frame.check_reach`)."""
    return None

  def operation(self, block):
    """The compiled operation a view, termination or reward kind runs for `block`
    (its `view`, `end` or `reward`; a user's rule: the rule itself)."""
    return getattr(self, {"view": "view", "termination": "end", "reward": "reward",
                          "available": "offer", "binding": "bind"}[self.role])


class LearnerKind(Kind):
  """A learner kind (see the module docstring). `reads`: "state" or "features";
  `continuous`: it draws the value of its node's one continuous primitive."""

  role = "learner"
  reads = "state"
  continuous = False
  bootstraps_at_own_end = False   # its `terminal` is the world's end only, not its call's
                                  # own (an option's critic: `kinds.option_critic`)
  masked = False         # its choose and observe take the children's mask after `n`
                         # ("prefix": a mask that offers the first k children)
  start = choose = observe = None          # its compiled operations

  def check(self, name, block, n_children, view_size):
    """Refuses, naming the node, a block that cannot serve subtask `name` with
    `n_children` children whose view gives `view_size` (the number of states of a
    state view, None if it does not know them; the length of a features view)."""

  def settings(self, name, block, schedule=None):
    """Its settings (`P`: a namedtuple of arrays and 64-bit numbers). A kind whose
    `settings` takes a `schedule` parameter is given the graph's schedule record
    (`hierarchy.kinds.epsilon.Schedule`), whose `epsilon` array a learner that follows
    it keeps in its settings; `settings(self, name, block)` is enough for the rest."""
    return None

  def size(self, block):
    """What it reads: its number of states, or the length of its features."""
    raise NotImplementedError

  def learned(self, block, n_children):
    """A fresh `L`: the arrays it learns, by name (saved and restored by name)."""
    raise NotImplementedError

  def scratch(self, block, n_children):
    """A fresh `N`: a node's own scratch (not saved)."""
    raise NotImplementedError

  def parameters(self, learned):
    """Its parameters by name, copies (`Program.parameters`): by default every array
    it learns."""
    return {field: np.array(value) for field, value in learned._asdict().items()
            if isinstance(value, np.ndarray)}


class TableKind(LearnerKind):
  """A learner kind over a table of `block.n_states` states (its view's)."""

  def check(self, name, block, n_children, view_size):
    check_positive_int(block, "n_states", block.n_states)
    if view_size is not None and view_size != block.n_states:
      raise GraphError(f"subtask {name!r}: its view gives {view_size} states, its "
                       f"{type(block).__name__} has n_states = {block.n_states}")

  def size(self, block):
    return int(block.n_states)


class NodeKind(Kind):
  """A view, termination or reward kind."""

  def check(self, name, block, arguments):
    """Refuses, naming the node, a block that cannot serve subtask `name`, whose
    calls bind `arguments` ({name: whether an integer})."""


class ViewKind(NodeKind):
  """A view kind: `gives` "state" or "features"; `view` its compiled operation."""

  role = "view"
  gives = "state"
  writes = False             # a features view that writes into `out` (see above)
  reflects = False           # it also writes, at out[size], the sign of its learner's
                             # continuous action (a view reflected: `kinds.gate_route`)
  view = None
  takes_settings = True      # False: `view(obs, call)`, a user's rule

  def size(self, block):
    """The number of states it gives (None: unknown, the learner's), or the length
    of its features (None: the learner's)."""
    return None


class AvailableKind(NodeKind):
  """The children a node may choose in a state (its `available`): `offer(P, obs, call,
  mask)` writes True for each child offered (a learner with `masked` reads it)."""
  role = "available"
  offer = None
  takes_settings = True
  prefix = False             # it offers a state's first k children (a TiledQTable's kind)


class BindingKind(NodeKind):
  """A `Child`'s arguments decided when the parent calls it (`Child("navigate",
  bind=block)`): `bind(P, obs, call)` -> a tuple of the arguments' values, in the
  order of `names(block)` ({argument: whether an integer}); `call` is the parent's.
  What it gives is checked where it is bound (`boundary.as_bound`): as many finite
  numbers as its names, an integer argument's whole; else one line naming the
  parent, the child and the binding. Its `check(name, block, arguments)` refuses a block
  as the graph is built, `name` the parent and `arguments` what the parent's call binds."""
  role = "binding"
  bind = None
  takes_settings = True

  def names(self, block):
    """The arguments it binds: {name: whether an integer}."""
    raise NotImplementedError


class TerminationKind(NodeKind):
  """A termination kind: `end` its compiled operation (the module docstring)."""
  role = "termination"
  end = None
  takes_settings = True
  gives_internal = False     # its `end` returns (event, G)
  continuing = False         # a continuing root's (SPEC section 8: `algorithm.CONTINUING`)
  draws = False              # its `end` draws: end(P, obs, call, samples, rng), from the
                             # run's generator (a learned termination's)


class RewardKind(NodeKind):
  """An internal reward kind: `reward` its compiled operation (the module docstring)."""
  role = "reward"
  reward = None
  takes_settings = True
  from_termination = False   # G is its node's termination's (a `gives_internal` one)


def check_positive_int(block, field, value, low=1):
  """A block's integer field, refused in one line naming it and what is allowed."""
  if not arrays.is_count(value, low):
    raise GraphError(f"{type(block).__name__}.{field} = {value!r}: must be an integer >= {low}")
  return int(value)


def checked_size(name, block, size):
  """What a learner kind's `size(block)` gave at subtask `name`, refused in one line
  unless an integer >= 1 (a user's kind may pass on its block's float)."""
  if not arrays.is_count(size):
    raise GraphError(f"subtask {name!r}: the kind of its {type(block).__name__} gave size "
                     f"{size!r}; a learner kind's size(block) is an integer >= 1 (the states "
                     "its view gives, or the numbers its coder tiles)")
  return int(size)
