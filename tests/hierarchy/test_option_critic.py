"""Option-critic on the open machine (`hierarchy.kinds.option_critic`, the agent
`taxi_option_critic`): its two paths are one algorithm; one step by hand is the
paper's updates; its arrays are saved by the root's name and a run resumes where it
stopped; and what it refuses is named in one line."""
import dataclasses

import gymnasium
import numpy as np
import pytest

import hpg_mj  # noqa: F401
from hpg_mj import agents
from hpg_mj.agents import taxi_option_critic as toc
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError, Primitive, Subtask, TaskGraph
from hpg_mj.hierarchy.kinds import option_critic as oc
from hpg_mj.hierarchy.program import Program
from hpg_mj.learners import rng
from hpg_mj.taskfile import updated
from hpg_mj.worlds import taxi_core as core
from hpg_mj.worlds import taxi_rules


def _agent(seed, fuel=True, **options):
  return toc.TaxiOptionCritic(updated(toc.Config(), environment={"fuel": fuel},
                                      options=options), seed=seed)


@pytest.mark.parametrize("fuel,env_id", [(True, "hpg_mj/TaxiFuel-v0"), (False, "hpg_mj/Taxi-v0")])
def test_stepwise_and_compiled_agree_bit_for_bit(fuel, env_id):
  a, b = _agent(5, fuel), _agent(5, fuel)
  ra = a.train_stepwise(gymnasium.make(env_id), 60)
  rb = b.train(60, "analytic")
  for field in ("return", "steps", "outcome", "calls"):
    np.testing.assert_array_equal(ra[field], rb[field])
  for name, value in a.state().items():
    np.testing.assert_array_equal(value, b.state()[name])
  state = a.state()
  assert all(np.any(state[f"root.{k}"] != 0) for k in ("q_omega", "q_u", "theta", "vartheta"))
  assert rb["calls"].sum() > len(rb)               # options end inside episodes too


def test_one_step_by_hand():
  """One primitive step of an option, from a fixed start, in an episode truncated
  after it: the critic's, the policy's and the termination's updates, as the module's
  docstring writes them (the option chosen greedily, its action certain: South)."""
  agent = toc.TaxiOptionCritic(updated(toc.Config(), environment={"max_steps": 1}, options={
      "n_options": 2, "alpha_critic": 0.5, "alpha_policy": 0.25, "alpha_termination": 0.25,
      "gamma": 0.9, "xi": 0.01, "epsilon": 0.0}), seed=2)
  c, n, k, m = agent.oc, agent.oc.n_states, 2, agent.oc.n_actions
  start = np.array([0, 0, 1, 2, 5])                # taxi at R, passenger at G for Y, fuel 5
  after = np.array([1, 0, 1, 2, 4])                # South: one row down, a unit of fuel
  s, s2 = (int(taxi_rules.encoded(x.astype(float), agent.world)) for x in (start, after))
  state = agent.state()
  state["root.q_omega"][:] = np.arange(n * k) % 7 * 0.5
  state["root.q_omega"][s * k:s * k + 2] = (1.0, 3.0)       # option 1 is chosen
  state["root.theta"][:] = 0.0
  for w in range(k):
    state["root.theta"][(w * n + s) * m + core.SOUTH] = 50.0  # and South, surely
  before = {key: value.copy() for key, value in state.items()}
  record = agent.as_record(agent.compiled(1, True, True, starts=[start]))
  assert record["steps"][0] == 1 and record["return"][0] == -1.0
  q0, w = before["root.q_omega"], 1
  beta = 0.5                                           # vartheta = 0
  target = -1.0 + 0.9 * ((1 - beta) * q0[s2 * k + w] + beta * q0[s2 * k:s2 * k + 2].max())
  q_omega = q0[s * k + w] + 0.5 * (target - q0[s * k + w])
  q_u = 0.5 * target
  got = agent.state()
  np.testing.assert_allclose(got["root.q_omega"][s * k + w], q_omega, rtol=1e-13)
  np.testing.assert_allclose(got["root.q_u"][(s * k + w) * m + core.SOUTH], q_u, rtol=1e-13)
  row = before["root.theta"][(w * n + s) * m:(w * n + s + 1) * m]
  pi = np.exp(row - row.max()) / np.exp(row - row.max()).sum()
  theta = row - 0.25 * (q_u - q_omega) * pi
  theta[core.SOUTH] += 0.25 * (q_u - q_omega)
  np.testing.assert_allclose(got["root.theta"][(w * n + s) * m:(w * n + s + 1) * m], theta,
                             rtol=1e-13)
  advantage = q0[s2 * k + w] - q0[s2 * k:s2 * k + 2].max() + 0.01
  np.testing.assert_allclose(got["root.vartheta"][w * n + s2],
                             -0.25 * beta * (1 - beta) * advantage, rtol=1e-13)
  changed = {key for key in got if np.any(got[key] != before[key])}
  assert changed == {"rng_state", "root.q_omega", "root.q_u", "root.theta", "root.vartheta"}


