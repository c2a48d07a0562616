"""MAXQ-Q on the taxi: hand-worked updates, the exact completion values of the
recursively optimal policy, and the task-graph path equal to the fused loop."""
import gymnasium
import numpy as np
import pytest
import compile_order

import hpg_mj  # noqa: F401
from hpg_mj import suite
from hpg_mj.agents import taxi_maxq as mq
from hpg_mj.taskfile import updated
from hpg_mj.hierarchy import maxq
from hpg_mj.hierarchy import taxi_subtasks as rules
from hpg_mj.worlds import taxi_core, taxi_values
from hpg_mj.worlds import taxi_rules as world_rules

CLASSIC = taxi_core.TaxiRules(fuel_enabled=False)
# Short schedules: every level explores, then all are greedy by episode 20,000.
SHORT = updated(mq.Config(), root={"epsilon_episodes": 20_000},
                carry={"epsilon_episodes": 10_000}, navigate={"epsilon_episodes": 3_000})


def _update(agent, subtask, target, child, before, after, ended=False):
  """One completion update of `agent`'s tables, from `before` to `after`."""
  path = np.array([before], dtype=np.int64)
  maxq.update_completion(subtask, target, child, path, 0, 1, np.array(after, dtype=np.int64), ended,
                       agent.world, agent.tables, agent.settings, True, maxq.new_scratch())


def _entry(agent, subtask, target, state, child):
  row = maxq.abstract_state(subtask, target, np.array(state, dtype=np.int64), agent.world)
  return agent.offsets[subtask] + row * rules.N_CHILDREN[subtask] + child


def test_completion_updates_match_hand_worked_steps():
  config = updated(mq.Config(), navigate={"alpha": 0.5, "pseudo_reward": -3.0},
                   carry={"alpha": 0.25}, root={"initial": 0.0})
  agent = maxq.MAXQEngine(config=config)
  # Navigate(G = (0, 4)) moves East from (0, 3) onto G: it terminated there, so C~
  # gets the pseudo-reward and C gets 0: C~ = 0.5 * -3, C = 0.5 * 0.
  before, after = [0, 3, 2, 1, 9], [0, 4, 2, 1, 8]
  _update(agent, rules.NAVIGATE, 1, taxi_core.EAST, before, after)
  i = _entry(agent, rules.NAVIGATE, 1, before, taxi_core.EAST)
  assert agent.c_tilde[i] == -1.5 and agent.c[i] == 0.0
  assert np.count_nonzero(agent.c_tilde) == 1 and np.count_nonzero(agent.c) == 0
  # Put chose Navigate(destination = G) in (2, 4) and it returned at G: the
  # target is the best child there, Dropoff: V(Dropoff, s') + C(Put, s', Dropoff).
  ride_before, ride_after = [2, 4, 4, 1, 9], [0, 4, 4, 1, 7]
  s_after = maxq.primitive_state(np.array(ride_after), agent.world)
  agent.values[s_after * maxq.N_PRIMITIVES + taxi_core.DROPOFF] = 20.0
  agent.c[_entry(agent, rules.PUT, 0, ride_after, rules.CARRY_PRIMITIVE)] = 2.0    # made up
  agent.c_tilde[_entry(agent, rules.PUT, 0, ride_after, rules.CARRY_PRIMITIVE)] = 4.0
  _update(agent, rules.PUT, 0, rules.CARRY_NAVIGATE, ride_before, ride_after)
  j = _entry(agent, rules.PUT, 0, ride_before, rules.CARRY_NAVIGATE)
  assert agent.c_tilde[j] == 0.25 * (20.0 + 4.0) and agent.c[j] == 0.25 * (20.0 + 2.0)
  # The episode ended (the tank ran dry): both targets are 0.
  agent.c_tilde[j] = agent.c[j] = 8.0
  _update(agent, rules.PUT, 0, rules.CARRY_NAVIGATE, ride_before, ride_after, ended=True)
  assert agent.c_tilde[j] == 6.0 and agent.c[j] == 6.0
  # A primitive's value: V(a, s) <- (1 - alpha) V + alpha r.
  values = np.array([2.0])
  maxq.update_primitive(values, 0, -10.0, 0.25)
  assert values[0] == 0.25 * -10.0 + 0.75 * 2.0


