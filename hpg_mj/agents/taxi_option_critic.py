"""Option-critic on taxi-fuel (Bacon, Harb and Precup, 2017; `hierarchy.kinds.option_critic`):
a learned hierarchy beside the designed one (taxi HPG, MAXQ-Q) and the flat learner,
on the same task and the same machine. A root over `n_options` options, each a
softmax policy over the primitives with a learned termination, all over the taxi's
full state (6,500 states with fuel); the root is epsilon-greedy over the options'
values Q_Omega, learned inside them by intra-option Q-learning. Nothing of the task's
structure (Get, Put, Refuel, Navigate) is given: the options find their own.
"""
import dataclasses

from hpg_mj import taskfile
from hpg_mj.agents import _taxi
from hpg_mj.agents import hierarchy
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import Primitive, Subtask, TaskGraph
from hpg_mj.hierarchy.kinds import option_critic as oc_kinds
from hpg_mj.taskfile import param
from hpg_mj.worlds import taxi_core as core


@dataclasses.dataclass(frozen=True)
class Options(taskfile.Section):
  """[options]: the option-critic's options and step sizes."""
  learner: str = param("option_critic", "Bacon et al.'s option-critic, tabular",
                       choices=("option_critic",))
  n_options: int = param(4, "options the root chooses among", low=1, high=64)
  alpha_critic: float = param(0.5, "step size of Q_Omega and Q_U", low=0, high=1, low_open=True)
  alpha_policy: float = param(0.25, "step size of the intra-option policies", low=0,
                              low_open=True)
  alpha_termination: float = param(0.25, "step size of the terminations", low=0)
  gamma: float = param(0.99, "discount", low=0, high=1, low_open=True)
  epsilon: float = param(0.01, "the root's exploration among the options", low=0, high=1)
  xi: float = param(0.01, "the termination's margin (favours longer options)")
  temperature: float = param(1.0, "the intra-option softmax's temperature", low=0,
                             low_open=True)
  baseline: bool = param(True, "subtract Q_Omega(s, w) from Q_U(s, w, a) in the policy gradient")
  initial: float = param(0.0, "Q_Omega and Q_U before learning (optimistic: explores)")


@dataclasses.dataclass(frozen=True)
class Config:
  """The task file's schema: its sections [environment] and [options]."""
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)
  options: Options = dataclasses.field(default_factory=Options)


class TaxiOptionCritic(hierarchy.TaxiHierarchy):
  """Option-critic: a root over learned options; its state by the root's name
  (`root.q_omega`, `root.q_u`, `root.theta`, `root.vartheta`)."""

  name = "taxi_option_critic"
  Config = Config
  record_fields = ("return", "steps", "outcome", "calls")
  tags = ("learned_hierarchy",)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    o = self.config.options
    self.n_actions = core.num_actions(self.rules.fuel_enabled)
    self.oc = oc_kinds.OptionCritic(
        core.num_states(self.rules.fuel_enabled, self.rules.capacity), int(o.n_options),
        self.n_actions, o.alpha_critic, o.alpha_policy, o.alpha_termination, o.gamma,
        o.epsilon, o.xi, o.temperature, bool(o.baseline), float(o.initial))

  def graph(self):
    """root -> option0 ... option{k-1} -> the primitives; every node sees the full state."""
    names = core.ACTION_NAMES[:self.n_actions]
    options = [f"option{w}" for w in range(self.oc.n_options)]
    return TaskGraph("root", [
        Subtask("root", children=options, learner=oc_kinds.OverOptions(self.oc),
                view=blocks.TaxiState(), termination=blocks.Never()),
        *(Subtask(name, children=list(names), learner=oc_kinds.IntraOption(self.oc, w),
                  view=blocks.TaxiState(), termination=oc_kinds.LearnedTermination(self.oc, w))
          for w, name in enumerate(options)),
        *(Primitive(name, action=i) for i, name in enumerate(names)),
    ])

  def metrics(self, record):
    """The task's metrics, with the options called per episode over the last
    `metric_window` episodes."""
    out = super().metrics(record)
    w = record[-self.metric_window:]
    out["calls_per_episode"] = float(w["calls"].mean()) if len(w) else None
    return out
