"""DQN in JAX on the taxi: every step of every copy, its replay buffer and its
gradient steps in one jitted loop over the JAX taxi (`hpg_mj.jax.dqn`).
The agent is `hpg_mj.agents.jax_ppo`'s (the record, the metrics, the greedy
measure, the saved state, the input contract) with this learner and its [dqn]
section. It needs the extra `pip install 'hpg_mj[jax]'`; JAX is imported only when
such an agent is built."""
import dataclasses

from hpg_mj.agents import _taxi
from hpg_mj.agents import jax_ppo
from hpg_mj.agents import sb3
from hpg_mj.taskfile import param


@dataclasses.dataclass(frozen=True)
class DQNSection(sb3.DQNSection):
  """[dqn]: DQN (Mnih et al. 2015) as SB3's by the same names, plus the steps of
  every copy in one compiled call and the gradient clipping SB3 fixes (its 10)."""
  n_steps: int = param(64, "steps of every copy in one compiled call (train_freq divides it)",
                       low=1)
  max_grad_norm: float = param(10.0, "the gradient's global norm is clipped to this",
                               low=0, low_open=True)


@dataclasses.dataclass(frozen=True)
class TaxiDQNJaxConfig:
  """The task file's schema: its sections [environment] and [dqn]."""
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)
  dqn: DQNSection = dataclasses.field(default_factory=DQNSection)

  def __post_init__(self):
    jax_ppo.check_replay("dqn", self.dqn)


class TaxiDQNJax(jax_ppo.TaxiPPOJax):
  """DQN in JAX on taxi-fuel (or the classic taxi, [environment] fuel = false)."""
  name = "taxi_dqn_jax"
  algorithm = "dqn"
  Config = TaxiDQNJaxConfig
