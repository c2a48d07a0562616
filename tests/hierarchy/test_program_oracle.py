"""The open machine (`hierarchy.program`) against the pure-Python oracle
(`tests/oracle.py`: the executor with the step-by-step learners) on random graphs of
blocks, flat, of two and three levels and the route's shape, with a user's rules,
learned widths, shaping weights and offered children: fused, step by step and in the
oracle, every record, every call told and every learned parameter is the same bit
for bit."""
import numba
import numpy as np
import pytest

import hpg_mj  # noqa: F401
import gymnasium
from hpg_mj.hierarchy import algorithm, blocks, ship_rules
from hpg_mj.hierarchy.graph import Child, Primitive, Subtask, TaskGraph
from hpg_mj.hierarchy.kinds.rules import Abstraction, InternalReward, Termination
from hpg_mj.hierarchy.program import Program
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import rng, tiles
import oracle


# A user's rules (`Abstraction`, `Termination`, `InternalReward`), as a user writes them.
@numba.njit
def _boxed(obs, call):
  """A region's end: 200 m from where it began (failure), or 120 steps (success)."""
  dx, dy = obs[0] - call.origin[0], obs[1] - call.origin[1]
  if dx * dx + dy * dy > 200.0 ** 2:
    return -1
  return 1 if call.steps >= 120 else 0


@numba.njit
def _steady(obs, call, event):
  """G: turning costs, a success pays."""
  return -0.01 * abs(obs[3]) + 5.0 * event


@numba.njit
def _quadrant(obs, call):
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
                        internal_reward=(blocks.Shaping(), None, InternalReward(_steady))[
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
                    view=Abstraction(_quadrant) if ruled else blocks.GridCell(50.0, 20),
                    termination=(Termination(_boxed) if ruled else
                                 blocks.LocalGoal(int(g.integers(50, 400)))))]
    root_children = [Child("region", direction=int(d))
                     for d in g.choice(8, size=int(g.integers(1, 5)), replace=False)]
    grid = 4
  root = Subtask("root", children=root_children, learner=q_table(grid * grid),
                 view=blocks.GridCell(1000.0 / grid, grid), termination=blocks.Never())
  used = sorted({r.node for r in root_children} | {c.node for m in mids for c in m.children})
  watch = tuple(used[:int(g.integers(0, len(used) + 1))])
  legs = [leg for leg in legs if leg.name in used]          # (a leg no node calls: refused)
  return TaskGraph("root", [root, *mids, *legs, Primitive("turn")],
                   schedule=blocks.HeldEpsilon(float(g.uniform(0.1, 0.5)), watch, 0.5, 3, 2, 1.5))


def _parameters(m, graph):
  got = m.parameters()
  out = {}
  for node in graph.subtasks():
    if isinstance(node.learner, (blocks.QTable, blocks.TiledQTable)):
      out[node.name] = got[f"{node.name}.q"]
    else:
      out[node.name] = np.concatenate([got[f"{node.name}.{k}"] for k in (
          "theta", "values", "log_sigma") if f"{node.name}.{k}" in got])
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


# Six graphs: they hold every shape and block the coverage test below asks for; each
# graph is a compile of its own (10-40 s of the suite), so not more.
N_GRAPHS = 6


@pytest.mark.parametrize("seed", range(N_GRAPHS))
def test_random_graphs_give_the_oracles_numbers_on_every_path(seed):
  graph = random_graph(seed)
  max_steps = 150 + 25 * seed
  world = (100.0, -300.0, max_steps)
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic", max_steps=max_steps,
                       gate_reward=100.0, out_of_bounds_reward=-300.0)
  fused, stepwise = Program(graph), Program(graph)
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
    b = stepwise.run_stepwise(env, episodes, learn, sample, states[1], start(states[1]),
                              lambda last: last.info.get("event") == "gate", on_call=told(0))
    c = o.run(env, episodes, learn, sample, start(states[2]), on_call=told(1))
    np.testing.assert_array_equal(a, c, err_msg=f"fused vs oracle, learn={learn}")
    np.testing.assert_array_equal(b, c, err_msg=f"stepwise vs oracle, learn={learn}")
    if learn:
      assert a[:, 1].sum() >= 400                                 # real episodes
  assert a.shape[1] == algorithm.ROW_COUNTERS + 3 * len(graph.nodes)
  assert calls[0] == calls[1]                      # on_call: the same calls, in order
  np.testing.assert_array_equal(states[0], states[2])
  np.testing.assert_array_equal(states[1], states[2])
  want = _oracle_parameters(o, graph)
  for got in (_parameters(fused, graph), _parameters(stepwise, graph)):
    for name, value in want.items():
      np.testing.assert_array_equal(got[name], value, err_msg=name)
  assert any(np.any(v != 0.0) for v in want.values())          # something was learned


def test_random_graphs_cover_every_shape_and_a_subtask_run():
  graphs = [random_graph(s) for s in range(N_GRAPHS)]
  shapes = {(len([n for n in g.subtasks() if isinstance(n.learner, blocks.QTable)]),
             any(isinstance(n.learner, blocks.TiledQTable) for n in g.subtasks()))
            for g in graphs}
  assert shapes == {(0, False), (1, False), (2, False), (0, True)}   # flat, 2, 3 levels, route
  used = {type(part).__name__ for g in graphs for n in g.subtasks()
          for part in (n.view, n.termination, n.internal_reward, n.available)}
  assert {"Abstraction", "Termination", "InternalReward", "Shaping", "GridCell", "LocalGoal", "AimTiles",
          "TargetReached", "NearGateLine", "StateTiles"} <= used
  assert any(getattr(n.learner, "width_alpha", 0.0) for g in graphs for n in g.subtasks())
