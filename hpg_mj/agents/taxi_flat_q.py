"""Flat Q-learning on taxi-fuel over the full state (SPEC section 5): a baseline
of HPG (tag "baseline"). One-step Watkins Q-learning (Q(0), undiscounted),
epsilon-greedy with a linear decay over the learning episodes. The agent is its
Config and a one-node graph of blocks, which the open machine (`hierarchy.program`)
runs on both paths (fused with the taxi's rules; step by step through any taxi
environment)."""

import dataclasses

from hpg_mj.agents import _taxi
from hpg_mj.agents import hierarchy
from hpg_mj import taskfile
from hpg_mj.taskfile import param
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
  """The task file's schema: its sections [environment] and [policy]."""
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)
  policy: Policy = dataclasses.field(default_factory=Policy)


class TaxiFlatQ(hierarchy.TaxiHierarchy):
  """Flat Q-learning: a one-node graph whose QTable sees the whole state; its state
  by node name (`policy.q`, `policy.trace_index`, ...)."""

  name = "taxi_flat_q"
  Config = Config
  record_fields = ("return", "steps", "outcome")
  tags = ("baseline",)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    pol = self.config.policy
    self.n_actions = core.num_actions(self.rules.fuel_enabled)
    self.learner = blocks.QTable(core.num_states(self.rules.fuel_enabled, self.rules.capacity),
                                 pol.alpha, trace_decay=0.0, gamma=1.0, epsilon_schedule=True,
                                 trace_capacity=16)
    self.machine.state()["policy.q"][:] = pol.initial

  def graph(self):
    """One node over the primitives, ending with the episode; epsilon decays linearly."""
    pol = self.config.policy
    names = core.ACTION_NAMES[:self.n_actions]
    return TaskGraph("policy", [
        Subtask("policy", children=list(names), learner=self.learner,
                view=blocks.TaxiState(), termination=blocks.Never()),
        *(Primitive(name, action=i) for i, name in enumerate(names)),
    ], schedule=blocks.LinearEpsilon(pol.epsilon_start, pol.epsilon_end, pol.epsilon_episodes))
