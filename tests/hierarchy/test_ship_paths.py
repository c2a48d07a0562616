"""The two training paths of the ship hierarchy are one algorithm."""
import gymnasium
import numpy as np

import hpg_mj  # noqa: F401
from hpg_mj import suite
from hpg_mj.hierarchy import executor
from hpg_mj.hierarchy import ship as ship_hierarchy
from hpg_mj.hierarchy import ship_compiled


def test_stepwise_and_compiled_give_identical_parameters():
  stepwise = ship_hierarchy.ShipHybrid(seed=5)
  compiled = ship_hierarchy.ShipHybrid(seed=5)
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic").unwrapped
  a = stepwise.train_stepwise(executor.GymAdapter(env), 200)
  b = compiled.train_compiled(200)
  np.testing.assert_array_equal(a, b)
  assert a[:, ship_compiled.STEPS].sum() > 20000        # a real amount of learning
  pa, pb = stepwise.parameters(), compiled.parameters()
  for name in pa:
    np.testing.assert_array_equal(pa[name], pb[name])
    assert np.any(pa[name] != 0.0)
  np.testing.assert_array_equal(stepwise.rng_state, compiled.rng_state)


def test_stepwise_through_dm_control_on_the_mujoco_ship():
  agent = ship_hierarchy.ShipHybrid(seed=1)
  env = suite.load("ship", "steer", {"random": 0})
  record = agent.train_stepwise(executor.DmControlAdapter(env), 3)
  assert record[:, ship_compiled.STEPS].min() >= 1
  assert record[:, ship_compiled.CALLS].min() >= 1
  # A fixed start is honoured and the gate is recognised through dm_control.
  record = agent.train_stepwise(executor.DmControlAdapter(env), 1, learn=False,
                                start=[400.0, 380.0, 0.0, 0.0])
  assert record[0, ship_compiled.PASSED] == 1.0
