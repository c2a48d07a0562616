"""The step-by-step learners (the Python executor's) refuse what a view gives wrongly,
before it reaches their arrays: a state past the table (which had killed Python with
a segmentation fault through the executor), a float where a state is due, tiles of
the wrong number; the executor's message names the subtask, in one line."""
import gymnasium
import numpy as np
import pytest

import hpg_mj  # noqa: F401  (registers the Gymnasium ids)
from hpg_mj.hierarchy import executor
from hpg_mj.hierarchy.graph import Primitive, Subtask, TaskGraph
from hpg_mj.learners import rng, stepwise


@pytest.mark.parametrize("features, said", [
    (100000, "the view gave state 100000; expected an integer state in [0, 400)"),
    (-1, "the view gave state -1; expected an integer state in [0, 400)"),
    (3.0, "the view gave 3.0 (float); expected an integer state in [0, 400)"),
    (np.float64(7.5), "the view gave np.float64(7.5) (float64); expected an integer state"),
    (True, "the view gave True (bool); expected an integer state"),
])
def test_a_table_refuses_a_state_it_does_not_have(features, said):
  q = stepwise.QLambda(400, 3, 0.1, 0.9)
  with pytest.raises(ValueError, match="^QLambda: " + said.replace("(", r"\(").replace(
      ")", r"\)").replace("[", r"\[")):
    q.act(features, None, rng.make_state(0), True)
  assert stepwise.QLambda(400, 3, 0.1, 0.9).act(np.int64(399), None, rng.make_state(0), True) in (0, 1, 2)


def test_a_cmac_policy_refuses_tiles_of_the_wrong_number_or_kind():
  g = stepwise.GaussianPolicyGradient(100, 9, 15.0, 0.01)
  for features, said in ((np.array([1, 2]), "the view gave 2 value(s) of int64 with shape (2,); "
                                            "expected 9"),
                         (np.zeros(9), "the view gave 9 value(s) of float64"),
                         (np.full(9, 100), "the view gave tile 100; expected tile indices in "
                                           "[0, 100)")):
    with pytest.raises(ValueError, match=r"^GaussianPolicyGradient: " + said.replace(
        "(", r"\(").replace(")", r"\)").replace("[", r"\[")):
      g.act(features, None, rng.make_state(0), True)


def test_the_executor_names_the_subtask_where_it_had_crashed():
  """The issue's case: a root view giving states 100-499 to a 400-state table."""
  graph = TaskGraph("root", [Primitive("left", -15.0), Primitive("right", 15.0), Subtask(
      "root", children=["left", "right"], termination=lambda call, step: False,
      view=lambda call, obs: 100 + int(obs[0] * 0.4) % 400,
      learner=stepwise.QLambda(400, 2, 0.1, 0.9))])
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic", max_steps=200)
  run = executor.Executor(graph, executor.adapter_for(env), rng.make_state(0))
  with pytest.raises(ValueError) as e:
    for _ in range(20):
      run.run_episode(np.array([900.0, 100.0, 0.0, 0.0]), learn=True)
  assert str(e.value).startswith("subtask 'root': QLambda: the view gave state 4")
  assert str(e.value).endswith("expected an integer state in [0, 400)")
  assert "\n" not in str(e.value)
