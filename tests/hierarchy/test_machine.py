"""The compiled machine (`hierarchy.machine`) against the pure-Python oracle on random
graphs of blocks: fused, step by step and in the oracle, every record and every
learned parameter is the same bit for bit; and what the machine refuses."""
import numba
import numpy as np
import pytest
import compile_order

import hpg_mj  # noqa: F401
import gymnasium
from hpg_mj.hierarchy import blocks, machine, ship_rules
from hpg_mj.hierarchy.graph import Child, GraphError, Primitive, Subtask, TaskGraph
from hpg_mj.learners import stepwise
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import rng, tiles
import oracle


# A user's rules (`blocks.CellRule`, `EndRule`, `RewardRule`), as a user writes them.
@numba.njit
def _boxed(obs, origin, arg, steps):
  """A region's end: 200 m from where it began (failure), or 120 steps (success)."""
  dx, dy = obs[0] - origin[0], obs[1] - origin[1]
  if dx * dx + dy * dy > 200.0 ** 2:
    return -1
  return 1 if steps >= 120 else 0


@numba.njit
def _steady(obs, origin, arg, steps, event):
  """G: turning costs, a success pays."""
  return -0.01 * abs(obs[3]) + 5.0 * event


@numba.njit
def _quadrant(obs, origin, arg, steps):
  """The field's quarter, 0-3."""
  return (obs[0] >= 500.0) * 2 + (obs[1] >= 500.0)


def _local_coder(g):
  return tiles.TileCoder((0.0, 0.0, -180.0, -15.0), (150.0, 150.0, 180.0, 15.0),
                         (int(g.integers(2, 6)), int(g.integers(2, 6)), int(g.integers(4, 37)),
                          int(g.integers(2, 6))), (False, False, True, False),
                         int(g.integers(1, 6)))


def _route_graph(g):
  """A root over tiles of (x, y, heading) choosing targets (`blocks.GatePoints`) for
  an aim subtask (`blocks.AimTiles`, `blocks.TargetReached`)."""
  root_coder = tiles.TileCoder((0.0, 0.0, -45.0), (1000.0, 1000.0, 315.0),
                               (int(g.integers(2, 11)), int(g.integers(2, 11)), 4),
                               (False, False, True), int(g.integers(1, 9)))
  reflect, scale = float(g.choice([180.0, 90.0, 45.0])), str(g.choice(["sqrt", "linear"]))
  aim_coder = tiles.TileCoder((-ship_rules.error_coordinate(reflect, scale), -15.0, 0.0),
                              (180.0, 15.0, ship_rules.DISTANCE_CLIP),
                              (int(g.integers(6, 37)), int(g.integers(2, 7)), int(g.integers(2, 5))),
                              (reflect == 180.0, False, False), int(g.integers(1, 9)))
  root = blocks.TiledQTable(root_coder, float(g.uniform(0.05, 0.3)), float(g.uniform(0.0, 0.95)),
                            float(g.uniform(0.05, 0.5)), epsilon_schedule=bool(g.random() < 0.5))
  aim = blocks.GaussianCMAC(aim_coder, float(g.uniform(0.002, 0.05)),
                            float(g.choice([1.0, 0.99])), float(g.choice([0.0, 0.3])), 15.0,
                            float(g.choice([0.0, 0.01])), 0.25, float(g.choice([1.0, 4.0])))
  targets = blocks.GatePoints(float(g.uniform(0.0, 10.0)), float(g.uniform(30.0, 150.0)),
                              float(g.uniform(5.0, 60.0)))
  chosen = g.choice(ship_rules.N_TARGETS, size=int(g.integers(1, 5)), replace=False)
  return TaskGraph("root", [
      Subtask("root", children=[Child("aim", target=int(t)) for t in chosen], learner=root,
              view=blocks.StateTiles(root_coder), termination=blocks.Never(),
              available=blocks.NearGateLine(float(g.uniform(50.0, 1000.0)))),
      Subtask("aim", children=["turn"], learner=aim,
              view=blocks.AimTiles(aim_coder, targets, scale, reflect),
              termination=blocks.TargetReached(int(g.integers(30, 300))),
              internal_reward=blocks.Shaping(float(g.uniform(0.0, 2.0)))
              if g.random() < 0.7 else None,
              reward=blocks.STEP if g.random() < 0.7 else blocks.SUMMED),
      Primitive("turn")],
      schedule=blocks.HeldEpsilon(float(g.uniform(0.1, 0.5)), ("aim",)[:int(g.integers(0, 2))],
                                  0.5, 3, 2, 1.5))


