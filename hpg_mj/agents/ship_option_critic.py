"""Option-critic on the ship (Bacon, Harb and Precup, 2017;
`hierarchy.kinds.option_critic_cmac`): a learned hierarchy beside the designed one
(the hybrid) and the flat learners (flat PGRL, the actor-critic), on the same task,
CMAC and machine. A root over `n_options` options, each a Gaussian-with-sigmoid
policy over the turning rate with a learned termination, all over the tiles of the
whole state (x, y, theta, theta_dot: flat PGRL's coder); the root is epsilon-greedy
over the options' values Q_Omega, learned inside them by intra-option TD. Nothing of
the task's structure (the gate's approach, the subtasks' local frame) is given: the
options find their own.
"""
import dataclasses

from hpg_mj import taskfile
from hpg_mj.agents import _ship
from hpg_mj.agents import hierarchy
from hpg_mj.agents import ship_flat_pg
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import Primitive, Subtask, TaskGraph
from hpg_mj.hierarchy.kinds import option_critic_cmac as oc_kinds
from hpg_mj.taskfile import param
from hpg_mj.worlds import ship_core as core


@dataclasses.dataclass(frozen=True)
class Options(taskfile.Section):
  """[options]: the option-critic's options, step sizes and CMAC."""
  learner: str = param("option_critic", "Bacon et al.'s option-critic over a CMAC",
                       choices=("option_critic",))
  n_options: int = param(4, "options the root chooses among", low=1, high=64)
  alpha_critic: float = param(0.3, "step size of Q_Omega", low=0, high=1, low_open=True)
  alpha_policy: float = param(0.03, "step size of the intra-option policies", low=0,
                              low_open=True)
  alpha_termination: float = param(0.01, "step size of the terminations", low=0)
  gamma: float = param(0.99, "discount", low=0, high=1, low_open=True)
  epsilon: float = param(0.05, "the root's exploration among the options", low=0, high=1)
  xi: float = param(0.01, "the termination's margin (favours longer options)")
  sigma: float = param(1.0, "the intra-option Gaussian's width (before the sigmoid)", low=0,
                       low_open=True)
  initial: float = param(0.0, "Q_Omega before learning")
  tilings: int = param(9, "CMAC tilings", low=1)
  tiles: tuple = param((20, 20, 36, 5), "tiles per tiling over x, y, theta, theta_dot",
                       length=4, low=1)


@dataclasses.dataclass(frozen=True)
class Config:
  """The task file's schema: its sections [environment] and [options]."""
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)
  options: Options = dataclasses.field(default_factory=Options)


def learner(o):
  """(the CMAC, the `OptionCriticCMAC` holding every option's arrays) of an [options]
  section `o`: flat PGRL's coder over the ship's whole state."""
  coder = ship_flat_pg.actor_coder(o.tilings, o.tiles)
  return coder, oc_kinds.OptionCriticCMAC(
      coder, int(o.n_options), core.MAX_TURN_RATE, o.alpha_critic, o.alpha_policy,
      o.alpha_termination, o.gamma, o.epsilon, o.xi, o.sigma, float(o.initial))


class ShipOptionCritic(hierarchy.ShipHierarchy):
  """Option-critic: a root over learned options; its state by the root's name
  (`root.q_omega`, `root.theta`, `root.vartheta`)."""

  name = "ship_option_critic"
  Config = Config
  tags = ("learned_hierarchy",)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    self.coder, self.oc = learner(self.config.options)

  def graph(self):
    """root -> option0 ... option{k-1} -> the turning rate; every node sees the
    tiles of the whole state."""
    return graph(self.oc, lambda: blocks.StateTiles(self.coder))

  def metrics(self, record):
    """The task's metrics, with the options called per episode over the last
    `metric_window` episodes."""
    return {**super().metrics(record), **option_metrics(record[-self.metric_window:])}


def graph(oc, view):
  """The option-critic's graph over `oc`: root -> option0 ... option{k-1} -> the
  turning rate, every node seeing `view()` (a view block of the features `oc.coder`
  tiles, made afresh for each node; the options' terminations tile the same)."""
  options = [f"option{w}" for w in range(oc.n_options)]
  return TaskGraph("root", [
      Subtask("root", children=options, learner=oc_kinds.OverOptionsCMAC(oc),
              view=view(), termination=blocks.Never()),
      *(Subtask(name, children=["turn"], learner=oc_kinds.IntraOptionCMAC(oc, w),
                view=view(), termination=oc_kinds.LearnedTerminationCMAC(oc, w))
        for w, name in enumerate(options)),
      Primitive("turn"),
  ])


def option_metrics(w):
  """The options called per episode over the record rows `w` (its field calls)."""
  return {"calls_per_episode": float(w["calls"].mean()) if len(w) else None}
