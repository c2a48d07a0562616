"""The route past the paper's (hpg_mj.agents.ship_beyond): the root's targets and
state, the aim subtask's state as an isometry, its outcome, J, and the refusals."""
import dataclasses
import math

import numpy as np
import pytest

from hpg_mj import agents
from hpg_mj.agents import ship_beyond as sb
from hpg_mj.hierarchy import ship_rules as route
from hpg_mj.worlds import ship_core as core

T = route.SHIPPED_TARGETS


def test_the_gate_target_follows_the_ship_and_approach_points_are_fixed():
  assert route.N_TARGETS == 4
  at = lambda x, y: np.array([x, y, 0.0, 0.0])
  tgt = lambda target, state, side: route.target_of(target, state, side, T.inset_m, T.approach_m)
  assert tgt(0, at(100.0, 900.0), 1.0) == (352.0, 400.0)   # posts moved in 2 m
  assert tgt(0, at(401.5, 10.0), -1.0) == (401.5, 400.0)
  assert tgt(0, at(999.0, 400.0), 1.0) == (448.0, 400.0)
  assert tgt(1, at(0.0, 0.0), -1.0) == (300.0, 320.0)      # the call's side
  assert tgt(3, at(0.0, 0.0), 1.0) == (500.0, 480.0)
  assert route.side_of(400.0) == 1.0 and route.side_of(399.9) == -1.0


def test_root_tiles_cells_and_heading_sectors():
  # One tiling is the table: 50 m cells, 8 sectors centred on N, NE, ...: (x, y) =
  # (125, 980) is cell (2, 19).
  coder = sb.root_coder(sb.Root())
  assert coder.size == 20 * 20 * 8

  def tile(x, y, heading):
    return int(coder.active([x, y, heading])[0])
  assert tile(125.0, 980.0, 0.0) == (2 * 20 + 19) * 8 + 0
  assert tile(125.0, 980.0, 22.4) % 8 == 0
  assert tile(125.0, 980.0, 22.6) % 8 == 1
  assert tile(125.0, 980.0, -22.6) % 8 == 7
  assert tile(125.0, 980.0, -180.0) % 8 == 4
  assert tile(1000.0, 1000.0, 179.0) == (19 * 20 + 19) * 8 + 4
  # The shipped root: 16 tilings of 100 m cells and 90 degree sectors, one tile each;
  # a neighbour 10 m away shares most of them.
  coder = sb.root_coder(agents.build(agents.load_task("ship_hybrid_beyond"), seed=0).config.root)
  here, there = coder.active([420.0, 610.0, 30.0]), coder.active([430.0, 610.0, 30.0])
  assert len(set(here)) == 16 and 8 <= np.sum(here == there) < 16


def test_the_aim_state_is_an_isometry_of_the_dynamics():
  rs = np.random.default_rng(0)
  view, moved_view = np.empty(3), np.empty(3)
  for _ in range(20):
    state = np.array([*rs.uniform(100, 900, 2), rs.uniform(-180, 180), rs.uniform(-15, 15)])
    target = rs.uniform(100, 900, 2)
    # Turn the world by a quarter turn about the target and shift it: same view.
    d = state[:2] - target
    moved = np.array([target[0] + d[1] + 7.0, target[1] - d[0] - 3.0,
                      core.wrap_deg(state[2] + 90.0), state[3]])
    route.aim_view(state, target[0], target[1], view)
    route.aim_view(moved, target[0] + 7.0, target[1] - 3.0, moved_view)
    np.testing.assert_allclose(view, moved_view, atol=1e-9)
  route.aim_view(np.array([0.0, 0.0, 45.0, 2.0]), 300.0, 300.0, view)
  np.testing.assert_allclose(view, [0.0, 2.0, route.DISTANCE_CLIP], atol=1e-9)
  route.aim_view(np.array([0.0, 0.0, 0.0, -1.0]), 100.0, 0.0, view)     # target due east
  np.testing.assert_allclose(view, [-90.0, -1.0, 100.0], atol=1e-9)
  route.aim_view(np.array([0.0, 0.0, 0.0, -1.0]), 100.0, 0.0, view, True)   # the sqrt scale
  np.testing.assert_allclose(view, [-180.0 * math.sqrt(0.5), -1.0, 100.0], atol=1e-9)
  route.aim_view(np.array([0.0, 0.0, 45.0, 0.0]), 0.0, 100.0, view, True)   # 45 deg off: 90
  np.testing.assert_allclose(view[0], 90.0, atol=1e-9)


