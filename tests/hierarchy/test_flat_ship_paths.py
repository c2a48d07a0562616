"""The flat ship baselines: both training paths are one algorithm."""
import dataclasses

import gymnasium
import numpy as np
import pytest

import hpg_mj  # noqa: F401
from hpg_mj.agents import ship_actor_critic, ship_flat_pg


def _short(module):
  """The agent's default configuration with 400-step episodes."""
  config = module.Config()
  return dataclasses.replace(config, environment=dataclasses.replace(config.environment,
                                                                     max_steps=400))


@pytest.mark.parametrize("make", [
    lambda: ship_flat_pg.ShipFlatPG(_short(ship_flat_pg), seed=2),
    lambda: ship_actor_critic.ShipActorCritic(dataclasses.replace(
        _short(ship_actor_critic), actor=ship_actor_critic.Actor(alpha=1e-3)), seed=2),
])
def test_stepwise_and_compiled_agree_bit_for_bit(make):
  a, b = make(), make()
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic", max_steps=400)
  ra = a.train_stepwise(env, 12)
  rb = b.train(12, "analytic")
  np.testing.assert_array_equal(ra, rb)
  assert ra["steps"].sum() > 1000
  for name, value in a.state().items():
    np.testing.assert_array_equal(value, b.state()[name])
  weights = [v for k, v in a.state().items() if k.endswith(("_w", "_theta", ".theta"))]
  assert weights and all(np.any(w != 0) for w in weights)


def test_flat_sizes_are_the_papers():
  assert ship_flat_pg.actor_coder().size == 648_000
  assert ship_actor_critic.critic_coder().size == 1_215_000
