"""On the task ladder the open machine's two paths are one algorithm: fused with a
task's compiled world (`Program.run_world`) and step by step through its Gymnasium
environment, a fixed seed gives the same rows, parameters and generator, so the
fused loop's world steps and observes as the environment does (the goal's
dictionary flattened) and both draw the episode's start alike."""
import dataclasses

import gymnasium
import numpy as np
import pytest

import hpg_mj  # noqa: F401
from hpg_mj.agents import ship_ladder_flat_pg
from hpg_mj.agents import ship_ladder_hybrid
from hpg_mj.agents import ship_ladder_option_critic
from hpg_mj.agents import ship_ladder_waypoints
from hpg_mj.agents.base import GREEDY_SEED
from hpg_mj.hierarchy import ladder
from hpg_mj.learners import rng
from hpg_mj.worlds import ship_goal_core
from hpg_mj.worlds import ship_ladder


def _agent(cls, task, level, seed):
  config = cls.Config()
  environment = dataclasses.replace(config.environment, world=task, level=level,
                                    out_of_bounds_reward=-300.0)
  return cls(dataclasses.replace(config, environment=environment), seed=seed)


# Levels where an untrained ship meets the task's own events (the current's strongest
# water, the regatta's closest gates, the harbour's most obstacles).
CASES = [(ship_ladder_hybrid.ShipLadderHybrid, "ship_current", "hard", 30),
         (ship_ladder_hybrid.ShipLadderHybrid, "ship_goal", "medium", 30),
         (ship_ladder_hybrid.ShipLadderHybrid, "ship_regatta", "hard", 30),
         (ship_ladder_hybrid.ShipLadderHybrid, "ship_harbour", "hard", 30),
         (ship_ladder_flat_pg.ShipLadderFlatPG, "ship_current", "medium", 20),
         (ship_ladder_flat_pg.ShipLadderFlatPG, "ship_goal", "hard", 20),
         (ship_ladder_option_critic.ShipLadderOptionCritic, "ship_current", "medium", 10),
         (ship_ladder_option_critic.ShipLadderOptionCritic, "ship_goal", "hard", 10),
         (ship_ladder_waypoints.ShipLadderWaypoints, "ship_regatta", "hard", 30),
         (ship_ladder_waypoints.ShipLadderWaypoints, "ship_goal", "hard", 20),
         (ship_ladder_waypoints.ShipLadderWaypoints, "ship_current", "hard", 20),
         (ship_ladder_waypoints.ShipLadderWaypoints, "ship_harbour", "easy", 20)]


@pytest.mark.parametrize("cls,task,level,episodes", CASES,
                         ids=[f"{c.name}-{t}" for c, t, _, _ in CASES])
def test_fused_and_stepwise_paths_give_identical_rows(cls, task, level, episodes):
  fused, stepwise = _agent(cls, task, level, 4), _agent(cls, task, level, 4)
  a = fused.train(episodes, "analytic")
  env = gymnasium.make(ship_ladder.ENV_IDS[task], level=level, backend="analytic",
                       out_of_bounds_reward=-300.0)
  b = stepwise.train_stepwise(env, episodes)
  np.testing.assert_array_equal(a, b)
  assert a["steps"].sum() > 2000 and len(np.unique(a["steps"])) > episodes // 2
  pa, pb = fused.parameters(), stepwise.parameters()
  assert sorted(pa) == sorted(pb)
  for name in pa:
    np.testing.assert_array_equal(pa[name], pb[name], err_msg=name)
    if name.endswith((".theta", ".vartheta")):
      assert np.any(pa[name] != 0.0), name           # it learned something
  if "calls" in a.dtype.names:                       # (the option-critic's options end inside)
    assert a["calls"].sum() > 2 * episodes
  np.testing.assert_array_equal(fused.rng_state, stepwise.rng_state)
  # Greedy from the reports' fixed starts (the benchmark's), the same too.
  starts, rows = fused.fixed_starts(3), []
  for i in range(3):
    stepwise.set_seed(GREEDY_SEED + i)
    rows.append(stepwise.run_stepwise(env, 1, learn=False, start=starts[i]))
  np.testing.assert_array_equal(fused.evaluate_fixed(3), np.concatenate(rows))


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
    if terminated or truncated:           # past its end the environment only warns
      break


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
