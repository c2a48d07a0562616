"""Tabular HPG (Algorithm 1) on taxi-fuel (SPEC section 5, paper section 5.1): its
configuration and its graph of blocks (`hierarchy.blocks`: a `GibbsTable` per
subtask over the taxi's abstractions, children, terminations and Navigate's
binding, `hierarchy.taxi_subtasks`), which the open machine (`hierarchy.program`)
runs on both paths.

Every non-primitive subtask of the task graph (`taxi_rules`) holds one policy
parameter per (abstract state, child) and acts with a softmax (Gibbs) policy;
each learns by Eq. 3 on its own trace (`learners.eligibility`):

    on every call of subtask i:    z_i <- 0                            (Algorithm 1, lines 11-12)
    each choice a in state s:      z_i <- gamma_i z_i + psi_i(s, a)    (line 14; `softmax_act`)
    when the child a returns R:    theta_i <- theta_i + alpha_i R z_i  (line 16, read as Eq. 3)

R is the sum of the primitive rewards earned while the child ran (line 17); the
taxi has no internal reward G. The trace is reset when a subtask starts rather
than when it ends (line 12): the same thing, except that the final child's
reward - a delivery's +20 - is applied with the trace still holding the
choices that led to it, as Eq. 3 does (z is reset at s*, and R(s*, .) = 0).

Two deliberate departures from the paper, each an option of the task file
(tasks/taxi_fuel_hpg.toml) explained at `Config`: the step sizes warm up instead
of never increasing, and each subtask subtracts a learned baseline b_i(s) from
its reward-to-go (REINFORCE's baseline), which adds to the rule above

    each choice a in state s:      theta_i <- theta_i - alpha_i b_i(s) psi_i(s, a)
    when the child a returns R:    b_i(s) <- b_i(s) + beta_i (R + b_i(s') - b_i(s))

"""
import dataclasses

from hpg_mj.agents import _taxi
from hpg_mj.agents import hierarchy
from hpg_mj import taskfile
from hpg_mj.taskfile import param
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy import taxi_subtasks
from hpg_mj.hierarchy.graph import Child, Primitive, Subtask, TaskGraph
from hpg_mj.worlds import taxi_core as core


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
  ], frozen=True, bases=(taskfile.Section,))
  cls.__doc__ = doc
  return cls


Root = _level(0.3, 0.0, 15_000, 20_000, "[root]: Root -> {Get, Put, Refuel}")
Carry = _level(0.1, 0.1, 0, 25_000, "[carry]: Get, Put and Refuel (each its own table)")
Navigate = _level(0.1, 0.1, 0, 25_000, "[navigate]: Navigate(t), one table over (t, row, col)")


@dataclasses.dataclass(frozen=True)
class Config:
  """HPG's hyper-parameters for the taxi, by level: [root]; [carry] (Get, Put and
  Refuel); [navigate] (Navigate(t)); each with the keys alpha, start_fraction,
  delay, ramp, trace_gamma and baseline (alpha_i, start_i, ... below).

  Step sizes warm up: subtask i learns with alpha_i * f_i(e) in its e-th learning
  episode, f_i = start_i for the first delay_i episodes, then rising linearly to
  1 over ramp_i episodes. The paper's assumptions A4-A5 ask for non-increasing
  step sizes; a constant alpha large enough to learn in 100,000 episodes makes
  Eq. 3 (REINFORCE, no baseline) commit early to wrong children for good: the
  first calls are long random walks that mostly end with the tank dry, so every
  choice in them gets the same large negative reward-to-go, pure noise that
  drives the softmax to a corner, and a subtask whose calls from a state always
  run dry never again sees a reward that tells its children apart. Small steps
  while calls are long and doomed, full steps once they are short, avoid it.
  Root also waits (delay) with a uniform policy while its children learn, or it
  learns to avoid a child (Refuel, say) that is merely still bad.

  Each subtask may also subtract a baseline b_i(s) from its reward-to-go, a
  second declared departure (REINFORCE's baseline, Williams 1992; the paper's
  Eq. 3 has none): a choice a made in state s then moves theta_i along
  psi(s, a) times (the rewards of the rest of the call - b_i(s)) instead of the
  rewards alone. In Eq. 3's online form that is one extra step at the choice,
  theta_i <- theta_i - alpha_i b_i(s) psi(s, a) (`policies.softmax_choose`), next to the
  unchanged z and theta updates. b_i is a table over subtask i's abstract states,
  learned by TD(0) on the subtask's own rewards with step size baseline_i
  (`policies.softmax_learn`; 0 keeps b_i = 0, Eq. 3 exactly). Any b(s) that does not
  depend on the choice made in s leaves the gradient estimate unbiased
  (E[psi(s, a)] = 0 under the policy); it only removes variance. Why it is
  needed: without it every call's reward-to-go is of one sign (Navigate's only
  ever negative, Root's mostly the +20 delivery), so each choice is pushed the
  same way whatever its worth, and only the small differences between those
  large pushes carry the gradient. Root, whose decisions (refuel now, later or
  never) differ by a few steps out of a return of about 6, learned them too
  slowly: about 93% of the optimal mean return after 100,000 episodes (online,
  last 1,000 episodes, seeds 0-4) with alpha 0.1 / 0.03 / 0.03 and no
  baseline, while the larger step sizes below run away without one (51%).
  With the baseline and them: 98.8% (97.2% over seeds 5-24). The baseline's
  step size is 1 at most: b(s) moves part of the way to its TD target. The
  baselines learn from the first episode, Root's too while Root waits.
  """
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)
  root: Root = dataclasses.field(default_factory=Root)
  carry: Carry = dataclasses.field(default_factory=Carry)
  navigate: Navigate = dataclasses.field(default_factory=Navigate)


