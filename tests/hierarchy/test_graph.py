"""The task-graph API: validation, and a new hierarchy built in a few lines."""
import gymnasium
import numpy as np
import pytest

import hpg_mj  # noqa: F401
from hpg_mj.hierarchy import executor
from hpg_mj.agents.ship_hybrid import ShipHybrid
from hpg_mj.hierarchy.graph import Child, GraphError, Primitive, Subtask, TaskGraph
from hpg_mj.learners import rng, stepwise, tiles
from hpg_mj.worlds import ship_core as core


def _subtask(name, children, **kw):
  args = dict(termination=lambda call, step: True, view=lambda call, obs: 0,
              learner=stepwise.SoftmaxPolicyGradient(1, max(1, len(children)), 0.1))
  args.update(kw)
  return Subtask(name, children=children, **args)


def test_cycle_is_refused_naming_the_nodes():
  with pytest.raises(GraphError, match="cycle through a -> b -> a"):
    TaskGraph("root", [_subtask("root", ["a"]), _subtask("a", ["b"]), _subtask("b", ["a", "go"]),
                       Primitive("go", 0)])


def test_unknown_child_is_refused_naming_the_node():
  with pytest.raises(GraphError, match="subtask 'root' names an unknown child 'nowhere'"):
    TaskGraph("root", [_subtask("root", ["go", Child("nowhere", k=1)]), Primitive("go", 0)])


def test_missing_termination_is_refused_naming_the_node():
  with pytest.raises(GraphError, match="subtask 'leaf' has no termination"):
    TaskGraph("root", [_subtask("root", ["leaf"]), _subtask("leaf", ["go"], termination=None),
                       Primitive("go", 0)])


def test_other_malformed_graphs():
  with pytest.raises(GraphError, match="root 'top' is not a node"):
    TaskGraph("top", [_subtask("root", ["go"]), Primitive("go", 0)])
  with pytest.raises(GraphError, match="defined twice"):
    TaskGraph("root", [_subtask("root", ["go"]), Primitive("go", 0), Primitive("go", 1)])
  with pytest.raises(GraphError, match="has no children"):
    TaskGraph("root", [_subtask("root", [])])


def test_a_new_hierarchy_over_the_ship():
  """A third hierarchy: a policy-gradient root over four straight legs (N, E, S, W)
  only, on a coarser 10 x 10 grid, reusing the straight subtask's rules."""
  coder = tiles.TileCoder((0.0, 0.0, -180.0, -15.0), (150.0, 150.0, 180.0, 15.0),
                          (5, 5, 36, 5), (False, False, True, False), 9)
  leg_learner = stepwise.GaussianPolicyGradient(coder.size, 9, 15.0, alpha=0.01, gamma=0.99)
  root_learner = stepwise.SoftmaxPolicyGradient(100, 4, alpha=0.05)
  arrays, local, active = coder.arrays(), np.empty(4), np.empty(9, dtype=np.int64)
  local_samples = np.empty((4, 2))
  calls = []

  def leg_view(call, obs):
    origin = call.memo.setdefault("origin", np.array(call.origin[:2]))
    core.global_to_local(obs, origin, call.args["direction"], local)
    tiles.active_tiles(local, arrays, active)
    return active

  def leg_reward(call, step):
    event, internal = core.low_level_outcome(
        step.info["positions"], step.obs, call.memo["origin"], call.args["direction"],
        call.steps, local_samples, local, 300)
    call.memo["event"] = event
    return internal

  graph = TaskGraph("root", [
      Subtask("root", children=[Child("leg", direction=d) for d in (0, 2, 4, 6)],
              view=lambda call, obs: int(obs[0] // 100) * 10 + int(obs[1] // 100) if
              0 <= obs[0] < 1000 and 0 <= obs[1] < 1000 else 0,
              termination=lambda call, step: False, learner=root_learner),
      Subtask("leg", children=["turn"], view=leg_view, internal_reward=leg_reward,
              reward=lambda call, step, r: -1.0, learner=leg_learner,
              termination=lambda call, step: call.memo["event"] != core.NO_EVENT,
              on_exit=lambda call, step, over: calls.append(call.args["direction"])),
      Primitive("turn"),
  ])
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic", max_steps=400)
  run = executor.Executor(graph, executor.GymAdapter(env), rng.make_state(0))
  before = root_learner.parameters().copy()
  for _ in range(3):
    total, steps, last = run.run_episode()
    assert last.terminated or last.truncated
    assert 1 <= steps <= 400
  assert calls and set(calls) <= {0, 2, 4, 6}
  assert not np.array_equal(before, root_learner.parameters())


def test_paper_ship_graph_shape():
  graph = ShipHybrid().graph()
  refs = graph.children("root")
  assert [r.node for r in refs] == ["straight", "diagonal"] * 4
  assert [r.args["direction"] for r in refs] == list(range(8))
  assert graph.nodes["diagonal"].learner is not graph.nodes["straight"].learner


def test_a_learner_missing_a_method_is_refused_when_the_graph_is_built():
  class NoObserve:
    def start(self):
      pass

    def act(self, features, mask, rng_state, sample):
      return 0
  with pytest.raises(GraphError, match=r"subtask 'root': its learner NoObserve has no observe; "
                                       r"a learner answers start\(\)"):
    TaskGraph("root", [_subtask("root", ["go"], learner=NoObserve()), Primitive("go", 0)])


def test_a_learner_of_the_wrong_action_size_is_refused_naming_the_node():
  with pytest.raises(GraphError, match="subtask 'root': its learner SoftmaxPolicyGradient "
                                       "chooses among 3 actions, the node has 2 children"):
    TaskGraph("root", [_subtask("root", ["go", "stop"],
                                learner=stepwise.SoftmaxPolicyGradient(1, 3, 0.1)),
                       Primitive("go", 0), Primitive("stop", 1)])