def test_saved_by_the_roots_name_and_resumed(tmp_path):
  agent = agents.build(agents.load_task("taxi_fuel_option_critic"), seed=3)
  record = agent.train(200)
  assert {"root.q_omega", "root.q_u", "root.theta", "root.vartheta"} <= set(agent.state())
  assert set(agent.parameters()) == {"root.q_omega", "root.q_u", "root.theta", "root.vartheta"}
  agents.save(agent, tmp_path / "a", record)
  ahead = agent.train(100)
  loaded, _, _ = agents.load(tmp_path / "a")
  again = loaded.train(100)
  for field in ahead.dtype.names:
    np.testing.assert_array_equal(ahead[field], again[field])


def _graph(c, root_learner=None, option_learner=None, end=None, k=None):
  names = core.ACTION_NAMES[:c.n_actions]
  options = [f"option{w}" for w in range(c.n_options if k is None else k)]
  return TaskGraph("root", [
      Subtask("root", children=options, learner=root_learner or oc.OverOptions(c),
              view=blocks.TaxiState(), termination=blocks.Never()),
      *(Subtask(n, children=list(names), learner=option_learner(w) if option_learner else
                oc.IntraOption(c, w), view=blocks.TaxiState(),
                termination=end(w) if end else oc.LearnedTermination(c, w))
        for w, n in enumerate(options)),
      *(Primitive(n, action=i) for i, n in enumerate(names))])


def test_what_it_refuses_is_named():
  world = taxi_rules.world_config(core.TaxiRules())
  c = oc.OptionCritic(core.num_states(True), 2, core.num_actions(True))
  with pytest.raises(GraphError, match=r"^subtask 'root': OverOptions chooses among 2 options "
                                       r"\(OptionCritic.n_options\); it has 3 children"):
    Program(_graph(c, k=3), obs_size=5, world=world)
  with pytest.raises(GraphError, match=r"^subtask 'option1': its IntraOption.option = 5: "
                                       r"must be an integer in \[0, 2\)"):
    Program(_graph(c, option_learner=lambda w: oc.IntraOption(c, 5 if w else 0)), obs_size=5,
            world=world)
  small = oc.OptionCritic(10, 2, core.num_actions(True))
  with pytest.raises(GraphError, match=r"^subtask 'root': its view gives 6500 states, its "
                                       r"OptionCritic has n_states = 10"):
    Program(_graph(small), obs_size=5, world=world)
  with pytest.raises(ValueError, match=r"^OptionCritic.gamma = 2.0: must be a finite number "
                                       r"in \[0, 1\]"):
    oc.OptionCritic(10, 2, 7, gamma=2.0)
  with pytest.raises(GraphError, match=r"reads the world's settings"):
    Program(_graph(c), obs_size=5)


@dataclasses.dataclass(eq=False)
class _WithCost(oc.IntraOption):
  """A newcomer's deliberation-cost variant of the option's learner, its kind forgotten."""
  eta: float = 0.5


@dataclasses.dataclass(eq=False)
class _Renamed(oc.IntraOption):
  """A subclass that adds no field: the base's kind runs it, as it is."""


def test_a_subclassed_block_with_a_field_of_its_own_needs_a_kind_of_its_own():
  """Unregistered, the variant ran as the shipped option-critic, its `eta` ignored, bit
  for bit; now the machine refuses it, naming the field and the kind it would run by."""
  world = taxi_rules.world_config(core.TaxiRules())
  c = oc.OptionCritic(core.num_states(True), 2, core.num_actions(True))
  with pytest.raises(GraphError, match=r"^subtask 'option0': its learner _WithCost adds \['eta'\] "
                                       r"to IntraOption, whose kind \(IntraOptionKind\) would run "
                                       r"it ignoring them; register a kind for _WithCost"):
    Program(_graph(c, option_learner=lambda w: _WithCost(c, w)), obs_size=5, world=world)
  Program(_graph(c, option_learner=lambda w: _Renamed(c, w)), obs_size=5, world=world)
