"""The harbour (hpg_mj.worlds.ship_harbour_core, ship_harbour): each level's obstacles in
the rule and in the MJCF alike, the rule that ends an episode on touching one, the
rays cast in closed form against MuJoCo's rangefinders, and the starts off the
obstacles."""
import math

import numpy as np
import pytest

from hpg_mj import cli

from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_harbour
from hpg_mj.worlds import ship_harbour_core as harbour_core
from hpg_mj.worlds import ship_model
from hpg_mj.worlds import ship_task

LEVELS = list(harbour_core.LEVELS)


def _sail(level, state, rates):
  """(event, reward) of each control step of the analytic ship sailing `rates`."""
  one = harbour_core.OneShip(level, 5000)
  state, samples, out = np.array(state, dtype=np.float64), np.empty((4, 2)), []
  for steps, r in enumerate(rates, 1):
    core.euler_control(state, r, samples)
    event, reward, terminated, _ = one(samples, steps)
    out.append((event, reward))
    if terminated:
      break
  return out


@pytest.fixture(scope="module")
def physics():
  return ship_harbour.Physics.from_xml_string(*ship_harbour.get_model_and_assets())


def test_the_mjcf_obstacles_are_the_rules_and_only_the_levels_show(physics):
  model = physics.model.ptr
  for level in LEVELS:
    physics.place_obstacles(level)
    islands, piers = harbour_core.level_shapes(level)
    island_ids, pier_ids = ship_harbour.obstacle_geoms(model, level)
    assert min(island_ids + pier_ids, default=0) >= 0
    for i, (x, y, radius) in zip(island_ids, islands):
      np.testing.assert_array_equal(model.geom_pos[i], [x, y, 10.0])
      assert model.geom_size[i][0] == radius and model.geom_type[i] == 5     # cylinder
    for i, (cx, cy, ux, uy, half_length, half_width) in zip(pier_ids, piers):
      np.testing.assert_array_equal(model.geom_pos[i], [cx, cy, 10.0])
      np.testing.assert_array_equal(model.geom_size[i][:2], [half_length, half_width])
      frame = np.empty(9)
      import mujoco
      mujoco.mju_quat2Mat(frame, model.geom_quat[i])
      np.testing.assert_allclose(frame.reshape(3, 3)[:2, 0], [ux, uy], atol=1e-15)
    others = [i for other in LEVELS if other != level
              for i in sum(ship_harbour.obstacle_geoms(model, other), [])]
    assert all(model.geom_pos[i][2] < -30.0 for i in others)
  # The starts are drawn again on an obstacle; none lies on one.
  rules = ship_task.ShipRules("steer")
  rng = np.random.default_rng(0)
  islands, piers = harbour_core.level_shapes("hard")
  starts = np.array([harbour_core.sample_start(rules, rng, islands, piers) for _ in range(400)])
  assert not any(harbour_core.inside(x, y, islands, piers) for x, y in starts[:, :2])
  np.testing.assert_array_equal(harbour_core.sample_start(rules, np.random.default_rng(0),
                                                          islands, piers), starts[0])


@pytest.mark.parametrize("level", LEVELS)
def test_the_rays_in_closed_form_are_mujocos_rangefinders(physics, level):
  # Poses all over the field (some inside an obstacle, where both read the way out):
  # the analytic ranges of the MuJoCo ship's state equal its rangefinders within 1e-9 m
  # (measured: under 1e-12), and some rays see something, some nothing.
  physics.place_obstacles(level)
  one = harbour_core.OneShip(level, 5000)
  rng = np.random.default_rng(1)
  seen = []
  for x, y, theta in zip(rng.uniform(0, 1000, 300), rng.uniform(0, 1000, 300),
                         rng.uniform(-180, 180, 300)):
    physics.set_ship_state([x, y, theta, 0.0])
    state = physics.ship_state()
    mujoco_ranges = one.observe(state, physics.rangefinder_readings())[4:]
    np.testing.assert_allclose(mujoco_ranges, one.observe(state)[4:], atol=1e-9, rtol=0)
    seen.append(mujoco_ranges)
  seen = np.array(seen)
  assert (seen == harbour_core.MAX_RANGE_M).mean() > 0.3 and (seen < 100.0).sum() > 50


