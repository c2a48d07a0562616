"""MAXQ-Q (Dietterich 2000) on taxi-fuel over the task graph of SPEC section 5: a
baseline of HPG (tag "baseline"). The fused loop is `baselines.taxi_maxq.train`;
the step-by-step path runs the same compiled rules through `MAXQNode` learners on
the shared taxi graph (`hierarchy.taxi_maxq`).
"""
import dataclasses

from hpg_mj.agents import _taxi
from hpg_mj.agents.taskfile import param
from hpg_mj.baselines import taxi_maxq as mq
from hpg_mj.hierarchy import taxi_maxq as maxq_graph

LEVELS = ("root", "carry", "navigate")


def _level(epsilon, epsilon_episodes, initial, pseudo_reward, doc):
  fields = [
      ("learner", str, param("maxq_q", "MAXQ-Q", choices=("maxq_q",))),
      ("alpha", float, param(1.0, "completion step size", low=0, high=1, low_open=True)),
      ("epsilon", float, param(epsilon, "epsilon-greedy at first, decaying linearly to 0",
                               low=0, high=1)),
      ("epsilon_episodes", int, param(epsilon_episodes, "episodes of the decay", low=0)),
      ("initial", float, param(initial, "C~ and C before learning")),
  ]
  if pseudo_reward:
    fields.append(("pseudo_reward", float, param(0.0, "C~'s reward when the subtask ends")))
  cls = dataclasses.make_dataclass("Level", fields, frozen=True)
  cls.__doc__ = doc
  return cls


Root = _level(1.0, 14_000, 20.0, False, "[root]: Root -> {Get, Put, Refuel}; sees the full state")
Carry = _level(0.1, 6_000, 0.0, True, "[carry]: Get, Put, Refuel (each its own tables)")
Navigate = _level(0.1, 1_000, 0.0, True, "[navigate]: Navigate(t), over (t, row, col, fuel)")


@dataclasses.dataclass(frozen=True)
class Primitive:
  """[primitive]: V(a, s) over (classic state, tank empty)."""
  alpha: float = param(1.0, "V(a, s) step size", low=0, high=1, low_open=True)
  all_states_updating: bool = param(True, "a child's target updates every state its run "
                                    "passed through")


@dataclasses.dataclass(frozen=True)
class Config:
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)
  root: Root = dataclasses.field(default_factory=Root)
  carry: Carry = dataclasses.field(default_factory=Carry)
  navigate: Navigate = dataclasses.field(default_factory=Navigate)
  primitive: Primitive = dataclasses.field(default_factory=Primitive)


class TaxiMAXQ(_taxi.TaxiAgent):
  """MAXQ-Q's tables and generator, trained step by step or compiled."""

  name = "taxi_maxq"
  Config = Config
  record_fields = ("return", "steps", "outcome")
  tags = ("baseline",)

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    kwargs = {}
    for level in LEVELS:
      sec = getattr(self.config, level)
      kwargs.update({f"alpha_{level}": sec.alpha, f"epsilon_{level}": sec.epsilon,
                     f"epsilon_episodes_{level}": sec.epsilon_episodes,
                     f"initial_{level}": sec.initial})
      if level != "root":
        kwargs[f"pseudo_reward_{level}"] = sec.pseudo_reward
    prim = self.config.primitive
    config = mq.MAXQConfig(alpha_primitive=prim.alpha, all_states=prim.all_states_updating,
                           **kwargs)
    self._adopt(mq.TaxiMAXQ(seed=seed, config=config, task=self.rules))
    self.hierarchy = maxq_graph.TaxiMAXQHierarchy(self.engine)

  def state(self):
    a = self.engine
    return {"rng_state": self.rng_state, "primitive_values": a.values,
            "completions_pseudo": a.c_tilde, "completions": a.c}

  def compiled(self, episodes, learn, sample):
    before = self.engine.episodes
    rows = self.engine.run(episodes, learn=learn, sample=sample)
    self.engine.episodes = before
    return rows

  def graph(self):
    return self.hierarchy.graph()

  def begin_episode(self, learn):
    h = self.hierarchy
    mq.epsilons_at(h.settings, self.engine.episodes, h.epsilons)
    h.cursor[0] = 0