def random_graph(seed):
  """A random graph of blocks: flat, two levels (root over legs), three (root over
  regions over legs) or a route (a tiled root over targets for an aim subtask), with
  random learners, sizes, ends and rewards."""
  g = np.random.default_rng(seed)
  shape = ("flat", "two", "three", "route")[seed % 4]
  if shape == "route":
    return _route_graph(g)
  if shape == "flat":
    coder = tiles.TileCoder((0.0, 0.0, -180.0, -15.0), (1000.0, 1000.0, 180.0, 15.0),
                            (int(g.integers(2, 21)), int(g.integers(2, 21)), 36, 5),
                            (False, False, True, False), int(g.integers(1, 10)))
    learner = blocks.GaussianCMAC(coder, float(g.uniform(0.002, 0.05)),
                                  float(g.choice([1.0, 0.97])), 0.0, 15.0)
    return TaskGraph("policy", [Subtask("policy", children=["turn"], learner=learner,
                                        view=blocks.StateTiles(coder),
                                        termination=blocks.Never()), Primitive("turn")])
  legs = []
  for i in range(int(g.integers(1, 3))):
    coder = _local_coder(g)
    learner = blocks.GaussianCMAC(coder, float(g.uniform(0.002, 0.05)),
                                  float(g.choice([1.0, 0.95])), float(g.choice([0.0, 0.1])),
                                  15.0, float(g.choice([0.0, 0.0, 0.01])), 0.25,
                                  float(g.choice([1.0, 4.0])))
    legs.append(Subtask(f"leg{i}", children=["turn"], learner=learner,
                        view=blocks.LocalTiles(coder),
                        termination=blocks.LocalGoal(int(g.integers(20, 300))),
                        internal_reward=(blocks.Shaping(), None, blocks.RewardRule(_steady))[
                            int(g.choice(3, p=[0.6, 0.2, 0.2]))],
                        reward=blocks.STEP if g.random() < 0.7 else blocks.SUMMED))

  def calls(k):
    directions = g.choice(8, size=int(g.integers(1, k + 1)), replace=False)
    return [Child(legs[int(g.integers(len(legs)))].name, direction=int(d)) for d in directions]

  def q_table(n_states):
    return blocks.QTable(n_states, float(g.uniform(0.05, 0.3)), float(g.uniform(0.0, 0.95)),
                         float(g.uniform(0.05, 0.5)), epsilon_schedule=bool(g.random() < 0.5))

  grid = int(g.choice([10, 20]))
  root_children = calls(8)
  mids = []
  if shape == "three":
    ruled = g.random() < 0.5
    mids = [Subtask("region", children=calls(4), learner=q_table(4 if ruled else 400),
                    view=blocks.CellRule(_quadrant) if ruled else blocks.GridCell(50.0, 20),
                    termination=(blocks.EndRule(_boxed) if ruled else
                                 blocks.LocalGoal(int(g.integers(50, 400)))))]
    root_children = [Child("region", direction=int(d))
                     for d in g.choice(8, size=int(g.integers(1, 5)), replace=False)]
    grid = 4
  root = Subtask("root", children=root_children, learner=q_table(grid * grid),
                 view=blocks.GridCell(1000.0 / grid, grid), termination=blocks.Never())
  used = sorted({r.node for r in root_children} | {c.node for m in mids for c in m.children})
  watch = tuple(used[:int(g.integers(0, len(used) + 1))])
  return TaskGraph("root", [root, *mids, *legs, Primitive("turn")],
                   schedule=blocks.HeldEpsilon(float(g.uniform(0.1, 0.5)), watch, 0.5, 3, 2, 1.5))


