"""The regatta, in the style of dm_control's suite: a course of gates to pass in order,
laid out from the episode's seed (`ship_regatta_core`'s layout, rule and levels).

Tasks:
  easy:   3 gates 250 m apart, the course bending by at most 30 degrees at each.
  medium: 5 gates 200 m apart, turning by 30 to 75 degrees at each, to either side.
  hard:   8 gates 150 m apart, turning by 60 to 135 degrees at each: hairpins; the course
          closes after 1,000 control steps (10 minutes).

The ship, the field, the uniform starts and the bounds are `ship/steer`'s, and so is the
way a gate is passed (a sampled segment crossing it between the posts, either way); only
the next gate counts. -1 per control step, +100 for each gate but the last, +500 for
the last, which ends the episode; -100 for leaving the field; 5,000 control steps (1,000
at hard), then truncated. The observation adds the next gate and the one after it as the ship sees them
(`next_gate`, `gate_after`: ahead and to starboard in m, heading less the ship's in
degrees) and the gates left to pass (`gates_left`). On MuJoCo the steering ship sails on
assets/ship_regatta.xml, whose course geoms are moved to the episode's gates.
"""
import collections

import numpy as np

from hpg_mj import _assets
from hpg_mj import _headless
from hpg_mj.worlds import ship
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_regatta_core as regatta_core

with _headless.simulation_imports():   # no GL in the simulating process (SPEC section 9)
  from dm_control.utils import containers

SUITE = containers.TaggedTasks()

MODEL = "ship_regatta.xml"


def get_model_and_assets():
  """The MJCF model of the regatta and its assets (ship.xml, which it includes)."""
  return _assets.read_model(MODEL), _assets.included_assets(MODEL)


class Physics(ship.Physics):
  """The steering ship on assets/ship_regatta.xml: its course geoms drawn with it."""

  model_file = MODEL


class RegattaTask(ship.ShipTask):
  """`ship/steer` round a course of the level's gates (`ship_regatta_core`); the
  observation adds the next two gates as the ship sees them and the gates left."""

  def __init__(self, level=regatta_core.DEFAULT_LEVEL, random=None, initial_state=None,
               course=None, strict=False, max_steps=None, gate_reward=regatta_core.GATE_REWARD,
               finish_reward=regatta_core.FINISH_REWARD,
               out_of_bounds_reward=regatta_core.OUT_OF_BOUNDS_REWARD):
    """Args:
      level: "easy", "medium" or "hard" (`ship_regatta_core.LEVELS`).
      random, initial_state, strict: as `ShipTask`'s (a seed, a fixed start, whether a
        turning rate outside [-15, 15] deg/s is an error rather than clipped).
      max_steps: control steps before the episode is truncated (default 5,000; at
        hard at most the level's time limit, 1,000).
      course: optional fixed course, [[x, y, heading_deg], ...]; by default laid out
        at each reset.
      gate_reward: each gate passed but the last; finish_reward: the last;
      out_of_bounds_reward: leaving the field.
    """
    self.level = level
    self.layout = regatta_core.level_layout(level, "ship_regatta")
    super().__init__("steer", random=random, initial_state=initial_state, strict=strict,
                     max_steps=regatta_core.episode_steps(level, max_steps),
                     gate_reward=finish_reward,
                     out_of_bounds_reward=out_of_bounds_reward)
    self.name = f"ship_regatta-{level}"
    self.course = course
    # A course observed before the first episode (dm_control reads an observation to
    # make its spec): the level's, laid out from a seed of its own.
    self._ship = regatta_core.OneShip(self.rules.max_steps, gate_reward, finish_reward,
                                      out_of_bounds_reward)
    self._ship.set_course(regatta_core.sample_course(np.random.default_rng(0), self.layout))

  @property
  def course(self):
    """A fixed course (rows [x, y, heading_deg]) for the next episodes, or None (laid
    out at each reset)."""
    return self._course

  @course.setter
  def course(self, course):
    self._course = None if course is None else regatta_core.check_course(
        course, self.layout[0], self.name)

  @property
  def gates_passed(self):
    """The gates of this episode's course passed so far."""
    return self._ship.next_gate

  def initialize_episode(self, physics):
    super().initialize_episode(physics)     # the ship's start, then the course
    self._ship.set_course(self._course if self._course is not None
                          else regatta_core.sample_course(self.random, self.layout))
    physics.place_course(self._ship.posts, 0)

  def after_step(self, physics):
    self._steps += 1
    state = physics.stepped_state
    passed = self._ship.next_gate
    event, reward, terminated, truncated = self._ship(physics.sampled_positions(), self._steps)
    if self._ship.next_gate != passed:     # the next gate's colour moves on
      physics.place_course(self._ship.posts, self._ship.next_gate)
    self._outcome = (reward, terminated, truncated, regatta_core.EVENT_NAMES[event])
    self._state_after_step = state

  def get_observation(self, physics):
    # `ShipTask.get_observation`'s state, and every entry a part of one new array (the
    # Gymnasium environment's observation), which no other step's shares.
    state, self._state_after_step = self._state_after_step, None
    if state is None:
      state = physics.ship_state()
    seen = self._ship.observe(state)
    return collections.OrderedDict(
        (("position", seen[:2]), ("heading_deg", seen[2:3]), ("turning_rate_deg", seen[3:4]),
         ("next_gate", seen[4:7]), ("gate_after", seen[7:10]), ("gates_left", seen[10:])))


def _constructor(level):
  def task(random=None, initial_state=None, course=None, strict=False, max_steps=None,
           environment_kwargs=None, gate_reward=regatta_core.GATE_REWARD,
           finish_reward=regatta_core.FINISH_REWARD,
           out_of_bounds_reward=regatta_core.OUT_OF_BOUNDS_REWARD):
    return ship.environment(
        Physics.from_xml_string(*get_model_and_assets()),
        RegattaTask(level, random=random, initial_state=initial_state, course=course,
                    strict=strict, max_steps=max_steps, gate_reward=gate_reward,
                    finish_reward=finish_reward, out_of_bounds_reward=out_of_bounds_reward),
        environment_kwargs)
  gates, spacing, smallest, largest = regatta_core.LEVELS[level]
  task.__name__ = task.__qualname__ = level
  task.__doc__ = (f"Pass a course of {gates} gates in order (level {level!r}: {spacing:g} m "
                  f"apart, turning by {smallest:g} to {largest:g} degrees at each), laid out "
                  "at each reset; `course=[[x, y, heading_deg], ...]` fixes it. The rewards "
                  f"are SPEC section 11's unless given (+{regatta_core.GATE_REWARD:g} a gate, "
                  f"+{regatta_core.FINISH_REWARD:g} the last, "
                  f"{core.OUT_OF_BOUNDS_REWARD:g} off the field).")
  if regatta_core.TIME_LIMITS[level] is not None:
    task.__doc__ += (f" The course closes after {regatta_core.TIME_LIMITS[level]:,} control "
                     "steps, whatever a larger `max_steps` asks.")
  return task


easy = SUITE.add("benchmarking", "easy")(_constructor("easy"))
medium = SUITE.add("benchmarking", "medium")(_constructor("medium"))
hard = SUITE.add("benchmarking", "hard")(_constructor("hard"))
