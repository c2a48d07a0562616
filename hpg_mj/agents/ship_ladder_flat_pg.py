"""Flat PGRL (paper section 5.2; SPEC section 4) carried to the task ladder (SPEC section
11): Eq. 3 over the whole episode with the Gaussian-with-sigmoid policy on a CMAC of the
whole field (9 tilings x 20 x 20 x 36 x 5 tiles over x, y, theta, theta_dot), acting
every 0.6 s, on the task and level its task file's [environment] names, with
`ship_flat_pg`'s [policy] section and defaults. A baseline of the ladder's hybrid (tag
"baseline").

What its CMAC tiles is the ship's state as the hybrid's root reads it
(`ship_ladder_hybrid`): on the current and the harbour the ship's own (the steering
task's gate, the harbour's fixed obstacles learned as places); on the goal and the
regatta the ship's state in the frame of the episode's (the next) gate
(`blocks.GateTiles`), which puts that gate where the steering task's stands.
"""
import dataclasses

from hpg_mj.agents import _ladder
from hpg_mj.agents import hierarchy
from hpg_mj.agents import ship_flat_pg
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import Primitive, Subtask, TaskGraph
from hpg_mj.worlds import ship_core as core


@dataclasses.dataclass(frozen=True)
class Config:
  """The task file's schema: [environment] (the ladder's task and level) and flat
  PGRL's [policy]."""
  environment: _ladder.LadderEnvironment = dataclasses.field(
      default_factory=_ladder.LadderEnvironment)
  policy: ship_flat_pg.Policy = dataclasses.field(default_factory=ship_flat_pg.Policy)


class ShipLadderFlatPG(hierarchy.ShipLadderHierarchy):
  """Flat PGRL on a ladder task (see the module docstring): a one-node graph whose Eq. 3
  learner sees the whole state's tiles, run by the open machine fused with the task's
  world and step by step through its environments; its state by node name
  (`policy.theta`, ...)."""

  name = "ship_ladder_flat_pg"
  Config = Config
  record_fields = ("passed", "steps", "gates", "return")
  tags = ("baseline",)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    pol = self.config.policy
    self.coder = ship_flat_pg.actor_coder(pol.tilings, pol.tiles)
    self.learner = blocks.GaussianCMAC(self.coder, pol.alpha, pol.trace_gamma, 0.0,
                                       core.MAX_TURN_RATE)

  def graph(self):
    """One node over the whole task: Eq. 3 with the episode's rewards (z <- 0 at its
    start), choosing the turning rate every 0.6 s from the tiles of the ship's state
    (in the gate's frame on the goal and the regatta)."""
    view = _ladder.tiles_view(self.config.environment.world, self.coder)
    return TaskGraph("policy", [
        Subtask("policy", children=["turn"], learner=self.learner, view=view,
                termination=blocks.Never()),
        Primitive("turn"),
    ])
