"""The flat ship baselines: both training paths are one algorithm."""
import gymnasium
import numpy as np
import pytest

import hpg_mj  # noqa: F401
from hpg_mj.baselines import ship_flat
from hpg_mj.hierarchy import executor


@pytest.mark.parametrize("make", [
    lambda: ship_flat.FlatPolicyGradient(seed=2),
    lambda: ship_flat.ActorCriticAgent(alpha_actor=1e-3, alpha_critic=0.01, seed=2),
])
def test_stepwise_and_compiled_agree_bit_for_bit(make):
  a, b = make(), make()
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic", max_steps=400).unwrapped
  a.max_steps = b.max_steps = 400
  ra = a.train_stepwise(executor.GymAdapter(env), 12)
  rb = b.train_compiled(12)
  np.testing.assert_array_equal(ra, rb)
  assert ra[:, ship_flat.STEPS].sum() > 1000
  np.testing.assert_array_equal(a.rng_state, b.rng_state)
  for x, y in ((a.learner, b.learner),):
    if hasattr(x, "trace"):
      np.testing.assert_array_equal(x.parameters(), y.parameters())
      assert np.any(x.parameters() != 0)
    else:
      np.testing.assert_array_equal(x.actor_w, y.actor_w)
      for key in x.critic:
        np.testing.assert_array_equal(x.critic[key], y.critic[key])
      assert np.any(x.actor_w != 0) and np.any(x.critic["w"] != 0)


def test_flat_sizes_are_the_papers():
  assert ship_flat.actor_coder().size == 648_000
  assert ship_flat.critic_coder().size == 1_215_000
