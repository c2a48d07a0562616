"""The taxi hierarchy on the task-graph API and its compiled loop are one algorithm;
so are flat Q-learning's two paths."""
import gymnasium
import numpy as np
import pytest

import hpg_mj  # noqa: F401
from hpg_mj import suite
from hpg_mj.baselines import taxi_flat_q
from hpg_mj.hierarchy import executor
from hpg_mj.hierarchy import taxi as taxi_hierarchy
from hpg_mj.hierarchy import taxi_compiled as tc
from hpg_mj.worlds import taxi_core

# Every level learns from the first episode, so that every table is compared.
EAGER = tc.HPGConfig(delay_root=0, start_root=0.5, ramp_root=100, ramp_carry=100,
                     ramp_navigate=100)


@pytest.mark.parametrize("fuel,env_id", [(True, "hpg_mj/TaxiFuel-v0"), (False, "hpg_mj/Taxi-v0")])
def test_stepwise_and_compiled_hpg_agree_bit_for_bit(fuel, env_id):
  task = taxi_core.TaxiRules(fuel_enabled=fuel)
  a, b = tc.TaxiHPG(seed=4, config=EAGER, task=task), tc.TaxiHPG(seed=4, config=EAGER, task=task)
  env = gymnasium.make(env_id).unwrapped
  ra = taxi_hierarchy.TaxiHierarchy(a).train_stepwise(executor.GymAdapter(env), 300)
  rb = b.run(300)
  np.testing.assert_array_equal(ra[:, :3], rb[:, :3])
  for x, y in zip(a.policy_tables(), b.policy_tables()):
    np.testing.assert_array_equal(x, y)
  tables = a.policy_tables()
  # Get, Put and Navigate always learn; Root only where it has a real choice (with fuel).
  assert all(np.any(tables[i] != 0) for i in (1, 2, 4))
  assert np.any(tables[0] != 0) == fuel
  # So do their baselines (HPGConfig's default), the same on both paths.
  for x, y in zip(a.values, b.values):
    np.testing.assert_array_equal(x, y)
  assert all(np.any(a.values[i] != 0) for i in (0, 1, 2, 4))
  np.testing.assert_array_equal(a.rng_state, b.rng_state)


def test_hpg_through_dm_control_matches_the_compiled_loop():
  a, b = tc.TaxiHPG(seed=1, config=EAGER), tc.TaxiHPG(seed=1, config=EAGER)
  ra = taxi_hierarchy.TaxiHierarchy(a).train_stepwise(
      executor.DmControlAdapter(suite.load("taxi", "fuel", {"random": 0})), 40)
  rb = b.run(40)
  np.testing.assert_array_equal(ra[:, :3], rb[:, :3])
  for x, y in zip(a.policy_tables(), b.policy_tables()):
    np.testing.assert_array_equal(x, y)
  for x, y in zip(a.values, b.values):
    np.testing.assert_array_equal(x, y)


def test_flat_q_paths_agree_bit_for_bit():
  a = taxi_flat_q.FlatQ(seed=3, epsilon_episodes=300)
  b = taxi_flat_q.FlatQ(seed=3, epsilon_episodes=300)
  env = gymnasium.make("hpg_mj/TaxiFuel-v0").unwrapped
  ra = a.train_stepwise(executor.GymAdapter(env), 400)
  rb = b.train_compiled(400)
  np.testing.assert_array_equal(ra, rb)
  np.testing.assert_array_equal(a.learner.q, b.learner.q)
  assert ra[:, taxi_flat_q.STEPS].sum() > 2000
