"""SAC in JAX on the ship: every step of every copy, its replay buffer and its
gradient steps in one jitted loop over the JAX ship (`hpg_mj.jax.sac`). The agent
is `hpg_mj.agents.jax_ppo`'s (the record, the metrics, the greedy measure, the saved
state, the input contract: observations onto [-1, 1], the turning rate in deg/s)
with this learner and its [sac] section; the actor acts in [-1, 1] and the world
gets r = 15 a deg/s (`hpg_mj.jax.ppo.ShipIO.act`). It needs the extra
`pip install 'hpg_mj[jax]'`; JAX is imported only when such an agent is built."""
import dataclasses

from hpg_mj.agents import _ship
from hpg_mj.agents import jax_ppo
from hpg_mj.agents import sb3
from hpg_mj.taskfile import param


@dataclasses.dataclass(frozen=True)
class SACSection(sb3.SACSection):
  """[sac]: SAC (Haarnoja et al. 2018) as SB3's by the same names (entropy
  coefficient learned, "auto"), plus the steps of every copy in one compiled call."""
  n_steps: int = param(250, "steps of every copy in one compiled call (train_freq divides it)",
                       low=1)


@dataclasses.dataclass(frozen=True)
class ShipSACJaxConfig:
  """The task file's schema: its sections [environment] and [sac]."""
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)
  sac: SACSection = dataclasses.field(default_factory=lambda: SACSection(
      learning_rate=1e-4, gamma=0.995))

  def __post_init__(self):
    jax_ppo.check_replay("sac", self.sac)


class ShipSACJax(jax_ppo.ShipPPOJax):
  """SAC in JAX on the full ship task (SPEC section 2), the task file's rewards."""
  name = "ship_sac_jax"
  algorithm = "sac"
  Config = ShipSACJaxConfig
  # `hpg-mj run` checkpoints at least every 0.1 M control steps: one to two minutes of
  # SAC on a core here (PPO's 1 M would leave a whole run unsaved).
  checkpoint_rows = 100