def test_ranges_in_closed_form():
  islands, piers = harbour_core.level_shapes("hard")
  cells = harbour_core.level_cells("hard")
  out = np.empty(harbour_core.RAYS)
  # In the hard level's northern pocket, heading north 10 m short of its wall's face
  # (y = 444): ahead 10 m, the rays at 30 and 60 degrees 10 / cos 30 and 10 / cos 60;
  # to port the wall that closes the pocket (its face at x = 276), to starboard the
  # pocket's open end.
  harbour_core.ranges_into(np.array([400.0, 434.0, 0.0, 0.0]), islands, piers, cells, out, 0)
  slant = 10.0 / math.cos(math.radians(30.0))
  np.testing.assert_allclose(out, [124.0, 20.0, slant, 10.0, slant, 20.0, 150.0],
                             rtol=1e-12)
  # Heading east 50 m north of the medium breakwater's centre line: the starboard beam
  # reads the distance to its face (50 - 6 m).
  medium = harbour_core.level_shapes("medium")
  harbour_core.ranges_into(np.array([250.0, 450.0, 90.0, 0.0]), *medium,
                           harbour_core.level_cells("medium"), out, 0)
  assert out[6] == 44.0 and out[0] == 150.0
  readings = np.array([-1.0, 3.5, 150.0, 151.0, 0.0, 20.0, -1.0])
  harbour_core.seen_ranges(readings, out, 0)
  np.testing.assert_array_equal(out, [150.0, 3.5, 150.0, 150.0, 0.0, 20.0, 150.0])


@pytest.mark.parametrize("level", LEVELS)
def test_the_rays_skip_no_obstacle_they_could_see(level):
  # Poses all over the field and close along the obstacles (where an obstacle lies just
  # behind the ship or just off a ray's line): `ranges_into`, which skips the obstacles
  # behind the ship and, for each ray, the rectangles wholly to one side of its line,
  # reads what casting every ray at every obstacle (`ray_distance`) reads.
  islands, piers = harbour_core.level_shapes(level)
  cells = harbour_core.level_cells(level)
  rng = np.random.default_rng(3)
  corners = [(p[0] + sx * p[4] * p[2] + sy * p[5] * p[3],
              p[1] + sx * p[4] * p[3] - sy * p[5] * p[2])
             for p in piers for sx in (-1, 1) for sy in (-1, 1)]
  near = [(c[0] + rng.normal(0, 8), c[1] + rng.normal(0, 8))
          for c in corners + [tuple(i[:2] + i[2] * np.array([1.0, 0.0])) for i in islands]
          for _ in range(40)]
  poses = list(zip(rng.uniform(0, 1000, 2000), rng.uniform(0, 1000, 2000))) + near
  out, seen = np.empty(harbour_core.RAYS), 0
  for (x, y), theta in zip(poses, rng.uniform(-180, 180, len(poses))):
    harbour_core.ranges_into(np.array([x, y, theta, 0.0]), islands, piers, cells, out, 0)
    rad = math.radians(theta)
    every = [harbour_core.ray_distance(
        x, y, math.sin(rad) * math.cos(math.radians(b)) + math.cos(rad) * math.sin(math.radians(b)),
        math.cos(rad) * math.cos(math.radians(b)) - math.sin(rad) * math.sin(math.radians(b)),
        islands, piers, harbour_core.MAX_RANGE_M) for b in harbour_core.BEARINGS_DEG]
    np.testing.assert_allclose(out, every, atol=1e-9, rtol=0)
    seen += (out < harbour_core.MAX_RANGE_M).sum()
  assert seen > 1000


