"""The open machine (`hierarchy.program`): a newcomer's hierarchy of their own rules
and a subtask with arguments, compiled; fused and step by step give the same numbers
bit for bit, and the Python executor with the step-by-step learners (the oracle)
gives them too; its learned arrays by name; a user's own learner kind; and every
wrong value a rule gives refused in one line naming the node, the value and what
was expected."""
import collections
import math
import re

import gymnasium
import numba
import numpy as np
import pytest

import hpg_mj  # noqa: F401  (registers the Gymnasium ids)
from hpg_mj.hierarchy import algorithm, blocks, executor, kinds, ship_rules
from hpg_mj.hierarchy.graph import Child, GraphError, Primitive, Subtask, TaskGraph
from hpg_mj.hierarchy.kinds import base
from hpg_mj.hierarchy.kinds.rules import Abstraction, Features, InternalReward, Termination
from hpg_mj.hierarchy.program import Program
from hpg_mj.learners import rng, stepwise, tiles
from hpg_mj.worlds import ship_core as core

WAYPOINTS = ((400.0, 300.0), (200.0, 600.0), (700.0, 600.0))
WORLD = (core.GATE_REWARD, core.OUT_OF_BOUNDS_REWARD, 400)


@numba.njit
def cell(obs, call):
  """The root's state: the 50 m cell of (x, y) on the 1,000 m field."""
  i = min(max(int(obs[0] // 50.0), 0), 19)
  j = min(max(int(obs[1] // 50.0), 0), 19)
  return i * 20 + j


@numba.njit
def aim(obs, call):
  """goto(x, y)'s state: the heading error to its point and the turning rate."""
  bearing = math.degrees(math.atan2(call.x - obs[0], call.y - obs[1]))
  return ((obs[2] - bearing + 180.0) % 360.0 - 180.0, obs[3])


@numba.njit
def arrived(obs, call):
  """goto's end: within 25 m of its point (success), or after `call.limit` steps."""
  if math.hypot(call.x - obs[0], call.y - obs[1]) < 25.0:
    return 1
  return -1 if call.steps >= call.limit else 0


@numba.njit
def closer(obs, call, event):
  """G: 10 for arriving."""
  return 10.0 * (event == 1)


CODER = tiles.TileCoder((-180.0, -15.0), (180.0, 15.0), (12, 6), (True, False), 5)


def one_node_graph(view=None, end=None, reward=None, learner=None):
  """goto alone, the root, for the boundary's checks (a program small to compile):
  `Program(graph, root_args=GOTO)`."""
  return TaskGraph("goto", [Primitive("turn"), Subtask(
      "goto", children=["turn"], termination=end or Termination(arrived),
      view=view or Features(aim), learner=learner or blocks.GaussianCMAC(CODER, alpha=0.02),
      internal_reward=reward)])


def table_graph(view):
  """A root alone over three turning rates by a table, for the boundary's checks."""
  return TaskGraph("root", [Primitive("left", -15.0), Primitive("ahead", 0.0),
                            Primitive("right", 15.0), Subtask(
      "root", children=["left", "ahead", "right"], termination=blocks.Never(),
      view=view, learner=blocks.QTable(400))])


GOTO = {"x": 500.0, "y": 400.0, "limit": 30}


def waypoint_graph(root_view=None, goto_view=None, end=None, reward=None, learner=None,
                   root_learner=None):
  """The issue's newcomer design: a root choosing among three waypoints, one shared
  goto(x, y) subtask (integer `limit`: its steps)."""
  goto = Subtask("goto", children=["turn"], termination=end or Termination(arrived),
                 view=goto_view or Features(aim),
                 learner=learner or blocks.GaussianCMAC(CODER, alpha=0.02),
                 internal_reward=reward or InternalReward(closer), reward=blocks.STEP)
  root = Subtask("root", children=[Child("goto", x=x, y=y, limit=80) for x, y in WAYPOINTS],
                 termination=blocks.Never(), view=root_view or Abstraction(cell),
                 learner=root_learner or blocks.QTable(400, alpha=0.1, trace_decay=0.9,
                                                       epsilon=0.2))
  return TaskGraph("root", [Primitive("turn"), goto, root])


def _counter(program, rows, node, what):
  """A node's counter column of the program's rows (0 calls, 1 runs, 2 successes)."""
  return rows[:, algorithm.ROW_COUNTERS + 3 * program.index[node] + what]


def _start(state):
  def draw():
    out = np.empty(4)
    core_start(state, out)
    return out
  return draw


def core_start(state, out):
  ship_rules.sample_start(state, out)


def _gym():
  return gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic", max_steps=WORLD[2])


def test_fused_and_step_by_step_agree_bit_for_bit():
  fused, stepped = Program(waypoint_graph()), Program(waypoint_graph())
  a, b = rng.make_state(3), rng.make_state(3)
  rows = fused.run(15, True, True, a, WORLD)
  rows_stepped = stepped.run_stepwise(_gym(), 15, True, True, b, _start(b),
                                      lambda last: last.info.get("event") == "gate")
  np.testing.assert_array_equal(rows[:, 1:], rows_stepped[:, 1:])
  np.testing.assert_array_equal(rows[:, 0], rows_stepped[:, 0])
  np.testing.assert_array_equal(a, b)
  assert rows[:, 1].sum() > 400                  # it sailed
  assert _counter(fused, rows, "goto", 0).sum() > 15    # goto called, more than once an episode
  for name, value in fused.state().items():
    np.testing.assert_array_equal(value, stepped.state()[name], err_msg=name)


def test_the_graphs_operations_compile_once_before_its_entry_points():
  """`graph_module.link` compiles each of the graph's operations for the types
  Algorithm 1 calls them with, so neither the fused loop nor the step-by-step entry
  points compile one again; each program holds the addresses of `enter`, `resume` and
  `judge` (a second program of the graph too), and takes them again in another
  process (here: its record of whose addresses they are lost)."""
  fused, stepped = Program(waypoint_graph()), Program(waypoint_graph())
  a, b = rng.make_state(5), rng.make_state(5)
  rows = fused.run(3, True, True, a, WORLD)
  stepped.run_stepwise(_gym(), 3, True, True, b, _start(b), lambda last: False)
  for op in ("enter", "resume", "judge", "chosen", "schedule_run", "schedule_episode",
             "schedule_decided"):
    assert len(getattr(fused._module, op).signatures) == 1, op
  assert (fused.frames.ops != 0).all()
  np.testing.assert_array_equal(fused.frames.ops, stepped.frames.ops)
  fused.frames.ops[:] = 0
  fused._linked_in = None
  again = fused.run(3, True, True, rng.make_state(5), WORLD)
  assert again.shape == rows.shape and (fused.frames.ops != 0).all()


class _Goto:
  """The oracle's goto(x, y): the same rules, in Python."""

  @staticmethod
  def view(call, obs):
    return CODER.active(np.array(aim.py_func(obs, _PyCall(call))))


class _PyCall:
  def __init__(self, call):
    self.x, self.y, self.limit = call.args["x"], call.args["y"], call.args["limit"]
    self.steps, self.origin = call.steps, call.origin


def test_the_python_executor_gives_the_same_numbers():
  """The oracle: the executor with `learners.stepwise`'s QLambda and
  GaussianPolicyGradient and the same rules in Python."""
  program = Program(waypoint_graph())
  a, b = rng.make_state(5), rng.make_state(5)
  rows = program.run(25, True, True, a, WORLD)
  q = stepwise.QLambda(400, 3, 0.1, 0.9, epsilon=0.2)
  g = stepwise.GaussianPolicyGradient(CODER.size, CODER.n_tilings, 15.0, 0.02)
  seen = collections.Counter()

  def step_reward(call, step, child):
    return core.STEP_REWARD

  def end(call, step):
    seen["end"] += 1
    return arrived.py_func(step.obs, _PyCall(call)) != 0

  def internal(call, step):
    return closer.py_func(step.obs, _PyCall(call), arrived.py_func(step.obs, _PyCall(call)))

  graph = TaskGraph("root", [
      Primitive("turn"),
      Subtask("goto", children=["turn"], termination=end, view=_Goto.view, learner=g,
              internal_reward=internal, reward=step_reward),
      Subtask("root", children=[Child("goto", x=x, y=y, limit=80) for x, y in WAYPOINTS],
              termination=lambda call, step: False,
              view=lambda call, obs: cell.py_func(obs, None), learner=q)])
  run = executor.Executor(graph, executor.adapter_for(_gym()), b)
  for i in range(25):
    start = np.empty(4)
    core_start(b, start)
    total, steps, last = run.run_episode(start, learn=True, sample=True)
    assert steps == rows[i, 1]
    assert total == rows[i, 2]
  np.testing.assert_array_equal(a, b)
  params = program.parameters()
  np.testing.assert_array_equal(params["root.q"], q.q)
  np.testing.assert_array_equal(params["goto.theta"], g.parameters())
  assert seen["end"] > 100


def test_learned_arrays_by_name_save_and_restore():
  program = Program(waypoint_graph())
  a = rng.make_state(1)
  program.run(20, True, True, a, WORLD)
  saved = {k: v.copy() for k, v in program.state().items()}
  assert {"root.q", "root.trace_index", "goto.theta", "goto.zs", "goto.values"} <= set(saved)
  after = program.run(10, True, True, a.copy(), WORLD)
  fresh = Program(waypoint_graph())
  for name, value in saved.items():
    fresh.state()[name][...] = value
  again = fresh.run(10, True, True, a.copy(), WORLD)
  np.testing.assert_array_equal(after, again)
  assert not np.array_equal(saved["root.q"], program.state()["root.q"])


def test_a_subtask_with_arguments_serves_every_point():
  """Each waypoint's goto ends at its own point: a success only within 25 m of it."""
  program = Program(waypoint_graph())
  a = rng.make_state(2)
  rows = program.run(300, True, True, a, WORLD)
  assert _counter(program, rows, "goto", 2).sum() > 20      # arrivals
  assert _counter(program, rows, "goto", 1).sum() > _counter(program, rows, "goto", 2).sum()


# ---- a user's own learner kind, in the user's file --------------------------------

@numba.njit
def _roundrobin_start(P, L, N):
  N.turn[0] = 0


@numba.njit
def _roundrobin_choose(P, L, N, x, n, rng_state, learn, sample):
  L.visits[x] += 1
  c = N.turn[0] % n
  N.turn[0] += 1
  return float(c)


@numba.njit
def _roundrobin_observe(P, L, N, x, signal, done, terminal, n, rng_state, learn, sample):
  L.returns[0] += signal
  if done:
    return 0.0
  return _roundrobin_choose(P, L, N, x, n, rng_state, learn, sample)


class RoundRobin:
  """A learner of the user's: its children in turn; counts the states it chose in."""

  def __init__(self, n_states):
    self.n_states = n_states


Learned = collections.namedtuple("Learned", ("visits", "returns"))
Scratch = collections.namedtuple("Scratch", ("turn",))


class RoundRobinKind(base.LearnerKind):
  block = RoundRobin
  reads = "state"
  start, choose, observe = (staticmethod(_roundrobin_start), staticmethod(_roundrobin_choose),
                            staticmethod(_roundrobin_observe))

  def size(self, block):
    return block.n_states

  def learned(self, block, n_children):
    return Learned(np.zeros(block.n_states, dtype=np.int64), np.zeros(1))

  def scratch(self, block, n_children):
    return Scratch(np.zeros(1, dtype=np.int64))


def test_a_learner_kind_of_the_users_own():
  kinds.register(RoundRobinKind())
  graph = waypoint_graph()
  graph.nodes["root"].learner = RoundRobin(400)
  program = Program(graph)
  rows = program.run(5, True, True, rng.make_state(0), WORLD)
  state = program.state()
  # One choice a call of goto (the last, cut by the episode's end, counted too), and
  # the children in turn: 0, 1, 2, 0, ...
  assert state["root.visits"].sum() == _counter(program, rows, "goto", 0).sum()
  assert state["root.returns"][0] == rows[:, algorithm.ROW_RETURN].sum()
  # Its size, from the user's block as given (a float here), is checked before any
  # array is made of it: one line naming the node, what it gave and what is allowed.
  graph.nodes["root"].learner = RoundRobin(400.0)
  with pytest.raises(GraphError, match=r"^subtask 'root': the kind of its RoundRobin gave "
                                       r"size 400.0; a learner kind's size\(block\) is an "
                                       r"integer >= 1 "):
    Program(graph)


# ---- the boundary: each wrong thing a rule gives --------------------------------

@numba.njit
def _state_past_table(obs, call):
  return 400 + int(obs[0] // 100.0)


@numba.njit
def _float_state(obs, call):
  return obs[0] / 50.0


@numba.njit
def _two_of_three(obs, call):
  return (obs[2], obs[3])


@numba.njit
def _nan_feature(obs, call):
  return (math.nan, obs[3])


@numba.njit
def _mixed_nan(obs, call):          # (a float and an int: a tuple of mixed types)
  return (math.nan if call.steps >= 3 else obs[2], 0)


@numba.njit
def _event_two(obs, call):
  return 2


@numba.njit
def _event_float(obs, call):
  return 0.5


@numba.njit
def _reward_inf(obs, call, event):
  return math.inf


CODER3 = tiles.TileCoder((-180.0, -15.0, 0.0), (180.0, 15.0, 1000.0), (12, 6, 4),
                         (True, False, False), 5)


@pytest.mark.parametrize("graph, message", [
    (lambda: table_graph(Abstraction(_state_past_table)),
     "subtask 'root': its view Abstraction(_state_past_table) gave 4"),
    (lambda: table_graph(Abstraction(_float_state)),
     "subtask 'root': its view Abstraction(_float_state) gave "),
    (lambda: one_node_graph(view=Features(_two_of_three), learner=blocks.GaussianCMAC(CODER3)),
     "subtask 'goto': its view Features(_two_of_three) gave 2 numbers; expected a tuple of 3"),
    (lambda: one_node_graph(view=Features(_nan_feature)),
     "subtask 'goto': its view Features(_nan_feature) gave nan; expected a tuple of 2 finite"),
    (lambda: one_node_graph(view=Features(_mixed_nan)),
     "subtask 'goto': its view Features(_mixed_nan) gave nan; expected a tuple of 2 finite"),
    (lambda: one_node_graph(end=Termination(_event_two)),
     "subtask 'goto': its termination Termination(_event_two) gave 2; expected 0 (go on)"),
    (lambda: one_node_graph(end=Termination(_event_float)),
     "subtask 'goto': its termination Termination(_event_float) gave 0.5 (a float)"),
    (lambda: one_node_graph(reward=InternalReward(_reward_inf)),
     "subtask 'goto': its internal reward InternalReward(_reward_inf) gave inf; expected a "
     "finite number"),
])
def test_a_wrong_value_is_one_line_naming_the_node(graph, message):
  """Fused; the step-by-step path runs the same compiled checks (below)."""
  program = Program(graph(), root_args=GOTO)
  with pytest.raises(ValueError) as e:
    program.run(3, True, True, rng.make_state(0), WORLD)
  text = str(e.value)
  assert message in text, text
  assert "\n" not in text


def test_a_wrong_value_step_by_step_is_the_same_line_and_no_crash():
  """The issue's crash: a root view giving states 400-409 for a 400-state table."""
  program = Program(table_graph(Abstraction(_state_past_table)))
  a = rng.make_state(0)
  with pytest.raises(ValueError, match=r"^subtask 'root': its view "
                                       r"Abstraction\(_state_past_table\) gave 40\d; expected "
                                       r"an integer state in \[0, 400\)$"):
    program.run_stepwise(_gym(), 3, True, True, a, _start(a), lambda last: 0.0)


@numba.njit
def _past_the_observation(obs, call):
  return (obs[2], obs[3], obs[4])        # the steering ship's observation holds 4 numbers


def test_a_rule_reading_past_the_observation_is_one_line_not_memory():
  """A newcomer's view read obs[11] of the harbour's 11 numbers and trained on whatever
  memory lay there. A user's own compiled functions are compiled with numba's bounds
  check (`program.bounds_checked`): the read raises, one line naming the user's code,
  and the read itself where its index is written past the end, on both paths; hpg_mj's
  own functions are compiled as they are."""
  from hpg_mj.hierarchy import boundary
  assert boundary.bounds_checked(arrived) is not arrived
  assert boundary.bounds_checked(arrived).targetoptions["boundscheck"] is True
  assert boundary.bounds_checked(arrived) is boundary.bounds_checked(arrived)
  assert boundary.bounds_checked(ship_rules.sample_start) is ship_rules.sample_start
  graph = lambda: one_node_graph(view=Features(_past_the_observation),  # noqa: E731
                                 learner=blocks.GaussianCMAC(CODER3))
  want = (r"^the graph's compiled program read past the end of an array \(index is out of "
          r"bounds\); numba checks the bounds in your own code but does not say which read it; "
          r"one of: view "
          r"Features\(_past_the_observation\), termination Termination\(arrived\) \(the "
          r"observation holds 4 numbers, obs\[0\] to obs\[3\]\); past it at a fixed index: "
          r"view Features\(_past_the_observation\) reads obs\[4\] \(test_program.py, line "
          r"\d+\)$")
  with pytest.raises(IndexError, match=want):
    Program(graph(), root_args=GOTO).run(3, True, True, rng.make_state(0), WORLD)
  a = rng.make_state(0)
  with pytest.raises(IndexError, match=want):
    Program(graph(), root_args=GOTO).run_stepwise(_gym(), 3, True, True, a, _start(a),
                                                  lambda last: 0.0)


# A learner kind of the user's that chooses what its block says: a child's index
# past the node's children, or a float that is not one, is refused, not read as a
# primitive (it had run silently: no call of a subtask, the last action repeated).

@numba.njit
def _giving_start(P, L, N):
  pass


@numba.njit
def _giving_choose(P, L, N, x, n, rng_state, learn, sample):
  return P.give


@numba.njit
def _giving_observe(P, L, N, x, signal, done, terminal, n, rng_state, learn, sample):
  return P.give


class Giving:
  """A learner block of the user's that chooses `give`, every time."""

  def __init__(self, give):
    self.n_states, self.give = 400, give


GivingSettings = collections.namedtuple("GivingSettings", ("give",))


class GivingKind(base.TableKind):
  block = Giving
  start, choose, observe = (staticmethod(_giving_start), staticmethod(_giving_choose),
                            staticmethod(_giving_observe))

  def settings(self, name, block):
    return GivingSettings(float(block.give))

  def learned(self, block, n_children):
    return Learned(np.zeros(1, dtype=np.int64), np.zeros(1))

  def scratch(self, block, n_children):
    return Scratch(np.zeros(1, dtype=np.int64))


kinds.register(GivingKind())


def _giving_graph(give):
  return TaskGraph("root", [Primitive("left", -15.0), Primitive("ahead", 0.0),
                            Primitive("right", 15.0), Subtask(
      "root", children=["left", "ahead", "right"], termination=blocks.Never(),
      view=Abstraction(cell), learner=Giving(give))])


@pytest.mark.parametrize("give, said", [(3.0, "3"), (-1.0, "-1"), (0.5, "0.5"), (math.nan, "nan"),
                                        (1e300, "1e+300")])
def test_a_learner_choosing_no_child_of_its_node_is_one_line_on_both_paths(give, said):
  line = (f"subtask 'root': its learner Giving chose {said}; expected a child's index in "
          "[0, 3)")
  program = Program(_giving_graph(give))
  with pytest.raises(ValueError) as e:
    program.run(2, True, True, rng.make_state(0), WORLD)
  assert str(e.value) == line
  a = rng.make_state(0)
  with pytest.raises(ValueError) as e:
    program.run_stepwise(_gym(), 2, True, True, a, _start(a), lambda last: 0.0)
  assert str(e.value) == line
  rows = Program(_giving_graph(2.0)).run(2, True, True, rng.make_state(0), WORLD)
  assert (rows[:, algorithm.ROW_STEPS] > 0).all()        # a child's index runs


# A binding kind of the user's: goto's point and its integer `limit` decided when the
# root calls it; what it gives is checked where it is bound, naming the child and the
# binding (a NaN had been blamed on goto's view; a short tuple was numba's "tuple index
# out of range" from the graph's module).

@numba.njit
def _point_bind(P, obs, call):
  x = math.nan if P.mode == 1 else P.x
  return (x, obs[1], 2.5 if P.mode == 2 else 80.0)


@numba.njit
def _short_bind(P, obs, call):
  return (P.x, obs[1])


class Point:
  """Binds goto(x, y, limit): x its own, y the ship's; mode 1 gives x NaN, mode 2
  gives limit 2.5."""

  def __init__(self, x, mode=0):
    self.x, self.mode = x, mode


class ShortPoint(Point):
  """Binds goto(x, y, limit) with two numbers."""


PointSettings = collections.namedtuple("PointSettings", ("x", "mode"))


class PointKind(base.BindingKind):
  block = Point
  bind = staticmethod(_point_bind)

  def names(self, block):
    return {"x": False, "y": False, "limit": True}

  def settings(self, name, block):
    return PointSettings(float(block.x), np.int64(block.mode))


class ShortPointKind(PointKind):
  block = ShortPoint
  bind = staticmethod(_short_bind)


kinds.register(PointKind())
kinds.register(ShortPointKind())


def _bound_graph(bind, view=None, extra=None):
  goto = Subtask("goto", children=["turn"], termination=Termination(arrived),
                 view=view or Features(aim), learner=blocks.GaussianCMAC(CODER, alpha=0.02),
                 reward=blocks.STEP)
  root = Subtask("root", children=[Child("goto", bind=Point(300.0)), Child("goto", bind=bind)] +
                 ([extra] if extra else []),
                 termination=blocks.Never(), view=Abstraction(cell),
                 learner=blocks.QTable(400, alpha=0.1, epsilon=0.2))
  return TaskGraph("root", [Primitive("turn"), goto, root])


@pytest.mark.parametrize("bind, said", [
    (Point(500.0, mode=1), "gave nan; expected a tuple of 3 finite numbers, one for each of "
                           "its names ['x', 'y', 'limit'] (limit whole)"),
    (Point(500.0, mode=2), "gave 2.5 (a float); expected a tuple of 3 finite numbers"),
    (ShortPoint(500.0), "gave 2 numbers; expected a tuple of 3 finite numbers"),
])
def test_what_a_binding_gives_is_checked_where_it_is_bound(bind, said):
  program = Program(_bound_graph(bind))
  line = f"subtask 'root': its child 1 ('goto') bound by {type(bind).__name__} {said}"
  with pytest.raises(ValueError) as e:
    program.run(20, True, True, rng.make_state(0), WORLD)
  assert str(e.value).startswith(line) and "\n" not in str(e.value), str(e.value)
  a = rng.make_state(0)
  with pytest.raises(ValueError) as e:
    program.run_stepwise(_gym(), 20, True, True, a, _start(a), lambda last: 0.0)
  assert str(e.value).startswith(line), str(e.value)
  fine = Program(_bound_graph(Point(500.0)))
  rows = fine.run(20, True, True, rng.make_state(0), WORLD)
  assert _counter(fine, rows, "goto", 0).sum() > 0            # whole floats bind an integer


@numba.njit
def _reads_z(obs, call):
  return (call.z - obs[0], obs[3])


@numba.njit
def _reads_array_field(obs, call):
  return (obs.nothing, obs[3])


@numba.njit
def _no_such_function(obs, call):
  return (math.hypotenuse(call.x - obs[0], call.y - obs[1]), obs[3])


def test_a_rule_naming_what_a_module_lacks_is_one_line_too():
  """`math.hypotenuse`: numba passes Python's AttributeError on with no place (150
  lines of numba's); it is the same one line, naming the user's file and line."""
  program = Program(one_node_graph(view=Features(_no_such_function)), root_args=GOTO)
  with pytest.raises(GraphError) as e:
    program.run(1, True, True, rng.make_state(0), WORLD)
  _assert_names_the_line(e.value, _no_such_function,
                         r"module 'math' has no attribute 'hypotenuse'")


def _assert_names_the_line(error, fn, reason):
  """`error` is the one line of a compile error in `fn` (its body's first line), with
  numba's `reason` (a regular expression)."""
  line = fn.py_func.__code__.co_firstlineno + 2
  assert re.fullmatch(rf"\S*test_program\.py, line {line}: your compiled code does not "
                      rf"compile: {reason} \(numba's reason; calling that function alone "
                      r"shows its whole message\)", str(error)), str(error)


def test_a_rule_reading_an_argument_nobody_binds_is_one_line_naming_the_subtask():
  """numba's typing error (40 lines into the graph's module) read for the subtask, its
  rule and the names its calls bind; any other typing error in the user's own code, one
  line naming their file, the line and numba's reason (not 40-80 lines of numba's)."""
  line = ("subtask 'goto': its view Features(_reads_z) reads call.z; its calls bind ['limit', "
          "'x', 'y'] (and call.origin, call.steps)")
  program = Program(_bound_graph(Point(500.0), view=Features(_reads_z)))
  with pytest.raises(GraphError) as e:
    program.run(1, True, True, rng.make_state(0), WORLD)
  assert str(e.value) == line
  a = rng.make_state(0)
  with pytest.raises(GraphError) as e:
    program.run_stepwise(_gym(), 1, True, True, a, _start(a), lambda last: 0.0)
  assert str(e.value) == line
  program = Program(one_node_graph(view=Features(_reads_array_field)), root_args=GOTO)
  with pytest.raises(GraphError) as e:
    program.run(1, True, True, rng.make_state(0), WORLD)
  _assert_names_the_line(e.value, _reads_array_field,
                         r"Unknown attribute 'nothing' of type array\(float64, 1d, C\)")


def _twins(view):
  """A root choosing between two subtasks of one shape (their kinds, their records'
  types): the graph's operations give both one branch."""
  twins = [Subtask(name, children=["turn"], termination=Termination(arrived), view=view,
                   learner=blocks.GaussianCMAC(CODER, alpha=0.02), reward=blocks.STEP)
           for name in ("left", "right")]
  root = Subtask("root", children=[Child("left", x=300.0, y=700.0, limit=50),
                                   Child("right", x=700.0, y=300.0, limit=50)],
                 termination=blocks.Never(),
                 view=Abstraction(cell), learner=blocks.QTable(400, alpha=0.1, epsilon=0.2))
  return TaskGraph("root", [Primitive("turn"), *twins, root])


def test_subtasks_of_one_shape_share_a_branch_and_a_rule_error_names_both():
  program = Program(_twins(Features(aim)))
  with open(program.module_path) as f:
    text = f.read()
  left, right = program.index["left"], program.index["right"]
  assert text.count(f"node == {left} or node == {right}:") == 4    # enter, resume, judge, chosen
  rows = program.run(20, True, True, rng.make_state(0), WORLD)
  assert rows[:, algorithm.ROW_STEPS].sum() > 0
  line = ("subtasks 'left', 'right': its view Features(_reads_z) reads call.z; its calls "
          "bind ['limit', 'x', 'y'] (and call.origin, call.steps)")
  with pytest.raises(GraphError) as e:
    Program(_twins(Features(_reads_z))).run(1, True, True, rng.make_state(0), WORLD)
  assert str(e.value) == line


def _plain(obs, call):
  return 0


class _Unregistered:
  """A learner block no kind is registered for."""


@pytest.mark.parametrize("make, message", [
    (lambda: waypoint_graph(root_view=Features(aim)),
     "subtask 'root': its learner QTable reads state, its view Features(aim) gives features"),
    (lambda: waypoint_graph(goto_view=Abstraction(cell)),
     "subtask 'goto': its learner GaussianCMAC reads features, its view Abstraction(cell) gives "
     "state"),
    (lambda: waypoint_graph(learner=blocks.ActorCritic(CODER, CODER)),
     "subtask 'goto': an ActorCritic's critic_coder tiles 2 numbers; it must tile 3: the 2 "
     "the actor_coder tiles, then the action r"),
    # a block's own setting, refused by its kind, named where the block is used
    (lambda: waypoint_graph(root_learner=blocks.QTable(400.0)),
     "subtask 'root': QTable.n_states = 400.0: must be an integer >= 1"),
    (lambda: waypoint_graph(learner=blocks.GaussianCMAC(CODER, alpha=-1.0)),
     "subtask 'goto': GaussianCMAC.alpha = -1.0: must be a finite number >= 0.0"),
    (lambda: waypoint_graph(learner=_Unregistered()),
     "subtask 'goto': its learner _Unregistered has no start, act, observe; a learner "
     "answers start()"),
    (lambda: TaskGraph("root", [Primitive("turn"), Subtask(
        "goto", children=["turn"], termination=Termination(arrived), view=Features(aim),
        learner=blocks.GaussianCMAC(CODER)), Subtask(
        "root", children=[Child("goto", x=1.0, y=2.0, limit=80), Child("goto", x=1.0, limit=80)],
        termination=blocks.Never(), view=Abstraction(cell), learner=blocks.QTable(400))]),
     "subtask 'goto': its calls bind different arguments: root's child 0 (x=1.0, y=2.0, "
     "limit=80) binds ['limit', 'x', 'y']; root's child 1 (x=1.0, limit=80) binds ['limit', "
     "'x']; every "
     "call of a subtask binds the same names"),
    (lambda: _bound_graph(Point(1.0), extra=Child("goto", x=1.0, y=2.0)),
     "subtask 'goto': its calls bind different arguments: root's child 2 (x=1.0, y=2.0) binds "
     "['x', 'y']; its other 2 calls bind ['limit', 'x', 'y']; every call of a subtask binds "
     "the same names"),
    (lambda: TaskGraph("root", [Primitive("turn"), Subtask(
        "goto", children=["turn"], termination=Termination(arrived), view=Features(aim),
        learner=blocks.GaussianCMAC(CODER)), Subtask(
        "spare", children=["turn"], termination=Termination(arrived), view=Features(aim),
        learner=blocks.GaussianCMAC(CODER)), Subtask(
        "root", children=[Child("goto", x=1.0, y=2.0, limit=80)],
        termination=blocks.Never(), view=Abstraction(cell), learner=blocks.QTable(400))]),
     "subtask 'spare' is called by no node of the graph; call it (Child('spare', ...)) or "
     "leave it out"),
    (lambda: waypoint_graph(goto_view=Features(numba.njit(_plain))),
     None),
])
def test_a_graph_the_machine_cannot_run_is_refused_naming_the_node(make, message):
  if message is None:            # (a rule that fits compiles)
    make()
    return
  with pytest.raises(GraphError, match="^" + re.escape(message)):
    Program(make())


def test_a_rule_that_is_not_compiled_is_refused():
  with pytest.raises(GraphError, match=r"Features: rule <function _plain .*> is not a "
                                       r"@numba.njit function"):
    Features(_plain)


# ---- the stand-alone subtasks (Program.run_alone) ---------------------------------------

@pytest.mark.parametrize("task, env_id", [("diagonal", "hpg_mj/ShipSteeringDiagonal-v0"),
                                          ("straight", "hpg_mj/ShipSteeringStraight-v0")])
def test_a_subtask_alone_is_the_same_fused_and_through_its_environment(task, env_id):
  """The stand-alone subtask (`ship_subtask`: the root alone, `Program.run_alone`) fused with
  the analytic ship and step by step through its Gymnasium environment: the same
  episodes, ends and learned parameters (its environment's reward holds G too,
  so only the return column differs)."""
  from hpg_mj.hierarchy import ship_subtask
  direction = ship_subtask.TASKS[task]
  runs = []
  for fused in (True, False):
    learner = blocks.GaussianCMAC(ship_subtask.paper_coder(), 0.01, 0.99, 0.3, 15.0, 0.003)
    m = Program(ship_subtask.graph(task, learner, 300), root_args={"direction": direction})
    state = rng.make_state(7)
    if fused:
      rows = m.run_alone(60, True, True, state)
    else:
      def start():
        out = np.empty(4)
        ship_rules.sample_local_start(state, direction, out)
        return out
      rows = m.run_stepwise(gymnasium.make(env_id, backend="analytic"), 60, True, True, state,
                            start, lambda last: last.info.get("event") == "goal")
    runs.append((np.delete(rows, 2, axis=1), *m.parameters().values()))
  for a, b in zip(*runs):
    np.testing.assert_array_equal(a, b)
  assert runs[0][0][:, 0].sum() > 0                                 # some calls succeeded



# ---- the step-by-step path's inputs -------------------------------------------------

def test_an_argument_of_another_kind_is_not_read_as_the_contiguous_one():
  """`Program._stepwise` calls numba's entry point for the argument kinds it has seen,
  which checks no types: a generator state of another layout (a strided view) must
  not be read as the contiguous one (the compiled code takes C arrays: it goes in as
  a contiguous copy and comes back). Both draws, from the same state, give the same
  action and leave the same state; a read-only observation is taken too."""
  from hpg_mj import agents
  m = agents.build(agents.load_task("ship_actor_critic"), seed=0).machine
  obs = np.array([400.0, 300.0, 10.0, 0.0])
  state = rng.make_state(7)
  strided = np.zeros(8, dtype=np.uint64)
  strided[::2] = state
  first = m.begin(obs, False, True, state)
  second = m.begin(obs, False, True, strided[::2])
  assert first == second
  np.testing.assert_array_equal(strided[::2], state)
  assert strided[1::2].sum() == 0
  obs.flags.writeable = False
  assert m.begin(obs, False, False, state) == m.begin(obs.copy(), False, False, state)


def test_observations_of_any_kind_are_read_as_their_values():
  """`Program.advance` passes a float64 observation and sampled positions in C order to
  the compiled code as they are, and copies any other into float64 arrays in C order:
  a float32, integer, strided or list observation, and strided positions, give what
  their float64 values give, on the first step (through the dispatcher) and the next
  (its entry point, called straight away); an observation that is not a vector, or not
  of the program's length, is refused, by name."""
  from hpg_mj import agents
  m = agents.build(agents.load_task("ship_actor_critic"), seed=0).machine
  state = rng.make_state(3)
  obs = np.array([400.0, 300.0, 10.0, 2.0])
  positions = np.array([[399.0, 298.5], [399.3, 299.0], [399.6, 299.5], [400.0, 300.0]])
  def episode(start, after, samples):
    s = state.copy()
    first = m.begin(start, False, True, s)
    return first, [m.advance(after, -1.0, False, False, {"positions": samples}, False, True, s)
                   for _ in range(3)]
  expected = episode(obs, obs + 1.5, positions)
  wide = np.zeros((4, 4))
  wide[:, ::2] = positions
  for start, after, samples in ((obs.astype(np.float32), (obs + 1.5).astype(np.float32),
                                 positions.astype(np.float32)),
                                (np.repeat(obs, 2)[::2], list(obs + 1.5), wide[:, ::2])):
    assert episode(start, after, samples) == expected
  assert episode(np.array([400, 300, 10, 2]), obs + 1.5, positions) == expected
  with pytest.raises(ValueError, match="Program: obs must be a vector"):
    m.begin(obs.reshape(2, 2), False, True, state)
  with pytest.raises(ValueError, match=r"Program: info\['positions'\] must be rows of \(x, y\)"):
    m.advance(obs, -1.0, False, False, {"positions": positions.ravel()}, False, True, state)
  for longer in (np.append(obs, 1.0), [*obs, 1.0]):       # as it is / copied
    m.begin(obs, False, True, state)
    m.advance(obs, -1.0, False, False, {}, False, True, state)
    with pytest.raises(ValueError, match="an observation of 5 numbers; this program was built "
                                         "for obs_size = 4"):
      m.advance(longer, -1.0, False, False, {}, False, True, state)


def test_an_observation_of_another_length_is_refused_and_changes_nothing():
  """An observation of another length than the program's is refused in one line, on
  the first step and within an episode, and the fused loop then trains as a program
  that never saw it."""
  from hpg_mj import agents
  task = agents.load_task("ship_actor_critic")
  seen, fresh = (agents.build(task, seed=0) for _ in range(2))
  state = rng.make_state(5)
  wide = np.array([400.0, 300.0, 10.0, 2.0, 7.0, 9.0])
  with pytest.raises(ValueError, match="an observation of 6 numbers"):
    seen.machine.begin(wide, False, False, state)
  seen.machine.begin(wide[:4], False, False, state)
  with pytest.raises(ValueError, match="an observation of 6 numbers"):
    seen.machine.advance(wide + 1.0, -1.0, False, False, {}, False, False, state)
  a, b = seen.train(5), fresh.train(5)
  for field in a.dtype.names:
    np.testing.assert_array_equal(a[field], b[field])
