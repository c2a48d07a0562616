"""Tabular HPG (the paper's Algorithm 1) on taxi-fuel (paper section 5.1; SPEC
section 5): a Gibbs policy per subtask of MAXQ's task graph with Refuel, learned
by Eq. 3 with a warm-up of the step sizes and a baseline (both declared).

The fused loop is `hierarchy.taxi_compiled.train`; the step-by-step path is the
task graph of `hierarchy.taxi` over the same arrays (`TaxiHierarchy`).
"""
import dataclasses

import numpy as np

from hpg_mj.agents import _taxi
from hpg_mj.agents.taskfile import param
from hpg_mj.hierarchy import taxi as taxi_hierarchy
from hpg_mj.hierarchy import taxi_compiled

LEVELS = ("root", "carry", "navigate")
_TRACE_KEYS = ("w", "zs", "y", "touched", "marked", "count", "acc")


def _level(alpha, start_fraction, delay, ramp, doc):
  cls = dataclasses.make_dataclass("Level", [
      ("learner", str, param("policy_gradient", "Eq. 3", choices=("policy_gradient",))),
      ("alpha", float, param(alpha, "Eq. 3 step size after the warm-up", low=0)),
      ("start_fraction", float, param(start_fraction, "the step size's fraction of alpha at "
                                      "first", low=0, high=1)),
      ("delay", int, param(delay, "learning episodes at start_fraction", low=0)),
      ("ramp", int, param(ramp, "episodes of the linear rise to alpha", low=1)),
      ("trace_gamma", float, param(1.0, "discount on the Eq. 3 trace (1 = plain Eq. 3)", low=0,
                                   high=1, low_open=True)),
      ("baseline", float, param(0.3, "TD(0) step size of the baseline b(s) (0: none, Eq. 3)",
                                low=0, high=1)),
  ], frozen=True)
  cls.__doc__ = doc
  return cls


Root = _level(0.3, 0.0, 15_000, 20_000, "[root]: Root -> {Get, Put, Refuel}")
Carry = _level(0.1, 0.1, 0, 25_000, "[carry]: Get, Put and Refuel (each its own table)")
Navigate = _level(0.1, 0.1, 0, 25_000, "[navigate]: Navigate(t), one table over (t, row, col)")


@dataclasses.dataclass(frozen=True)
class Config:
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)
  root: Root = dataclasses.field(default_factory=Root)
  carry: Carry = dataclasses.field(default_factory=Carry)
  navigate: Navigate = dataclasses.field(default_factory=Navigate)


class TaxiHPG(_taxi.TaxiAgent):
  """HPG's tables, baselines and generator, trained step by step or compiled."""

  name = "taxi_hpg"
  Config = Config
  record_fields = ("return", "steps", "outcome", "illegal")

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    kwargs = {}
    for level in LEVELS:
      sec = getattr(self.config, level)
      kwargs.update({f"alpha_{level}": sec.alpha, f"start_{level}": sec.start_fraction,
                     f"delay_{level}": sec.delay, f"ramp_{level}": sec.ramp,
                     f"gamma_{level}": sec.trace_gamma, f"baseline_{level}": sec.baseline})
    self._adopt(taxi_compiled.TaxiHPG(seed=seed, config=taxi_compiled.HPGConfig(**kwargs),
                                      task=self.rules))
    self.hierarchy = taxi_hierarchy.TaxiHierarchy(self.engine)
    self._schedule = self.engine.config.schedule()
    self._alphas = np.zeros(len(self.hierarchy.learners))

  def state(self):
    out = {"rng_state": self.rng_state}
    names = ("root", "get", "put", "refuel", "navigate")
    for name, trace, values in zip(names, self.engine.traces, self.engine.values):
      out.update({f"{name}_{k}": v for k, v in zip(_TRACE_KEYS, trace)})
      out[f"{name}_baseline"] = values
    return out

  def compiled(self, episodes, learn, sample):
    # (The engine counts its own episodes; the base class must not count them again.)
    before = self.engine.episodes
    rows = self.engine.run(episodes, learn=learn, greedy=not learn and not sample)
    self.engine.episodes = before
    return rows

  def graph(self):
    return self.hierarchy.graph()

  def begin_episode(self, learn):
    taxi_compiled.step_sizes(self._schedule, self.engine.episodes, self._alphas)
    for learner, alpha in zip(self.hierarchy.learners, self._alphas):
      learner.alpha = float(alpha)
