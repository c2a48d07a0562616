"""On the task ladder the open machine's two paths are one algorithm: fused with a
task's compiled world (`Program.run_world`) and step by step through its Gymnasium
environment, a fixed seed gives the same rows, parameters and generator, so the
fused loop's world steps and observes as the environment does (the goal's
dictionary flattened) and both draw the episode's start alike."""
import gymnasium
import numpy as np

import hpg_mj  # noqa: F401
from hpg_mj.hierarchy import ladder
from hpg_mj.learners import rng
from hpg_mj.worlds import ship_goal_core


def test_the_fused_world_observes_as_the_environment():
  """The goal's world, stepped by its compiled functions, writes the Gymnasium
  dictionary flattened (observation, achieved_goal, desired_goal), to the bit."""
  world = ladder.world("ship_goal", "hard")
  start = world.draw(rng.make_state(7))
  env = gymnasium.make("hpg_mj/ShipGoal-v0", level="hard", backend="analytic").unwrapped
  obs, _ = env.reset(options=world.options(start))
  state, mine, samples = world.new_state(), np.zeros(world.obs_size), np.zeros((4, 2))
  world.reset(world.params, state, start, mine)
  np.testing.assert_array_equal(mine, ship_goal_core.flatten(obs))
  assert list(obs) == list(ship_goal_core.OBSERVATION_KEYS)
  for k in range(1, 40):
    r = 15.0 * np.sin(0.3 * k)
    obs, reward, terminated, truncated, info = env.step(np.array([r]))
    event, got, ended, cut = world.step(world.params, state, r, samples, mine, k)
    np.testing.assert_array_equal(mine, ship_goal_core.flatten(obs))
    np.testing.assert_array_equal(samples, info["positions"])
    assert (got, ended, cut) == (reward, terminated, truncated)



def test_the_gate_frame_is_an_isometry_of_the_ship():
  """Sailing and then mapping into a gate's frame equals mapping and then sailing
  (SPEC section 3's demand of a frame), and the steering task's gate is its own frame."""
  from hpg_mj.hierarchy.kinds import gate_frame
  from hpg_mj.worlds import ship_core as core
  gate = (612.0, 233.0, np.sin(np.radians(-131.0)), np.cos(np.radians(-131.0)))
  ship = np.array([480.0, 310.0, 37.0, -4.0])
  framed, mapped = np.zeros(4), np.zeros(4)
  gate_frame.framed_ship(ship, *gate, framed)
  samples = np.zeros((4, 2))
  for k in range(200):
    r = 15.0 * np.sin(0.05 * k)
    core.euler_control(ship, r, samples)
    core.euler_control(framed, r, samples)
    gate_frame.framed_ship(ship, *gate, mapped)
    np.testing.assert_allclose(mapped[:2], framed[:2], atol=1e-9)
    assert abs(core.wrap_deg(mapped[2] - framed[2])) < 1e-9 and mapped[3] == framed[3]
  gate_frame.framed_ship(ship, 400.0, 400.0, 0.0, 1.0, mapped)
  np.testing.assert_array_equal(mapped, ship)
