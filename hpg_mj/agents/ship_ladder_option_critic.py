"""Option-critic (Bacon, Harb and Precup, 2017; `ship_option_critic`) carried to the task
ladder (SPEC section 11): a learned hierarchy beside the designed one
(`ship_ladder_hybrid`) and flat PGRL (`ship_ladder_flat_pg`), on the task and level its
task file's [environment] names, with `ship_option_critic`'s [options] and defaults. A
root epsilon-greedy over `n_options` options, each a Gaussian-with-sigmoid policy over
the turning rate with a learned termination, all over a CMAC of the ship's whole state
(9 tilings x 20 x 20 x 36 x 5 tiles over x, y, theta, theta_dot), acting every 0.6 s.

What its CMAC tiles is flat PGRL's on the ladder (`_ladder.tiles_view`): on the current
and the harbour the ship's own state; on the goal and the regatta the ship's state in
the frame of the episode's (the next) gate (`blocks.GateTiles`), which puts that gate
where the steering task's stands. Every node reads it, the options' learned
terminations too (`kinds.option_critic_cmac`). Nothing else of the task's structure is
given: the options find their own.
"""
import dataclasses

from hpg_mj.agents import _ladder
from hpg_mj.agents import hierarchy
from hpg_mj.agents import ship_option_critic


@dataclasses.dataclass(frozen=True)
class Config:
  """The task file's schema: [environment] (the ladder's task and level) and the
  option-critic's [options]."""
  environment: _ladder.LadderEnvironment = dataclasses.field(
      default_factory=_ladder.LadderEnvironment)
  options: ship_option_critic.Options = dataclasses.field(
      default_factory=ship_option_critic.Options)


class ShipLadderOptionCritic(hierarchy.ShipLadderHierarchy):
  """Option-critic on a ladder task (see the module docstring): a root over learned
  options, run by the open machine fused with the task's world and step by step through
  its environments; its state by the root's name (`root.q_omega`, `root.theta`,
  `root.vartheta`)."""

  name = "ship_ladder_option_critic"
  Config = Config
  record_fields = ("passed", "steps", "gates", "calls", "return")
  tags = ("learned_hierarchy",)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    self.coder, self.oc = ship_option_critic.learner(self.config.options)

  def graph(self):
    """`ship_option_critic`'s graph, root -> option0 ... option{k-1} -> the turning
    rate, every node seeing the task's tiles of the ship (in the gate's frame on the
    goal and the regatta)."""
    world = self.config.environment.world
    return ship_option_critic.graph(self.oc, lambda: _ladder.tiles_view(world, self.coder))

  def metrics(self, record):
    """The task's benchmark metrics (`ShipLadderHierarchy`), with the options called per
    episode over the last `metric_window` episodes."""
    return {**super().metrics(record),
            **ship_option_critic.option_metrics(record[-self.metric_window:])}
