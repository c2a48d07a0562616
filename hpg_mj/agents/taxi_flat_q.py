"""Flat Q-learning on taxi-fuel over the full state (SPEC section 5): a baseline
of HPG (tag "baseline"). One-step Watkins Q-learning, epsilon-greedy with a
linear decay: a one-node graph of blocks (a `QTable` over the whole state's
index, `TaxiCell("full")`, with a `LinearEpsilon`) that the compiled machine runs
fused with the taxi or step by step."""

import dataclasses

from hpg_mj.agents import _taxi
from hpg_mj.agents import taskfile
from hpg_mj.agents.taskfile import param
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import Primitive, Subtask, TaskGraph
from hpg_mj.worlds import taxi_core as core

@dataclasses.dataclass(frozen=True)
class Policy(taskfile.Section):
  """[policy]: Q-learning over the full state."""
  learner: str = param("q_learning", "one-step Watkins Q-learning", choices=("q_learning",))
  alpha: float = param(1.0, "step size", low=0, high=1, low_open=True)
  epsilon_start: float = param(0.1, "exploration at first", low=0, high=1)
  epsilon_end: float = param(0.0, "exploration after the decay", low=0, high=1)
  epsilon_episodes: int = param(50_000, "episodes of the linear decay", low=0)
  initial: float = param(20.0, "Q before learning")


@dataclasses.dataclass(frozen=True)
class Config:
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)
  policy: Policy = dataclasses.field(default_factory=Policy)


class TaxiFlatQ(_taxi.TaxiMachineAgent):
  """Flat Q-learning's table, trained by the compiled machine fused or step by step."""

  name = "taxi_flat_q"
  Config = Config
  record_fields = ("return", "steps", "outcome")
  tags = ("baseline",)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    pol = self.config.policy
    self.n_actions = core.num_actions(self.rules.fuel_enabled)
    self.q = blocks.QTable(core.num_states(self.rules.fuel_enabled, self.rules.capacity),
                           alpha=pol.alpha, trace_decay=0.0, epsilon=0.0,
                           epsilon_schedule=True, trace_capacity=16, initial=pol.initial)
    self.schedule = blocks.LinearEpsilon(pol.epsilon_start, pol.epsilon_end,
                                         pol.epsilon_episodes)

  def graph(self):
    actions = core.ACTION_NAMES[:self.n_actions]
    return TaskGraph("q", [
        Subtask("q", children=list(actions), learner=self.q, view=blocks.TaxiCell("full"),
                termination=blocks.Never()),
        *(Primitive(name, action=a) for a, name in enumerate(actions))],
        schedule=self.schedule)

  def state(self):
    q, index, value, count = self.machine.q_arrays(self.q)
    return {"rng_state": self.rng_state, "q": q, "trace_index": index, "trace_value": value,
            "trace_count": count}