def test_large_errors_on_the_negative_side_are_reflected():
  view = np.empty(3)
  reflect_at = route.error_coordinate(45.0, "sqrt")
  assert reflect_at == pytest.approx(90.0)                 # 180 sqrt(45 / 180)
  # Target due north; heading -90 (error -90, coordinate -127.3): reflected.
  side = route.aim_view(np.array([0.0, 0.0, -90.0, 4.0]), 0.0, 100.0, view, True, reflect_at)
  assert side == -1.0
  np.testing.assert_allclose(view, [180.0 * math.sqrt(0.5), -4.0, 100.0], atol=1e-9)
  # Error -30 (coordinate -73.5), +90 and +170: as they are.
  for heading in (-30.0, 90.0, 170.0):
    plain = np.empty(3)
    route.aim_view(np.array([0.0, 0.0, heading, 4.0]), 0.0, 100.0, plain, True)
    assert route.aim_view(np.array([0.0, 0.0, heading, 4.0]), 0.0, 100.0, view, True,
                       reflect_at) == 1.0
    np.testing.assert_allclose(view, plain, atol=1e-12)
  # The mirror image of a state in the world (x about the target's line, heading and
  # turning rate negated) has the same view beyond the fold, on the other side.
  rs = np.random.default_rng(1)
  mirrored = np.empty(3)
  for _ in range(50):
    state = np.array([*rs.uniform(100, 900, 2), rs.uniform(-180, 180), rs.uniform(-15, 15)])
    tx, ty = rs.uniform(100, 900, 2)
    image = np.array([2.0 * tx - state[0], state[1], -state[2], -state[3]])
    a = route.aim_view(state, tx, ty, view, True, reflect_at)
    b = route.aim_view(image, tx, ty, mirrored, True, reflect_at)
    if abs(view[0]) < reflect_at - 1e-6 or abs(mirrored[0]) < reflect_at - 1e-6:
      continue                                              # near e = 0: no fold
    assert a == -b
    np.testing.assert_allclose(view, mirrored, atol=1e-9)
  # The tiles then span [-90, 180] on the sqrt scale, not wrapping.
  low = dataclasses.replace(sb.Config().low_level, reflect_deg=45.0, tiles=(27, 6, 4))
  coder = sb.aim_coder(low)
  assert coder.low[0] == pytest.approx(-90.0) and coder.high[0] == 180.0
  assert not coder.wrap[0]


def test_aim_outcome_success_failure_and_shaping():
  samples = np.array([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0], [15.0, 0.0]])
  state = np.array([15.0, 0.0, 90.0, 0.0])                   # heading straight at the target
  samples += 100.0                                          # inside the field
  state = np.array([115.0, 100.0, 90.0, 0.0])               # heading straight at the target
  out = lambda samples, state, target, tx, ty, steps: route.aim_outcome(
      samples, state, target, tx, ty, steps, 600, T.radius_m, 1.0)
  event, g = out(samples, state, 1, 129.0, 100.0, 1)
  assert event == core.SUCCESS and g == 100.0               # 14 m <= radius 15, G = 0
  event, g = out(samples, state, 1, 131.0, 100.0, 1)
  assert event == core.NO_EVENT and g == 0.0
  event, g = out(samples, state, 1, 131.0, 100.0, 600)
  assert event == core.FAILURE and g == -100.0
  # The gate action ends only at the gate, off the field, or across the line beside it.
  event, _ = out(samples, state, 0, 129.0, 100.0, 1)
  assert event == core.NO_EVENT
  through = np.array([[400.0, 401.0], [400.0, 400.5], [400.0, 399.9], [400.0, 399.0]])
  event, g = out(through, np.array([400.0, 399.0, 180.0, 0.0]), 0, 400.0, 400.0, 1)
  assert event == core.SUCCESS and 99.0 <= g <= 100.0     # heading away: G near -1
  beside = np.array([[100.0, 401.0], [100.0, 400.5], [100.0, 399.9], [100.0, 399.0]])
  event, g = out(beside, np.array([100.0, 399.0, 180.0, 0.0]), 0, 352.0, 400.0, 1)
  assert event == core.FAILURE
  off = np.array([[2.0, 100.0], [1.0, 100.0], [0.5, 100.0], [-0.5, 100.0]])
  state = np.array([-0.5, 100.0, 0.0, 0.0])                 # 90 degrees off: G = exp(-9) - 1
  event, g = out(off, state, 1, 499.5, 100.0, 1)
  assert event == core.FAILURE and g == pytest.approx(math.exp(-9.0) - 1.0 - 100.0)


