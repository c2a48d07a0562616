"""Flat PGRL on the full ship task (paper section 5.2; SPEC section 4): Eq. 3 over
the whole episode with the Gaussian-with-sigmoid policy on a CMAC of 9 tilings x
20 x 20 x 36 x 5 = 72,000 tiles (648,000 weights), acting every 0.6 s with SPEC
section 2's rewards. A baseline of the hierarchy (tag "baseline").

Every step touches only the 9 active tiles: the trace is applied lazily
(`learners.eligibility`), so a step's cost does not grow with the episode or the
number of weights. The agent is its Config and a one-node graph of blocks, which
the open machine (`hierarchy.program`) runs on both paths.
"""
import dataclasses

from hpg_mj.agents import _ship
from hpg_mj.agents import hierarchy
from hpg_mj import taskfile
from hpg_mj.taskfile import param
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import Primitive, Subtask, TaskGraph
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core as core

def actor_coder(n_tilings=9, tiles=(20, 20, 36, 5)):
  """The policy's CMAC over the ship's state (x m, y m, heading deg, turning rate
  deg/s): `n_tilings` tilings of `tiles` tiles along each, the heading wrapping round."""
  return tiles_mod.TileCoder((0.0, 0.0, -180.0, -core.MAX_TURN_RATE),
                             (core.FIELD_SIZE, core.FIELD_SIZE, 180.0, core.MAX_TURN_RATE),
                             tuple(tiles), (False, False, True, False), n_tilings)


@dataclasses.dataclass(frozen=True)
class Policy(taskfile.Section):
  """[policy]: Eq. 3 over the full task."""
  learner: str = param("policy_gradient", "Eq. 3", choices=("policy_gradient",))
  alpha: float = param(0.01, "Eq. 3 step size", low=0, low_open=True)
  trace_gamma: float = param(1.0, "discount on the Eq. 3 trace (1 = plain Eq. 3)", low=0,
                             high=1, low_open=True)
  tilings: int = param(9, "CMAC tilings", low=1)
  tiles: tuple = param((20, 20, 36, 5), "tiles per tiling over x, y, theta, theta_dot",
                       length=4, low=1)


@dataclasses.dataclass(frozen=True)
class Config:
  """The task file's schema: its sections [environment] and [policy]."""
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)
  policy: Policy = dataclasses.field(default_factory=Policy)


class ShipFlatPG(hierarchy.ShipHierarchy):
  """Flat PGRL: a one-node graph whose Eq. 3 learner sees the whole state's tiles, run
  by the open machine; its state by node name (`policy.theta`, ...), its
  `parameters()` the policy's weights with pending updates applied (`policy.theta`)
  and its baseline's values (`policy.values`, zero: it has none)."""

  name = "ship_flat_pg"
  Config = Config
  record_fields = ("passed", "steps", "return")
  tags = ("baseline",)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    pol = self.config.policy
    self.coder = actor_coder(pol.tilings, pol.tiles)
    self.learner = blocks.GaussianCMAC(self.coder, pol.alpha, pol.trace_gamma, 0.0,
                                       core.MAX_TURN_RATE)

  def graph(self):
    """One node over the whole task: Eq. 3 with the episode's rewards (z <- 0 at
    its start), choosing the turning rate every 0.6 s."""
    return TaskGraph("policy", [
        Subtask("policy", children=["turn"], learner=self.learner,
                view=blocks.StateTiles(self.coder), termination=blocks.Never()),
        Primitive("turn"),
    ])
