"""The trivial hierarchy of a flat learner: one subtask over the primitives, which
ends with the episode. Flat agents run step by step on it, by the same executor as
the hierarchies."""
from hpg_mj.hierarchy.graph import Primitive, Subtask, TaskGraph


def flat_graph(learner, view, primitives, continuous=False):
  """One node, "policy", choosing among `primitives` (names; with `continuous`, one
  primitive whose value the learner gives); `primitives[i]` sends action i."""
  nodes = ([Primitive(primitives[0])] if continuous else
           [Primitive(name, action=i) for i, name in enumerate(primitives)])
  return TaskGraph("policy", [
      Subtask("policy", children=list(primitives), learner=learner, view=view,
              termination=lambda call, step: False),     # flat: ends with the episode
      *nodes,
  ])