def _parameters(m, graph):
  out = {}
  for node in graph.subtasks():
    if isinstance(node.learner, (blocks.QTable, blocks.TiledQTable)):
      out[node.name] = m.q_arrays(node.learner)[0].copy()
    else:
      trace, values = m.gaussian_arrays(node.learner)
      width = m.width_trace(node.learner)
      out[node.name] = np.concatenate([el.parameters(trace), values] + (
          [] if width is None else [el.parameters(width)]))
  return out


def _oracle_parameters(o, graph):
  out = {}
  for node in graph.subtasks():
    learner = o.learners[id(node.learner)]
    if isinstance(node.learner, (blocks.QTable, blocks.TiledQTable)):
      out[node.name] = learner.q.copy()
    else:
      width = [] if learner.width is None else [el.parameters(learner.width)]
      out[node.name] = np.concatenate([learner.parameters(), learner.values] + width)
  return out


@pytest.mark.parametrize("seed", range(12))
def test_random_graphs_give_the_oracles_numbers_on_every_path(seed):
  graph = random_graph(seed)
  max_steps = 150 + 25 * seed
  world = (100.0, -300.0, max_steps)
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic", max_steps=max_steps,
                       gate_reward=100.0, out_of_bounds_reward=-300.0)
  fused, stepwise = machine.Machine(graph), machine.Machine(graph)
  states = [rng.make_state(seed) for _ in range(3)]
  o = oracle.Oracle(graph, states[2])

  def start(state):
    def draw():
      out = np.empty(4)
      ship_rules.sample_start(state, out)
      return out
    return draw

  calls = ([], [])

  def told(k):
    return lambda call: calls[k].append((call.node, sorted(call.args.items()),
                                         float(call.origin[0]), float(call.origin[1])))

  for learn, sample, episodes in ((True, True, 6), (False, True, 2), (False, False, 2)):
    a = fused.run(episodes, learn, sample, states[0], world)
    b = machine.run_stepwise(stepwise, env, episodes, learn, sample, states[1],
                             start(states[1]), lambda last: last.info.get("event") == "gate",
                             on_call=told(0))
    c = o.run(env, episodes, learn, sample, start(states[2]), on_call=told(1))
    np.testing.assert_array_equal(a, c, err_msg=f"fused vs oracle, learn={learn}")
    np.testing.assert_array_equal(b, c, err_msg=f"stepwise vs oracle, learn={learn}")
    if learn:
      assert a[:, 1].sum() >= 400                                 # real episodes
  assert a.shape[1] == machine.ROW_COUNTERS + 3 * len(graph.nodes)
  assert calls[0] == calls[1]                      # on_call: the same calls, in order
  np.testing.assert_array_equal(states[0], states[2])
  np.testing.assert_array_equal(states[1], states[2])
  want = _oracle_parameters(o, graph)
  for got in (_parameters(fused, graph), _parameters(stepwise, graph)):
    for name, value in want.items():
      np.testing.assert_array_equal(got[name], value, err_msg=name)
  assert any(np.any(v != 0.0) for v in want.values())          # something was learned


def test_random_graphs_cover_every_shape_and_a_subtask_run():
  graphs = [random_graph(s) for s in range(12)]
  shapes = {(len([n for n in g.subtasks() if isinstance(n.learner, blocks.QTable)]),
             any(isinstance(n.learner, blocks.TiledQTable) for n in g.subtasks()))
            for g in graphs}
  assert shapes == {(0, False), (1, False), (2, False), (0, True)}   # flat, 2, 3 levels, route
  used = {type(part).__name__ for g in graphs for n in g.subtasks()
          for part in (n.view, n.termination, n.internal_reward, n.available)}
  assert {"CellRule", "EndRule", "RewardRule", "Shaping", "GridCell", "LocalGoal", "AimTiles",
          "TargetReached", "NearGateLine", "StateTiles"} <= used
  assert any(getattr(n.learner, "width_alpha", 0.0) for g in graphs for n in g.subtasks())


def _coder():
  return tiles.TileCoder((0.0, 0.0, -180.0, -15.0), (150.0, 150.0, 180.0, 15.0), (3, 3, 8, 3),
                         (False, False, True, False), 2)