def test_the_routes_j_is_the_ship_agents_by_hand():
  record = np.zeros(4, dtype=[("steps", float), ("passed", float), ("return", float)])
  record["steps"] = [1, 3, 3, 5000]
  record["passed"] = [1, 1, 0, 0]
  record["return"] = [99.0, 97.0, -303.0, -5000.0]          # gate, gate, left, truncated
  j = agents.build(agents.load_task("ship_hybrid_beyond"), seed=0).j(record)
  np.testing.assert_allclose(j[:3], [0.0, -1.99, -1.99 - 100 * 0.99 ** 2], rtol=1e-12)
  assert j[3] == pytest.approx(-(1 - 0.99 ** 5000) / 0.01)


def test_the_route_learns_and_both_paths_run():
  # Seed 6: early learning is slow on some seeds (online gate passes in episodes
  # 5,000-6,000 over seeds 4-7: 0.67-0.93; by 12,000: 0.92-0.95).
  agent = agents.build(agents.load_task("ship_hybrid_beyond"), seed=6)
  first = agent.train(3000)
  agent.train(3000)
  last = agent.train(3000)
  passed = lambda r: r["steps"][r["passed"] > 0]
  assert last["passed"].mean() > 0.9 > first["passed"][:300].mean()
  assert passed(last).mean() < 0.6 * passed(first[:300]).mean()   # much shorter routes
  greedy = agent.evaluate(50)
  assert greedy["passed"].mean() >= 0.8
  stepwise = agent.run_stepwise(agent.make_env("gymnasium"), 3, learn=False)
  assert len(stepwise) == 3 and stepwise["calls"].min() >= 1


def test_the_learned_width_runs_on_both_paths_and_bad_widths_are_refused():
  c = sb.Config()
  agent = sb.ShipBeyond(dataclasses.replace(
      c, low_level=dataclasses.replace(c.low_level, width_alpha=0.003)), seed=0)
  assert len(agent.train(5)) == 5
  assert len(agent.run_stepwise(agent.make_env("gymnasium"), 1)) == 1
  assert "aim.log_sigma" in agent.parameters()
  with pytest.raises(ValueError, match=r"sigma_low = 2.0, sigma_high = 4.0: need"):
    sb.ShipBeyond(dataclasses.replace(
        c, low_level=dataclasses.replace(c.low_level, sigma_low=2.0, sigma_high=4.0)))


def test_greedy_episodes_agree_on_both_paths():
  agent = agents.build(agents.load_task("ship_hybrid_beyond"), seed=6)
  agent.train(2000)
  env = agent.make_env("gymnasium")
  rs = np.random.default_rng(3)
  for _ in range(5):
    start = np.array([*rs.uniform(50, 950, 2), rs.uniform(-180, 180), rs.uniform(-15, 15)])
    # Both from the same generator state: a greedy root breaks ties at random.
    before = agent.rng_state.copy()
    fused = agent.as_record(agent.compiled(1, False, False, start=start))
    agent.rng_state[:] = before
    stepwise = agent.run_stepwise(env, 1, learn=False, start=start)
    for field in ("passed", "steps", "calls", "return"):
      assert fused[field][0] == stepwise[field][0], field


def test_the_route_script_diagnostics_run():
  # scripts/beyond_route.py's --helmsman on a briefly trained agent:
  # they use the agent's rules directly, so they break when those change.
  import importlib.util
  import pathlib
  path = pathlib.Path(__file__).resolve().parents[2] / "scripts" / "beyond_route.py"
  spec = importlib.util.spec_from_file_location("beyond_route", path)
  script = importlib.util.module_from_spec(spec)
  spec.loader.exec_module(script)
  agent = agents.build(agents.load_task("ship_hybrid_beyond"), seed=6)
  agent.train(300)
  fixed = script.beyond.route_starts(n=5)
  record = agent.as_record(np.concatenate([agent.compiled(1, False, False, start=s)
                                           for s in fixed]))
  line = script.helmsman_report(agent, fixed, record)
  assert line.startswith("helmsman gate ") and "nan" not in line.split(";")[0], line
