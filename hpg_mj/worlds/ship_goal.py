"""The goal-conditioned ship, in the style of dm_control's suite: pass a gate whose place
and heading are drawn each episode (`ship_goal_core`'s rule and levels).

Tasks:
  easy:   the gate's centre uniform within 100 m of `ship/steer`'s (400, 400), its
          heading within 30 degrees of north.
  medium: the centre anywhere in the middle 600 m ([200, 800] m each way), the
          heading within 90 degrees of north.
  hard:   the centre anywhere in [100, 900] m each way (both posts on the field),
          any heading; the gate 50 m wide, passed heading within 30 degrees of it;
          among the harbour's medium obstacles (`ship_goal_core.OBSTACLES`), the
          gate clear of them, touching one ending the episode as leaving the field.

The ship, the field, the uniform starts and the rewards are `ship/steer`'s (-1 per
control step, +100 at the gate, -100 off the field, 5,000 control steps then
truncated); the gate must be passed heading within 45 degrees of its heading (30 at
hard, where the gate is also half as wide), and the
pass and the departure are judged where the ship is at the end of each control step,
so that the same rule is a function of goals alone (`ship_goal_core`, for Hindsight
Experience Replay). The observation adds the gate (`gate_position`,
`gate_heading_deg`) and the rangefinders' `ranges` (150 m, nothing seen, in open water).
On MuJoCo the steering ship of assets/ship.xml sails, its gate's geoms moved to the
episode's gate; at `hard` the harbour's model (assets/ship_harbour.xml), its obstacles
and its rangefinder sensors.
"""
import numpy as np

from hpg_mj import _headless
from hpg_mj.worlds import ship
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_goal_core as goal_core
from hpg_mj.worlds import ship_harbour

with _headless.simulation_imports():   # no GL in the simulating process (SPEC section 9)
  from dm_control.utils import containers

SUITE = containers.TaggedTasks()
get_model_and_assets = ship.get_model_and_assets


class GoalTask(ship.ShipTask):
  """`ship/steer` with the episode's own gate (`ship_goal_core`)."""

  def __init__(self, level=goal_core.DEFAULT_LEVEL, random=None, initial_state=None, gate=None,
               strict=False, max_steps=None, **rewards):
    """Args:
      level: "easy", "medium" or "hard" (`ship_goal_core.LEVELS`).
      random, initial_state, strict: as `ShipTask`'s (a seed, a fixed start, whether a
        turning rate outside [-15, 15] deg/s is an error rather than clipped).
      max_steps: control steps before the episode is truncated (default 5,000).
      gate: optional fixed gate [x, y, heading_deg]; by default drawn each episode.
      **rewards: `gate_reward`, `out_of_bounds_reward` (as `ShipTask`'s).
    """
    self.level = level
    self.level_range = goal_core.level_range(level, "ship_goal")
    super().__init__("steer", random=random, initial_state=initial_state, strict=strict,
                     max_steps=goal_core.episode_steps(level, max_steps), **rewards)
    self.name = f"ship_goal-{level}"
    self.gate = gate
    # The gate observed before the first episode (dm_control reads an observation to
    # make its spec): ship/steer's.
    self.desired = goal_core.sample_gate(np.random.default_rng(0), level)
    self._gate_heading_deg = np.zeros(1)
    self.tolerance = goal_core.level_tolerance(level)
    self._judge = goal_core.OneShip(self.rules, level)

  @property
  def initial_state(self):
    """A fixed start [x, y, theta_deg, theta_dot_deg] for the next episodes, or None."""
    return self._initial_state

  @initial_state.setter
  def initial_state(self, state):
    self._initial_state = (None if state is None else
                           goal_core.check_start(self.rules, state, self.level, self.name))

  @property
  def gate(self):
    """A fixed gate [x, y, heading_deg] for the next episodes, or None (drawn)."""
    return self._gate

  @gate.setter
  def gate(self, gate):
    self._gate = None if gate is None else goal_core.check_gate(gate, self.name, self.level)

  def initialize_episode(self, physics):
    obstacles = goal_core.OBSTACLES[self.level]
    if obstacles is not None and physics.level != obstacles:
      physics.place_obstacles(obstacles)
    state = (self._initial_state if self._initial_state is not None
             else goal_core.sample_start(self.rules, self.random, self.level))
    physics.set_ship_state(state)     # the ship's start, then the gate
    physics.place_target(None)
    physics._samples = None
    self._steps = 0
    self._outcome = (0.0, False, False, None)
    self._state_after_step = None
    self.desired = (self._gate if self._gate is not None
                    else goal_core.sample_gate(self.random, self.level))
    physics.place_gate(goal_core.gate_posts(self.desired, self.tolerance[0]))
    self._gate_heading_deg = np.array([goal_core.gate_heading_deg(self.desired)])

  def after_step(self, physics):
    self._steps += 1
    state = physics.stepped_state
    _, reward, terminated, truncated, name = self._judge(physics.sampled_positions(), state,
                                                         self._steps, self.desired)
    self._outcome = (reward, terminated, truncated, name)
    self._state_after_step = state

  def get_observation(self, physics):
    state = self._state_after_step
    obs = super().get_observation(physics)
    if state is None:
      state = physics.ship_state()
    obs["gate_position"] = self.desired[:2].copy()
    obs["gate_heading_deg"] = self._gate_heading_deg.copy()
    obstacles = goal_core.OBSTACLES[self.level]
    if obstacles is None:             # open water: no ray meets anything
      obs["ranges"] = self._judge.ranges(np.ascontiguousarray(state, dtype=np.float64))
    else:
      if physics.level != obstacles:  # dm_control reads one observation before any reset
        physics.place_obstacles(obstacles)
      obs["ranges"] = self._judge.ranges(state, physics.rangefinder_readings())
    return obs


