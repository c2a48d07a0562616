"""The regatta (hpg_mj.worlds.ship_regatta_core, ship_regatta): the courses each level
lays out, the gates counted in order by the steering task's own crossing rule, what the
ship sees of them, and the MuJoCo ship round a course against the continuous one."""
import math

import numpy as np
import pytest

from hpg_mj import cli
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_model
from hpg_mj.worlds import ship_regatta
from hpg_mj.worlds import ship_regatta_core as regatta_core

# Three gates due north of each other, 200 m apart, passed northwards.
NORTH = np.array([[400.0, 400.0, 0.0], [400.0, 600.0, 0.0], [400.0, 800.0, 0.0]])


def _sail(course, state, rates, one=None):
  """(event, reward, gates passed) of each control step of a ship sailing `rates`."""
  one = one or regatta_core.OneShip(5000)
  one.set_course(course)
  state, samples, out = np.array(state, dtype=np.float64), np.empty((4, 2)), []
  for steps, r in enumerate(rates, 1):
    core.euler_control(state, r, samples)
    event, reward, terminated, _ = one(samples, steps)
    out.append((event, reward, one.next_gate))
    if terminated:
      break
  return out


@pytest.mark.parametrize("level", list(regatta_core.LEVELS))
def test_each_level_lays_its_courses_from_the_seed(level):
  gates, spacing, smallest, largest = regatta_core.LEVELS[level]
  rng = np.random.default_rng(0)
  courses = np.array([regatta_core.sample_course(rng, regatta_core.LEVELS[level])
                      for _ in range(300)])
  assert courses.shape == (300, gates, 3)
  legs = np.diff(courses[:, :, :2], axis=1)
  np.testing.assert_allclose(np.hypot(legs[..., 0], legs[..., 1]), spacing)
  # Each gate faces along the leg into it, turned from the gate before by the level's angle.
  np.testing.assert_allclose(np.degrees(np.arctan2(legs[..., 0], legs[..., 1])),
                             courses[:, 1:, 2], atol=1e-9)
  turns = np.abs(core.wrap_deg_array(np.diff(courses[:, :, 2], axis=1)))
  assert turns.min() >= smallest - 1e-9 and turns.max() <= largest + 1e-9
  assert turns.max() > largest - 5.0 and turns.min() < smallest + 5.0
  centres = courses[:, :, :2]
  assert centres.min() >= regatta_core.LOW and centres.max() <= regatta_core.HIGH
  apart = np.hypot(*(courses[:, :, None, :2] - courses[:, None, :, :2]).transpose(3, 0, 1, 2))
  assert apart[:, ~np.eye(gates, dtype=bool)].min() >= regatta_core.MIN_SEPARATION
  posts = np.array([regatta_core.posts_of(c) for c in courses[:20]])
  assert posts.min() >= 0.0 and posts.max() <= core.FIELD_SIZE
  again = regatta_core.sample_course(np.random.default_rng(0), regatta_core.LEVELS[level])
  np.testing.assert_array_equal(again, courses[0])


def test_the_gates_count_in_order_and_the_last_ends_the_episode():
  # 9.85 m south of the first gate heading north: its pass is the sixth step's (as
  # ship/steer's from 9.85 m), then a gate every 200 m / 1.8 m = 111.1 steps.
  out = _sail(NORTH, [400.0, 390.15, 0.0, 0.0], [0.0] * 300)
  events = [(k, e, rw) for k, (e, rw, _) in enumerate(out, 1) if e != core.NO_EVENT]
  assert events == [(6, regatta_core.GATE, 99.0), (117, regatta_core.GATE, 99.0),
                    (228, core.SUCCESS, 499.0)]
  assert all(rw == -1.0 for e, rw, _ in out if e == core.NO_EVENT) and len(out) == 228
  assert regatta_core.EVENT_NAMES[core.SUCCESS] == "finish"


def test_only_the_next_gate_counts_and_a_pass_is_the_steering_tasks():
  # The second gate sailed through before the first: nothing. Backwards (south) through
  # the first: a pass, as ship/steer's gate is passed either way.
  skipped = _sail(NORTH, [400.0, 590.15, 0.0, 0.0], [0.0] * 20)
  assert all(e == core.NO_EVENT for e, _, _ in skipped)
  backwards = _sail(NORTH, [400.0, 409.85, 180.0, 0.0], [0.0] * 10)
  assert backwards[5] == (regatta_core.GATE, 99.0, 1)
  # Every straight pass, at any offset and angle: the step the rule counts is the step
  # at which ship_core.steer_event, the steering task's rule, sees that gate crossed.
  rng = np.random.default_rng(1)
  posts = regatta_core.posts_of(NORTH)
  for _ in range(80):
    x, heading = rng.uniform(355.0, 445.0), rng.uniform(-70.0, 70.0)
    back = rng.uniform(5.0, 20.0)
    state = [x - back * math.sin(math.radians(heading)), 400.0 - back *
             math.cos(math.radians(heading)), heading, 0.0]
    passed = [k for k, (e, _, _) in enumerate(_sail(NORTH, state, [0.0] * 20)) if e]
    s, samples, steer = np.array(state), np.empty((4, 2)), []
    for k in range(20):
      core.euler_control(s, 0.0, samples)
      if core.steer_event(samples, posts[0], core.FIELD_SIZE)[0] == core.SUCCESS:
        steer.append(k)
    assert passed[:1] == steer[:1] and len(steer) == 1


