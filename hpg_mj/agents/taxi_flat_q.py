"""Flat Q-learning on taxi-fuel over the full state (SPEC section 5): a baseline
of HPG (tag "baseline"). One-step Watkins Q-learning, epsilon-greedy with a
linear decay; the fused loop is `baselines.taxi_flat_q.train`, the step-by-step
path the one-node graph over the same Q-table."""
import dataclasses

from hpg_mj.agents import _taxi
from hpg_mj.agents.taskfile import param
from hpg_mj.baselines import taxi_flat_q
from hpg_mj.hierarchy import flat as flat_graph
from hpg_mj.worlds import taxi_core as core


@dataclasses.dataclass(frozen=True)
class Policy:
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


class TaxiFlatQ(_taxi.TaxiAgent):
  """Flat Q-learning's table and generator, trained step by step or compiled."""

  name = "taxi_flat_q"
  Config = Config
  record_fields = ("return", "steps", "outcome")
  tags = ("baseline",)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    pol = self.config.policy
    self._adopt(taxi_flat_q.FlatQ(pol.alpha, pol.epsilon_start, pol.epsilon_end,
                                  pol.epsilon_episodes, pol.initial, seed=seed, task=self.rules))
    self.engine.primitive_steps = 0

  def state(self):
    lr = self.engine.learner
    return {"rng_state": self.rng_state, "q": lr.q, "trace_index": lr.index,
            "trace_value": lr.value, "trace_count": lr.count}

  def compiled(self, episodes, learn, sample):
    before = self.engine.episodes
    rows = self.engine.train_compiled(episodes, learn=learn, sample=sample)
    self.engine.episodes = before
    return rows

  def _view(self, call, obs):
    fuel = self.rules.fuel_enabled
    return core.encode_state(*(int(v) for v in obs[:4]),
                             int(obs[4]) if fuel else core.CLASSIC_FUEL, fuel)

  def graph(self):
    return flat_graph.flat_graph(self.engine.learner, self._view,
                                 list(core.ACTION_NAMES[:self.engine.n_actions]))