def test_all_states_updating_updates_every_state_of_the_childs_run():
  agent = maxq.MAXQEngine(config=updated(mq.Config(), root={"initial": 0.0}))
  # Get's Navigate(R) ran (2, 0) -> (1, 0) -> (0, 0): both states where it was
  # running get the target of the state it returned in.
  path = np.array([[2, 0, 0, 3, 9], [1, 0, 0, 3, 8], [0, 0, 0, 3, 7]], dtype=np.int64)
  pickup = maxq.primitive_state(path[2], agent.world) * maxq.N_PRIMITIVES + taxi_core.PICKUP
  agent.values[pickup] = -1.0
  maxq.update_completion(rules.GET, 0, rules.CARRY_NAVIGATE, path, 0, 2, path[2], False,
                      agent.world, agent.tables, agent.settings, True, maxq.new_scratch())
  for k in (0, 1):
    assert agent.c[_entry(agent, rules.GET, 0, path[k], rules.CARRY_NAVIGATE)] == -1.0
  assert np.count_nonzero(agent.c) == 2


def test_exact_values_are_the_flat_optimum():
  """The MAXQ abstraction is safe and the recursively optimal policy optimal:
  V(Root, s) of the exact hierarchical solution is V*(s) on every start."""
  for task in (CLASSIC, taxi_core.TaxiRules()):
    _, known, v = maxq.exact_values(task)
    model = taxi_values.taxi_values(task.fuel_enabled)
    starts = model.start_states()
    np.testing.assert_array_equal(v[rules.ROOT, starts], model.v[starts])
    assert known.any()


def _greedy_visits(agent):
  """Every (subtask, target, state, child) of greedy episodes from all the
  classic taxi's starts, and the returns."""
  q, v, mask = maxq.new_scratch()
  visits = []

  def run(subtask, target, state, episode):
    total = 0.0
    while not world_rules.episode_over(episode) and not maxq.terminated(subtask, target, state,
                                                                agent.world):
      a = maxq.choose(subtask, target, state, agent.world, agent.tables, 0.0, False,
                    agent.rng_state, (q, v, mask))
      visits.append((subtask, target, state.copy(), a))
      if subtask == rules.NAVIGATE:
        total += world_rules.primitive_step(state, episode, a, agent.world)
      elif subtask == rules.ROOT:
        total += run(a + 1, 0, state, episode)
      elif a == rules.CARRY_PRIMITIVE:
        total += world_rules.primitive_step(state, episode, rules.carry_primitive(subtask), agent.world)
      else:
        total += run(rules.NAVIGATE, rules.carry_target(subtask, state), state, episode)
    return total

  model = taxi_values.taxi_values(False)
  returns = {}
  for s in model.start_states():
    state = np.array(taxi_core.decode_state(s, False), dtype=np.int64)
    returns[s] = run(rules.ROOT, 0, state, np.zeros(3, dtype=np.int64))
  return visits, returns


def test_converged_completions_match_the_exact_values_on_the_classic_taxi():
  agent = maxq.MAXQEngine(seed=0, config=SHORT, task=CLASSIC)
  record = agent.run(30_000)
  assert record[-1000:, maxq.RETURN].mean() >= 0.98 * taxi_values.optimal_mean_return(False)
  exact, known, _ = maxq.exact_values(CLASSIC)
  visits, returns = _greedy_visits(agent)
  model = taxi_values.taxi_values(False)
  # The greedy policy is optimal from every start ...
  assert all(returns[s] == model.v[s] for s in returns)
  # ... and its completions C(i, s, a) (and C~: no pseudo-rewards) are exact on
  # every state it visits, in every subtask.
  seen = set()
  for subtask, target, state, child in visits:
    i = _entry(agent, subtask, target, state, child)
    assert known[i]
    assert abs(agent.c[i] - exact[i]) < 1e-9, (rules.SUBTASK_NAMES[subtask], state, child)
    assert agent.c_tilde[i] == agent.c[i]
    seen.add(subtask)
  assert seen == {rules.ROOT, rules.GET, rules.PUT, rules.NAVIGATE}
  # The learned V(Root, s) at each start is the optimal return.
  q, v, mask = maxq.new_scratch()
  for s in list(returns)[::7]:
    state = np.array(taxi_core.decode_state(s, False), dtype=np.int64)
    base = maxq.root_scores(state, agent.world, agent.tables, (q, v, mask))
    a = maxq.greedy(q[2], mask[2], rules.N_CHILDREN[rules.ROOT])
    assert v[2, a] + agent.c[base + a] == model.v[s]