class TaxiHPG(hierarchy.TaxiHierarchy):
  """HPG's Gibbs tables and baselines: the taxi hierarchy as a graph of blocks; its
  state by node name (`root.theta`, ..., `navigate.baseline`)."""

  name = "taxi_hpg"
  Config = Config
  record_fields = ("return", "steps", "outcome", "illegal")

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    sizes = taxi_subtasks.n_abstract_states(self.rules.fuel_enabled, self.rules.capacity)
    levels = (self.config.root, self.config.carry, self.config.carry, self.config.carry,
              self.config.navigate)
    self.tables = tuple(blocks.GibbsTable(n, level.alpha, level.trace_gamma, level.baseline,
                                          level.start_fraction, level.delay, level.ramp)
                        for n, level in zip(sizes, levels))

  def policy_tables(self):
    """Each subtask's current parameters, an (abstract states, children) table."""
    parameters = self.parameters()
    return tuple(parameters[f"{name}.theta"].reshape(t.n_states, -1)
                 for name, t in zip(blocks.TAXI_SUBTASKS, self.tables))

  def baselines(self):
    """Each subtask's baseline b(s), by abstract state (the live arrays)."""
    state = self.machine.state()
    return tuple(state[f"{name}.baseline"] for name in blocks.TAXI_SUBTASKS)

  def graph(self):
    """Root -> {Get, Put, Refuel}; each of those -> {Navigate(t), its primitive};
    Navigate(t) -> the four moves (`hierarchy.taxi_subtasks`)."""
    root, get, put, refuel, navigate = self.tables

    def carry(name, table, primitive):
      return Subtask(name, children=[Child("navigate", bind=blocks.TaxiTarget(name)), primitive],
                     learner=table, view=blocks.TaxiAbstraction(name),
                     available=blocks.TaxiChildren(name), termination=blocks.TaxiEnd(name))
    moves = [name.lower() for name in core.ACTION_NAMES[:4]]
    return TaskGraph("root", [
        Subtask("root", children=["get", "put", "refuel"], learner=root,
                view=blocks.TaxiAbstraction("root"), available=blocks.TaxiChildren("root"),
                termination=blocks.Never()),
        carry("get", get, "pickup"), carry("put", put, "dropoff"),
        carry("refuel", refuel, "fillup"),
        Subtask("navigate", children=moves, learner=navigate,
                view=blocks.TaxiAbstraction("navigate"), termination=blocks.TaxiEnd("navigate")),
        *(Primitive(name, action=i) for i, name in enumerate(moves)),
        Primitive("pickup", action=core.PICKUP), Primitive("dropoff", action=core.DROPOFF),
        Primitive("fillup", action=core.FILLUP),
    ])