def test_off_the_field_is_the_steering_tasks_penalty():
  out = _sail(NORTH, [500.0, 998.5, 0.0, 0.0], [0.0] * 5)
  assert out == [(core.FAILURE, -101.0, 0)]
  custom = regatta_core.OneShip(5000, gate_reward=10.0, finish_reward=20.0,
                                out_of_bounds_reward=-300.0)
  assert _sail(NORTH, [500.0, 998.5, 0.0, 0.0], [0.0], custom) == [(core.FAILURE, -301.0, 0)]


def test_the_ship_sees_the_next_two_gates_from_its_own_frame():
  one = regatta_core.OneShip(5000)
  one.set_course(NORTH)
  np.testing.assert_allclose(one.observe(np.array([400.0, 390.0, 0.0, 2.0])),
                             [400.0, 390.0, 0.0, 2.0, 10.0, 0.0, 0.0, 210.0, 0.0, 0.0, 3.0])
  # Heading east, 100 m west of the course: the gates ahead, on the port (left) side.
  seen = one.observe(np.array([300.0, 400.0, 90.0, 0.0]))
  np.testing.assert_allclose(seen[4:], [100.0, 0.0, -90.0, 100.0, -200.0, -90.0, 3.0],
                             atol=1e-12)
  state, samples = np.array([400.0, 790.15, 0.0, 0.0]), np.empty((4, 2))
  one.set_course(NORTH)
  one.next_gate = 2                                 # at the last gate: no gate after it
  seen = one.observe(state)
  np.testing.assert_allclose(seen[4:7], seen[7:10])
  assert seen[10] == 1.0
  for steps in range(1, 7):
    core.euler_control(state, 0.0, samples)
    event, *_ = one(samples, steps)
  assert event == core.SUCCESS and one.observe(state)[10] == 0.0


def test_bad_levels_and_courses_are_one_line_errors():
  with pytest.raises(ValueError, match=r"^ship regatta: unknown level 'windy'; allowed levels: "
                                       r"\['easy', 'medium', 'hard'\]$"):
    regatta_core.level_layout("windy")
  with pytest.raises(ValueError, match=r"^r: a course is 3 gates \[x, y, heading_deg\] "
                                       r"\(shape \(3, 3\)\), got shape \(2, 3\)$"):
    regatta_core.check_course(NORTH[:2], 3, "r")
  with pytest.raises(ValueError, match=r"^r gate 1: gate \[20.0, 500.0, 0.0\] puts its posts"):
    regatta_core.check_course([NORTH[0], [20.0, 500.0, 0.0], NORTH[2]], 3, "r")


def test_the_mujoco_model_is_the_steering_ship_with_a_course_drawn():
  # assets/ship_regatta.xml includes ship.xml: the same ship, bit for bit; its geoms
  # stand where the rule's posts are, as many as the hardest level's gates.
  regatta = ship_regatta.Physics.from_xml_string(*ship_regatta.get_model_and_assets())
  steer = ship_model.ShipPhysics.from_xml_string(*ship_model.get_model_and_assets())
  assert len(regatta._course_geoms) == regatta_core.MAX_GATES and steer._course_geoms == []
  course = regatta_core.sample_course(np.random.default_rng(3), regatta_core.LEVELS["medium"])
  regatta.place_course(regatta_core.posts_of(course), 2)
  model = regatta.model.ptr
  drawn = np.array([[model.geom_pos[i][:2] for i in ids[:2]] for ids in regatta._course_geoms[:5]])
  np.testing.assert_array_equal(drawn, regatta_core.posts_of(course))
  assert all(model.geom_pos[ids[0]][2] < 0.0 for ids in regatta._course_geoms[5:])   # hidden
  for physics in (regatta, steer):
    physics.set_ship_state([300.0, 200.0, 40.0, -5.0])
  for r in np.random.default_rng(4).uniform(-15, 15, 30):
    for physics in (regatta, steer):
      physics.set_turn_command(r)
      physics.step(6)
    np.testing.assert_array_equal(regatta.stepped_state, steer.stepped_state)


def test_cli_verify_regatta(capsys):
  # Both ships round each level's courses against the continuous ship (the command's
  # default is 3 courses a level; `hpg-mj verify regatta --starts 20` found the MuJoCo
  # ship alike on all 60, the Euler ship on 58). The scripted helmsman finishes the easy
  # and medium courses; the hard course closes after 1,000 control steps, before it
  # finishes, and the ships are compared over those ten minutes.
  assert cli.main(["verify", "regatta", "--starts", "1"]) == 0
  out = capsys.readouterr().out.splitlines()
  assert [line.split()[0] for line in out[1:4]] == ["easy", "medium", "hard"]
  assert all("same gates and end 1;" in line for line in out[1:4])
  assert all("helmsman finished 1;" in line for line in out[1:3])
  assert out[-1].endswith("met") and "NOT" not in out[-1]