def physics_of(level):
  """The MuJoCo physics of a goal `level`: the steering ship's (assets/ship.xml) in open
  water, the harbour's (assets/ship_harbour.xml, its obstacles placed) among obstacles."""
  obstacles = goal_core.OBSTACLES[level]
  if obstacles is None:
    return ship.Physics.from_xml_string(*get_model_and_assets())
  physics = ship_harbour.Physics.from_xml_string(*ship_harbour.get_model_and_assets())
  physics.place_obstacles(obstacles)
  return physics


def _constructor(level):
  def task(random=None, initial_state=None, gate=None, strict=False, max_steps=None,
           environment_kwargs=None, gate_reward=core.GATE_REWARD,
           out_of_bounds_reward=core.OUT_OF_BOUNDS_REWARD):
    return ship.environment(
        physics_of(level),
        GoalTask(level, random=random, initial_state=initial_state, gate=gate, strict=strict,
                 max_steps=max_steps, gate_reward=gate_reward,
                 out_of_bounds_reward=out_of_bounds_reward), environment_kwargs)
  low, high, largest = goal_core.LEVELS[level]
  half_width, degrees = goal_core.TOLERANCES[level]
  task.__name__ = task.__qualname__ = level
  task.__doc__ = (f"Pass a gate drawn each episode (level {level!r}: centre uniform on "
                  f"[{low:g}, {high:g}] m each way, heading within {largest:g} degrees of "
                  f"north; {2 * half_width:g} m wide, passed heading within {degrees:g} "
                  "degrees of it); `gate=[x, y, heading_deg]` fixes it. The rewards at the "
                  "gate and off the field are SPEC section 2's unless given.")
  if goal_core.OBSTACLES[level] is not None:
    task.__doc__ += (f" The water holds ship_harbour/{goal_core.OBSTACLES[level]}'s obstacles; "
                     "touching one ends the episode as leaving the field, and the gate is "
                     "drawn clear of them.")
  if goal_core.TIME_LIMITS[level] is not None:
    task.__doc__ += (f" The episode closes after {goal_core.TIME_LIMITS[level]:,} control "
                     "steps, whatever a larger `max_steps` asks.")
  return task


easy = SUITE.add("benchmarking", "easy")(_constructor("easy"))
medium = SUITE.add("benchmarking", "medium")(_constructor("medium"))
hard = SUITE.add("benchmarking", "hard")(_constructor("hard"))
