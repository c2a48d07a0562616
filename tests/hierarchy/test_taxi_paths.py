"""The taxi hierarchy on the task-graph API and its compiled loop are one algorithm;
so are flat Q-learning's two paths."""
import dataclasses

import gymnasium
import numpy as np
import pytest

import hpg_mj  # noqa: F401
from hpg_mj import suite
from hpg_mj.agents import taxi_flat_q, taxi_hpg


def _eager_hpg(seed, fuel=True):
  """HPG where every level learns from the first episode, so every table is compared."""
  c = taxi_hpg.Config()
  config = dataclasses.replace(
      c, environment=dataclasses.replace(c.environment, fuel=fuel),
      root=dataclasses.replace(c.root, delay=0, start_fraction=0.5, ramp=100),
      carry=dataclasses.replace(c.carry, ramp=100),
      navigate=dataclasses.replace(c.navigate, ramp=100))
  return taxi_hpg.TaxiHPG(config, seed=seed)


def _same(a, b):
  for name, value in a.state().items():
    np.testing.assert_array_equal(value, b.state()[name])
  assert a.episodes == b.episodes


@pytest.mark.parametrize("fuel,env_id", [(True, "hpg_mj/TaxiFuel-v0"), (False, "hpg_mj/Taxi-v0")])
def test_stepwise_and_compiled_hpg_agree_bit_for_bit(fuel, env_id):
  a, b = _eager_hpg(4, fuel), _eager_hpg(4, fuel)
  ra = a.train_stepwise(gymnasium.make(env_id), 300)
  rb = b.train(300, "analytic")
  for field in ("return", "steps", "outcome"):
    np.testing.assert_array_equal(ra[field], rb[field])
  _same(a, b)
  tables = a.policy_tables()
  # Get, Put and Navigate always learn; Root only where it has a real choice (with fuel).
  assert all(np.any(tables[i] != 0) for i in (1, 2, 4))
  assert np.any(tables[0] != 0) == fuel
  # So do their baselines, the same on both paths.
  assert all(np.any(a.baselines()[i] != 0) for i in (0, 1, 2, 4))


def test_hpg_through_dm_control_matches_the_compiled_loop():
  a, b = _eager_hpg(1), _eager_hpg(1)
  ra = a.train_stepwise(suite.load("taxi", "fuel", {"random": 0}), 40)
  rb = b.train(40, "analytic")
  for field in ("return", "steps", "outcome"):
    np.testing.assert_array_equal(ra[field], rb[field])
  _same(a, b)


def test_flat_q_paths_agree_bit_for_bit():
  config = dataclasses.replace(taxi_flat_q.Config(),
                               policy=taxi_flat_q.Policy(epsilon_episodes=300))
  a, b = taxi_flat_q.TaxiFlatQ(config, seed=3), taxi_flat_q.TaxiFlatQ(config, seed=3)
  ra = a.train_stepwise(gymnasium.make("hpg_mj/TaxiFuel-v0"), 400)
  rb = b.train(400, "analytic")
  np.testing.assert_array_equal(ra, rb)
  _same(a, b)
  assert ra["steps"].sum() > 2000