def test_touching_an_obstacle_ends_the_episode_with_the_out_of_bounds_penalty():
  # Heading north 12 m short of the easy island (400, 620) r 60 (its edge at y = 560):
  # the track meets it in the seventh step (12 / 1.8 = 6.7); its boundary counts.
  out = _sail("easy", [400.0, 548.0, 0.0, 0.0], [0.0] * 20)
  assert out[-1] == (harbour_core.AGROUND, -101.0) and len(out) == 7
  assert harbour_core.EVENT_NAMES[harbour_core.AGROUND] == "obstacle"
  assert harbour_core.segment_touches(400.0, 550.0, 400.0, 560.0,
                                      *harbour_core.level_shapes("easy"), 0.0)
  # A pier's side and end: sailing along its face 0.5 m off, nothing; across it, aground.
  hard = harbour_core.level_shapes("hard")
  assert not harbour_core.segment_touches(100.0, 406.5, 200.0, 406.5, *hard, 0.0)
  assert harbour_core.segment_touches(100.0, 406.5, 100.0, 405.5, *hard, 0.0)
  assert harbour_core.segment_touches(215.0, 562.0, 225.0, 558.0, *hard, 0.0)
  # The gate, the steering task's pass from 9.85 m at step 6; off the field as there.
  assert _sail("hard", [400.0, 390.15, 0.0, 0.0], [0.0] * 10)[-1] == (core.SUCCESS, 99.0)
  assert _sail("hard", [20.0, 998.5, 0.0, 0.0], [0.0] * 5) == [(core.FAILURE, -101.0)]
  custom = harbour_core.OneShip("easy", 5000, out_of_bounds_reward=-300.0)
  state, samples = np.array([400.0, 559.0, 0.0, 0.0]), np.empty((4, 2))
  core.euler_control(state, 0.0, samples)
  assert custom(samples, 1) == (harbour_core.AGROUND, -301.0, True, False)


@pytest.mark.parametrize("level", LEVELS)
def test_the_cells_prune_no_obstacle_a_step_can_touch(level):
  # Steps from everywhere, many near an obstacle: the rule, which tests only the
  # obstacles its 25 m cell lists, runs aground exactly where testing every obstacle does.
  islands, piers = harbour_core.level_shapes(level)
  cells = harbour_core.level_cells(level)
  rng = np.random.default_rng(2)
  samples, aground = np.empty((4, 2)), 0
  for x, y, theta, rate in zip(rng.uniform(-1, 1001, 4000), rng.uniform(-1, 1001, 4000),
                               rng.uniform(-180, 180, 4000), rng.uniform(-15, 15, 4000)):
    core.euler_control(np.array([x, y, theta, rate]), 0.0, samples)
    event, _ = harbour_core.harbour_event(samples, islands, piers, cells)
    touched = any(harbour_core.segment_touches(*samples[k - 1], *samples[k], islands, piers, 0.0)
                  for k in range(1, 4))
    assert (event == harbour_core.AGROUND) == (touched and event != core.SUCCESS
                                               and event != core.FAILURE)
    aground += event == harbour_core.AGROUND
  assert aground > 30


def test_bad_levels_and_starts_are_one_line_errors():
  with pytest.raises(ValueError, match=r"^ship harbour: unknown level 'windy'; allowed levels: "
                                       r"\['easy', 'medium', 'hard'\]$"):
    harbour_core.level_obstacles("windy")
  rules = ship_task.ShipRules("steer")
  with pytest.raises(ValueError, match=r"^h: start position \(400.0, 620.0\) lies on an "
                                       r"obstacle; allowed: any position on the field off "
                                       r"the harbour's islands and piers$"):
    harbour_core.check_start(rules, [400.0, 620.0, 0.0, 0.0],
                             *harbour_core.level_shapes("easy"), "h")


def test_the_mujoco_model_is_the_steering_ship_bit_for_bit(physics):
  steer = ship_model.ShipPhysics.from_xml_string(*ship_model.get_model_and_assets())
  for p in (physics, steer):
    p.set_ship_state([300.0, 200.0, 40.0, -5.0])
  for r in np.random.default_rng(4).uniform(-15, 15, 30):
    for p in (physics, steer):
      p.set_turn_command(r)
      p.step(6)
    np.testing.assert_array_equal(physics.stepped_state, steer.stepped_state)
    # The rays cast in the step's compiled call are those cast afresh where it ended.
    cast = physics.rangefinder_readings()
    physics._readings = None
    np.testing.assert_array_equal(physics.rangefinder_readings(), cast)


def test_cli_verify_harbour(capsys):
  # The blind helmsman's episodes on both ships (`hpg-mj verify harbour --starts 20`:
  # 60 of 60 alike, the ships at most 1.08 m apart, the rays within 2e-11 m; a ship that
  # grazes an obstacle may touch it a step later on the other backend).
  assert cli.main(["verify", "harbour", "--starts", "1"]) == 0
  out = capsys.readouterr().out.splitlines()
  assert [line.split()[0] for line in out[1:4]] == ["easy", "medium", "hard"]
  assert out[-1].endswith("met") and "NOT" not in out[-1]