def _leg(learner=None, children=("turn",), view=None, **kw):
  coder = _coder()
  learner = learner or blocks.GaussianCMAC(coder)
  return Subtask("leg", children=list(children), learner=learner,
                 view=view or blocks.LocalTiles(learner.coder if hasattr(learner, "coder")
                                                else coder),
                 termination=kw.get("termination", blocks.LocalGoal(50)))


def _root(children=None, **kw):
  return Subtask("root", children=children or [Child("leg", direction=0)],
                 learner=kw.get("learner", blocks.QTable(400)),
                 view=kw.get("view", blocks.GridCell()), termination=blocks.Never())


@pytest.mark.parametrize("nodes, schedule, message", [
    (lambda: [_root(), _leg(learner=stepwise.SoftmaxPolicyGradient(1, 1, 0.1)),
              Primitive("turn")], None,
     "subtask 'leg': learner .* is not a machine learner; allowed: QTable, TiledQTable, RLearning, "
     "GibbsTable, GaussianCMAC"),
    (lambda: [_root(), _leg(learner=object()), Primitive("turn")], None,
     "subtask 'leg': its learner object has no start, act, observe"),
    (lambda: [_root(view=blocks.LocalTiles(_coder())), _leg(), Primitive("turn")], None,
     "subtask 'root': a QTable needs a GridCell, CellRule or TaxiState view"),
    (lambda: [_root(), _leg(children=("turn", "turn2")), Primitive("turn"), Primitive("turn2")],
     None, "subtask 'leg': a GaussianCMAC's one child is a continuous primitive"),
    (lambda: [_root(), _leg(view=blocks.GridCell()), Primitive("turn")], None,
     "subtask 'leg': a GaussianCMAC needs a LocalTiles, StateTiles or AimTiles view over its "
     "own coder"),
    (lambda: [_root(learner=blocks.TiledQTable(_coder())), _leg(), Primitive("turn")], None,
     "subtask 'root': a TiledQTable needs a StateTiles view over its own coder"),
    (lambda: [Subtask("root", children=[Child("leg", direction=0)], learner=blocks.QTable(400),
                      view=blocks.GridCell(), termination=blocks.Never(),
                      available=blocks.NearGateLine(100.0)), _leg(), Primitive("turn")], None,
     "subtask 'root': only a TiledQTable offers its children by NearGateLine; its learner is "
     "a QTable"),
    (lambda: [_root(), _leg(termination=blocks.TargetReached()), Primitive("turn")], None,
     "subtask 'leg': a TargetReached ends a node with an AimTiles view \\(its targets\\); its "
     "view is a LocalTiles"),
    (lambda: [_root(children=[Child("leg", heading=3)]), _leg(), Primitive("turn")], None,
     "subtask 'root': its child 'leg' takes \\['heading'\\]; the machine passes one integer "
     "argument, one of \\['direction', 'target'\\]"),
    (lambda: [_root(), _leg(termination=object()), Primitive("turn")], None,
     "subtask 'leg': termination .* is not a machine termination; allowed: Never, Clock, "
     "LocalGoal"),
    (lambda: [_root(), _leg(termination=blocks.Clock(100)), Primitive("turn")], None,
     "subtask 'leg': a Clock ends only the root \\(a continuing task's record row\\); the "
     "root is 'root'"),
    (lambda: [_root(learner=blocks.RLearning(7)), _leg(), Primitive("turn")], None,
     "subtask 'root': its GridCell view has 400 states, its RLearning 7"),
    (lambda: [_root(view=blocks.CellRule(lambda obs, origin, arg, steps: 0)), _leg(),
              Primitive("turn")], None,
     "subtask 'root': its CellRule's rule must be an @numba.njit function; got <function"),
    (lambda: [_root(), _leg(termination=blocks.EndRule(_steady)), Primitive("turn")], None,
     r"subtask 'leg': its EndRule's rule _steady cannot be compiled for \(obs, origin, arg, "
     r"steps\) = \(float64 array, float64 array, int, int\): "),
    (lambda: [_root(), _leg(termination=blocks.EndRule(_pair)), Primitive("turn")], None,
     r"subtask 'leg': its EndRule's rule _pair returns Tuple\(.*\); a rule returns "
     "one number"),
    (lambda: [_root(), _leg(), Primitive("turn")], blocks.HeldEpsilon(watch=("nowhere",)),
     "the epsilon schedule watches 'nowhere', which is not a subtask of the graph"),
])
def test_what_the_machine_refuses_is_named(nodes, schedule, message):
  with pytest.raises(GraphError, match=message):
    machine.Machine(TaskGraph("root", nodes(), schedule=schedule))