def test_a_greedy_policy_delivers_every_passenger():
  agent = maxq.MAXQEngine(seed=2, config=SHORT, task=CLASSIC)
  agent.run(25_000)
  greedy = agent.run(500, learn=False)
  assert np.all(greedy[:, maxq.OUTCOME] == world_rules.DELIVERED)
  assert agent.episodes == 25_000


# Every level explores during all 300 episodes, so that every table is compared.
EAGER = updated(mq.Config(), root={"epsilon": 0.2, "epsilon_episodes": 300},
                carry={"epsilon_episodes": 200}, navigate={"epsilon_episodes": 100})


def _eager_agent(seed, fuel=True):
  """The MAXQ-Q agent with EAGER's schedules."""
  return mq.TaxiMAXQ(updated(EAGER, environment={"fuel": fuel}), seed=seed)


def _assert_same_agents(a, b):
  for name, value in a.state().items():
    np.testing.assert_array_equal(value, b.state()[name])
  assert a.episodes == b.episodes and a.engine.primitive_steps == b.engine.primitive_steps


@pytest.mark.parametrize("fuel,env_id", [(True, "hpg_mj/TaxiFuel-v0"), (False, "hpg_mj/Taxi-v0")])
def test_stepwise_and_compiled_maxq_agree_bit_for_bit(fuel, env_id):
  a, b = _eager_agent(4, fuel), _eager_agent(4, fuel)
  env = gymnasium.make(env_id)
  ra = a.train_stepwise(env, 300)
  rb = b.train(300, "analytic")
  np.testing.assert_array_equal(ra, rb)
  _assert_same_agents(a, b)
  # Every subtask learned (Refuel only with fuel).
  for i in range(rules.N_SUBTASKS):
    table = a.engine.completions(i) - (EAGER.root.initial if i == rules.ROOT else 0.0)
    assert np.any(table != 0) == (fuel or i != rules.REFUEL)
  # Greedy evaluation too.
  ga = a.run_stepwise(env, 20, learn=False)
  np.testing.assert_array_equal(ga, b.evaluate(20, "analytic"))
  _assert_same_agents(a, b)


def test_maxq_through_dm_control_matches_the_compiled_loop():
  a, b = _eager_agent(1), _eager_agent(1)
  ra = a.train_stepwise(suite.load("taxi", "fuel", {"random": 0}), 40)
  np.testing.assert_array_equal(ra, b.train(40, "analytic"))
  _assert_same_agents(a, b)


@pytest.mark.parametrize("section,key,value,message", [
    ("root", "alpha", 0.0, "allowed: > 0 and <= 1"), ("carry", "alpha", 1.5, "<= 1"),
    ("navigate", "epsilon", -0.1, "allowed: >= 0 and <= 1"),
    ("root", "epsilon_episodes", -1, "allowed: >= 0"), ("root", "initial", float("nan"), "finite")])
def test_bad_settings_are_refused(section, key, value, message):
  with pytest.raises(ValueError, match=f"{key} = .*{message}"):
    updated(mq.Config(), **{section: {key: value}})



def test_the_rules_compiled_first_are_those_train_calls(tmp_path):
  """`train`'s rules are compiled leaves first (`learners.jit.compile_first`), for the
  types `train` calls them with: with an empty numba cache each compiles once."""
  compile_order.assert_each_compiles_once(tmp_path, """
from hpg_mj.agents import taxi_maxq
from hpg_mj.hierarchy import maxq
agent = maxq.MAXQEngine(taxi_maxq.Config(), seed=0)
agent.run(20)
listed = agent._rules_bottom_up(*agent._train_scratch())
""")
