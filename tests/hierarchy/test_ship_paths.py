"""The two training paths of the ship hierarchy are one algorithm."""
import dataclasses

import gymnasium
import numpy as np
import pytest

import hpg_mj  # noqa: F401
from hpg_mj import suite
from hpg_mj.agents.ship_hybrid import ShipHybrid


@pytest.mark.parametrize("baseline", [0.0, 0.1])
def test_stepwise_and_compiled_give_identical_parameters(baseline):
  config = ShipHybrid.Config()
  config = dataclasses.replace(config, low_level=dataclasses.replace(config.low_level,
                                                                     baseline=baseline))
  stepwise = ShipHybrid(config, seed=5)
  compiled = ShipHybrid(config, seed=5)
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic")
  a = stepwise.train_stepwise(env, 200)
  b = compiled.train(200, "analytic")
  np.testing.assert_array_equal(a, b)
  assert a["steps"].sum() > 20000        # a real amount of learning
  pa, pb = stepwise.parameters(), compiled.parameters()
  assert sorted(pa) == ["diagonal.theta", "diagonal.values", "root.q", "straight.theta",
                        "straight.values"]
  for name in pa:
    np.testing.assert_array_equal(pa[name], pb[name])
    assert np.any(pa[name] != 0.0) == (not name.endswith(".values") or baseline != 0.0), name
  np.testing.assert_array_equal(stepwise.rng_state, compiled.rng_state)
  assert stepwise.episodes == compiled.episodes == 200
  for a_values, b_values in zip(stepwise.baselines(), compiled.baselines()):
    np.testing.assert_array_equal(a_values, b_values)
    assert np.any(a_values != 0.0) == (baseline != 0.0)


def test_stepwise_through_dm_control_on_the_mujoco_ship():
  agent = ShipHybrid(seed=1)
  env = suite.load("ship", "steer", {"random": 0})
  record = agent.train_stepwise(env, 3)
  assert record["steps"].min() >= 1
  assert record["calls"].min() >= 1
  # A fixed start is honoured and the gate is recognised through dm_control.
  record = agent.run_stepwise(env, 1, learn=False, start=[400.0, 380.0, 0.0, 0.0])
  assert record["passed"][0] == 1.0


class _Spy(gymnasium.Wrapper):
  """A user's wrapper: counts the resets and pays double."""

  def __init__(self, env):
    super().__init__(env)
    self.resets = 0

  def reset(self, **kwargs):
    self.resets += 1
    return self.env.reset(**kwargs)

  def step(self, action):
    obs, reward, terminated, truncated, info = self.env.step(action)
    return obs, 2.0 * reward, terminated, truncated, info


def test_stepwise_keeps_a_users_wrapper_and_drops_only_gymnasiums_checks():
  """A newcomer's wrapper was silently bypassed (the agent stepped `env.unwrapped`):
  now only gymnasium.make's own checks are dropped, from the outside in."""
  from hpg_mj.hierarchy import executor
  made = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic")
  assert executor.adapter_for(made).env is made.unwrapped
  spy = _Spy(made)
  assert executor.adapter_for(spy).env is spy
  plain = ShipHybrid(seed=3).run_stepwise(made, 3, learn=False)
  doubled = ShipHybrid(seed=3).run_stepwise(spy, 3, learn=False)
  assert spy.resets == 3
  np.testing.assert_array_equal(doubled["return"], 2.0 * plain["return"])