@pytest.mark.parametrize("leg, block", [
    (lambda: _leg(), "LocalTiles"),
    (lambda: _leg(view=blocks.StateTiles(_coder())), "LocalGoal"),
])
def test_a_taxi_machine_refuses_the_ships_local_frame(leg, block):
  # A machine with a taxi world compiles without the ship's local frame (its code is
  # pruned there), so a graph that needs it is refused when it is built.
  from hpg_mj.worlds import taxi_rules
  with pytest.raises(GraphError, match=f"subtask 'leg': {block} is a block of the ship's local "
                     "frame; a machine with a taxi world"):
    machine.Machine(TaskGraph("root", [_root(), leg(), Primitive("turn")]),
                    world=taxi_rules.world_config())


def test_only_a_graph_with_extra_blocks_compiles_their_code():
  # `extras` is None (their code pruned, a shorter first compile) unless the graph has
  # an actor-critic, a user rule, or the route's or the patrol's blocks.
  plain = [_root(), _leg(), Primitive("turn")]
  assert machine.Machine(TaskGraph("root", plain)).banks.extras is None
  for root in (_root(learner=blocks.RLearning(400)),
               _root(learner=blocks.RLearning(400), view=blocks.PatrolCell())):
    graph = TaskGraph("root", [root, _leg(), Primitive("turn")])
    assert machine.Machine(graph).banks.extras == 1
  ruled = _leg()
  ruled.internal_reward = blocks.RewardRule(_steady)
  assert machine.Machine(TaskGraph("root", [_root(), ruled, Primitive("turn")])).banks.extras == 1


@numba.njit
def _pair(obs, origin, arg, steps):
  return 0, 1


@numba.njit
def _far(obs, origin, arg, steps):
  return 400


@numba.njit
def _two(obs, origin, arg, steps):
  return 2


@pytest.mark.parametrize("root, leg, message", [
    (dict(view=blocks.CellRule(_far)), {},
     "a CellRule's rule gave a state outside its QTable's states"),
    ({}, dict(termination=blocks.EndRule(_two)),
     "an EndRule's rule gave an event other than 0, 1 or -1"),
])
def test_a_rule_that_breaks_its_contract_stops_the_run(root, leg, message):
  m = machine.Machine(TaskGraph("root", [_root(**root), _leg(**leg), Primitive("turn")]))
  with pytest.raises((IndexError, ValueError), match=message):
    m.run(1, True, True, rng.make_state(0), (100.0, -300.0, 100))


def test_a_shared_qtable_needs_one_number_of_children():
  shared = blocks.QTable(400)
  nodes = [_root(children=[Child("mid", direction=0), Child("other", direction=2)],
                 learner=blocks.QTable(400)),
           Subtask("mid", children=[Child("leg", direction=0)], learner=shared,
                   view=blocks.GridCell(), termination=blocks.LocalGoal(100)),
           Subtask("other", children=[Child("leg", direction=0), Child("leg", direction=2)],
                   learner=shared, view=blocks.GridCell(), termination=blocks.LocalGoal(100)),
           _leg(), Primitive("turn")]
  with pytest.raises(GraphError, match="subtask '(mid|other)': its QTable is shared with a "
                                       "node of [12] children, it has [12]"):
    machine.Machine(TaskGraph("root", nodes))


def test_the_machine_compiles_its_functions_once_leaves_first(tmp_path):
  """The functions `Machine._bottom_up` compiles before the fused loop are those the
  loop calls, for the types it calls them with: each compiles once."""
  compile_order.assert_each_compiles_once(tmp_path, """
from hpg_mj import agents
agent = agents.build(agents.load_task("ship_patrol_average_reward"), 0)
agent.train(2)
listed = agent.machine._bottom_up()
""")
