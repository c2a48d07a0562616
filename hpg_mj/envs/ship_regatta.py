"""The regatta as a Gymnasium environment and its native batch, on the MuJoCo or the
analytic ship (`hpg_mj.worlds.ship_regatta_core`)."""
import math

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from hpg_mj.envs import ship as ship_env
from hpg_mj.envs import vector
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_regatta_core as regatta_core


class MujocoRegattaBackend(ship_env.MujocoBackend):
  """The steering ship on assets/ship_regatta.xml, whose course geoms the environment
  moves to the episode's gates."""

  def __init__(self):
    from hpg_mj.worlds import ship_regatta   # MuJoCo and dm_control only for this backend
    self.physics = ship_regatta.Physics.from_xml_string(*ship_regatta.get_model_and_assets())
    self._nstep = core.SAMPLES_PER_CONTROL * self.physics._substeps_per_sample()


def spaces_of(rules, gates):
  """(observation space, action space): the steering ship's state, then two gates as the
  ship sees them (ahead and to starboard within the field's diagonal and one control
  step of sailing, 1,416.8 m, rounded up to whole metres; a heading in degrees) and the
  gates left, 0 to `gates`."""
  state, action = ship_env.spaces_of(rules)
  reach = float(math.ceil(math.hypot(state.high[0], state.high[1])))
  seen = [reach, reach, 180.0]
  observation = spaces.Box(low=np.concatenate([state.low, np.negative(seen * 2), [0.0]]),
                           high=np.concatenate([state.high, seen * 2, [float(gates)]]),
                           dtype=np.float64)
  return observation, action


class ShipRegattaEnv(ship_env.ShipSteeringEnv):
  """A regatta: pass a course of gates in order (`hpg_mj/ShipRegatta-v0`).

  ## Description
  The ship of `hpg_mj/ShipSteering-v0` (3 m/s on a 1 km field, its turning rate
  following the command with a 5 s lag) must pass a course of gates, one after another,
  laid out afresh at each reset from the episode's seed. Every gate is the steering
  task's gate moved and turned (100 m wide across its heading) and is passed as that one
  is: the ship's track between two positions sampled 0.2 s apart crosses the line
  between its posts, in either direction. Only the next gate counts. The first gate
  stands anywhere in [100, 900] m each way with any heading; each next one a fixed
  spacing on, along the previous gate's heading turned by the level's angle to a random
  side, and facing along that leg; no two gates come within 110 m of each other. A
  course takes hundreds of control steps and is made of legs alike up to a turn and a
  distance: a structure that invites a hierarchy (a leg a subtask, or the gate ahead a
  subgoal) without dictating one.

  | level | gates | spacing | turn at each gate |
  |---|---|---|---|
  | easy | 3 | 250 m | 0 to 30 deg |
  | medium | 5 | 200 m | 30 to 75 deg |
  | hard | 8 | 150 m | 60 to 135 deg, and the course closes after 1,000 control steps |

  ## Action space
  `Box(-15, 15, (1,), float64)`: the desired turning rate r in deg/s, held for one
  0.6 s control interval, as in `hpg_mj/ShipSteering-v0` (clipped, or refused with
  `strict=True`; NaN, infinity or a wrong shape raise `ValueError`).

  ## Observation space
  `Box(float64, (11,))`: the ship's state as in `hpg_mj/ShipSteering-v0`, then the next
  gate and the one after it as the ship sees them, then the gates left:

  | Num | Observation | Unit |
  |---|---|---|
  | 0 | `x`: the ship's position east | m |
  | 1 | `y`: the ship's position north | m |
  | 2 | `theta_deg`: the ship's heading, clockwise from north (+y), in [-180, 180) | deg |
  | 3 | `theta_dot_deg`: the ship's turning rate | deg/s |
  | 4 | `next_ahead`: the next gate's centre, ahead of the ship (along its heading) | m |
  | 5 | `next_starboard`: the next gate's centre, to the ship's starboard (right) | m |
  | 6 | `next_heading`: the next gate's heading less the ship's, wrapped | deg |
  | 7 | `after_ahead`: the gate after it, ahead of the ship | m |
  | 8 | `after_starboard`: the gate after it, to the ship's starboard | m |
  | 9 | `after_heading`: the gate after it, its heading less the ship's | deg |
  | 10 | `gates_left`: the gates left to pass, the next one included | gates |

  At the last gate elements 7-9 repeat 4-6 (there is no gate after it); after the
  finish both show the last gate and element 10 is 0. Off the field, the last position
  may lie up to 1.8 m (one control step of sailing) outside it.

  ## Rewards
  -1 per control step; +100 more for each gate passed but the last (`gate_reward`),
  +500 more for the last (`finish_reward`); -100 more for leaving the field
  (`out_of_bounds_reward`, `hpg_mj/ShipSteering-v0`'s default). A lap of the scripted
  helmsman (the steering task's, aimed through each gate in turn) takes about 590, 780
  and 930 control steps (easy, medium, hard), so the rewards make the course worth
  sailing: from 88%, 97% and 95% of the uniform starts that lap beats leaving the field
  by the nearest edge.

  ## Starting state
  The ship as in `hpg_mj/ShipSteering-v0`: x, y uniform on [0, 1000] m, heading uniform
  on [-180, 180) deg, turning rate uniform on [-15, 15] deg/s; then the course is laid
  out, both from the generator `reset(seed=...)` seeds. `reset(options={"state": [x, y,
  theta_deg, theta_dot_deg], "course": [[x, y, heading_deg], ...]})` fixes either (a
  course is the level's number of gates, each with its posts on the field; it is not
  held to the level's spacing and turns, so its scores are not the level's, whose
  bounds are over laid-out courses).

  ## Episode end
  Terminated when the last gate is passed (`info["event"] == "finish"`) or the ship
  leaves the field (`"out_of_bounds"`). Truncated after 5,000 control steps (3,000 s;
  `max_steps`), the episode limit of `hpg_mj/ShipSteering-v0`; at `hard` the course closes
  after 1,000 control steps (600 s), whatever a larger `max_steps` asks.

  ## Information
  `reset` and `step` return a dictionary:
  - `event`: what the step did: `"gate"` (a gate passed, not the last), `"finish"`,
    `"out_of_bounds"` or None (and None at `reset`).
  - `gates_passed`: the gates of the course passed so far (an int).
  - `positions` (`step` only): the positions sampled every 0.2 s during the step, rows
    (x, y), row 0 where it began; the gates and the bounds are checked on them.
  - `course` (`reset` only): the episode's course, rows `[x, y, heading_deg]` of its
    gates' centres and headings, in order (also `env.unwrapped.course`).

  ## Arguments
  - `level="easy"`: "easy", "medium" or "hard".
  - `backend="mujoco"`: the steering ship on assets/ship_regatta.xml (its course geoms
    moved to the episode's gates), or "analytic" (Equation 1, explicit Euler at 0.2 s);
    `hpg-mj verify regatta` sails the scripted helmsman's courses on both.
  - `render_mode=None`: or "rgb_array": a top-down frame with the wake and the course
    (the next gate yellow, the later ones white, the passed ones grey); `width=640`,
    `height=480`, `camera=None` ("top"; or "overview", "chase", "local").
  - `strict=False`: refuse out-of-range turning rates instead of clipping them.
  - `max_steps=None`: the episode limit in control steps (5,000; at most 1,000 at
    `hard`).
  - `gate_reward=100.0`, `finish_reward=500.0`, `out_of_bounds_reward=-100.0`: the
    rewards above.

  ## References
  [1] M. Ghavamzadeh and S. Mahadevan, "Hierarchical Policy Gradient
  Algorithms," Proceedings of the 20th International Conference on Machine
  Learning (ICML), 2003 (the ship of Equation 1 and its gate).

  [2] W. T. Miller, R. S. Sutton and P. J. Werbos (eds.), *Neural Networks for
  Control*, MIT Press, 1990 (the ship steering task).

  [3] hpg_mj's specification, docs/SPEC.md section 11: this task's levels and numbers.

  ## Version history
  - v0: the first release (not yet tagged: until then a v0 task may still change;
    each change is dated in docs/changelog.md, and scores made before it are not
    comparable with later ones).
  - v0, 2026-12-07: a step before the first reset is refused, one after the episode's
    end warned of (refused with `strict=True`).
  """

  model_file = "ship_regatta.xml"

  def __init__(self, level=regatta_core.DEFAULT_LEVEL, backend="mujoco", render_mode=None,
               strict=False, max_steps=None, width=640, height=480, camera=None,
               gate_reward=regatta_core.GATE_REWARD, finish_reward=regatta_core.FINISH_REWARD,
               out_of_bounds_reward=regatta_core.OUT_OF_BOUNDS_REWARD):
    self.level = level
    self.layout = regatta_core.level_layout(level, "ShipRegattaEnv")
    super().__init__("steer", backend, render_mode, strict,
                     regatta_core.episode_steps(level, max_steps), width, height, camera,
                     finish_reward, out_of_bounds_reward)
    self._name = f"ShipRegatta({level}, backend={backend})"
    self.observation_space, self.action_space = spaces_of(self.rules, self.layout[0])
    self._ship = regatta_core.OneShip(self.rules.max_steps, gate_reward, finish_reward,
                                      out_of_bounds_reward)

  def _make_backend(self, name):
    if name == "mujoco":
      return MujocoRegattaBackend()
    return ship_env.make_backend(name)

  @property
  def course(self):
    """This episode's course: rows [x, y, heading_deg] of its gates, in order."""
    return self._ship.course.copy()

  def _place_course(self):
    """The MuJoCo ship's course geoms where the rule's gates are (for its pictures)."""
    if hasattr(self.backend, "physics"):
      self.backend.physics.place_course(self._ship.posts, self._ship.next_gate)

  def reset(self, *, seed=None, options=None):
    gymnasium.Env.reset(self, seed=seed)    # the steering task's reset knows no course
    state, options = self._start(options, "course")
    if options.get("course") is not None:
      course = regatta_core.check_course(options["course"], self.layout[0], self._name)
    else:
      course = regatta_core.sample_course(self.np_random, self.layout)
    self._ship.set_course(course)
    self.backend.set_state(state)
    self._place_course()
    state = self._begun()
    return self._ship.observe(state), {"event": None, "gates_passed": 0,
                                       "course": self.course}

  def step(self, action):
    samples, state = self._sail(action)
    passed = self._ship.next_gate
    event, reward, terminated, truncated = self._ship(samples, self._steps)
    if self._ship.next_gate != passed:
      self._place_course()
    info = {"event": regatta_core.EVENT_NAMES[event], "gates_passed": self._ship.next_gate,
            "positions": samples}
    return self._result(self._ship.observe(state), reward, terminated, truncated, info)

  def _drawn(self):
    return {"course": self._ship.posts, "next_gate": self._ship.next_gate}


class ShipRegattaVectorEnv(vector.ShipSteeringVectorEnv):
  """A batch of `num_envs` regattas (`ShipRegattaEnv`'s manual; the batch as
  `ShipSteeringVectorEnv`'s): `gymnasium.make_vec("hpg_mj/ShipRegatta-v0", num_envs=N,
  level="hard", backend="analytic")` sails and judges every copy in one compiled call.
  Observations `(N, 11)`, each row as the single environment's. Infos add
  `gates_passed` (an int array); `reset()`'s adds `course` `(N, gates, 3)`, masked to the
  copies reset (after an autoreset, `env.unwrapped.courses` holds every copy's: copying
  them into each step's info would cost the batch a third of its speed). Reset options
  add `course` (one course `(gates, 3)` for every copy reset, or one per copy,
  `(N, gates, 3)`). The MuJoCo ships' course geoms are not moved (the batch draws
  nothing)."""

  RESET_OPTIONS = ("reset_mask", "state", "course")

  def __init__(self, num_envs=1, level=regatta_core.DEFAULT_LEVEL, backend="mujoco",
               strict=False, max_steps=None, gate_reward=regatta_core.GATE_REWARD,
               finish_reward=regatta_core.FINISH_REWARD,
               out_of_bounds_reward=regatta_core.OUT_OF_BOUNDS_REWARD,
               autoreset_mode=AutoresetMode.NEXT_STEP, render_mode=None):
    self.level = level
    self.layout = regatta_core.level_layout(level, "ShipRegattaVectorEnv")
    super().__init__(num_envs, "steer", backend, strict,
                     regatta_core.episode_steps(level, max_steps), finish_reward,
                     out_of_bounds_reward, autoreset_mode, render_mode)
    self.who = f"ShipRegattaVectorEnv({level}, backend={backend})"
    gates = self.layout[0]
    self.single_observation_space, _ = spaces_of(self.rules, gates)
    self.observation_space = batch_space(self.single_observation_space, self.num_envs)
    self.gate_reward, self.finish_reward = float(gate_reward), float(finish_reward)
    n = self.num_envs
    self._courses = np.zeros((n, gates, 3))
    self._posts = np.zeros((n, gates, 2, 2))
    self._next = np.zeros(n, dtype=np.int64)
    self._obs = np.zeros((n, regatta_core.OBSERVATION_SIZE))

  @property
  def courses(self):
    """Every copy's course, `(N, gates, 3)`: rows [x, y, heading_deg] of its gates."""
    return self._courses.copy()

  def reset(self, *, seed=None, options=None):
    """Starts the copies `options["reset_mask"]` selects (every copy by default):
    `(observations, info)`, the info with each copy's `course`."""
    observations, info = super().reset(seed=seed, options=options)
    info["course"] = self._courses.copy()
    info["_course"] = info["_event"].copy()
    return observations, info

  def _make_ships(self, backend):
    if backend == "mujoco":
      return vector._MujocoShips(self.num_envs, MujocoRegattaBackend)
    return super()._make_ships(backend)      # analytic: sailed in `step_batch`

  def _start(self, indices, options):
    super()._start(indices, options)
    given = options.get("course")
    gates = self.layout[0]
    if given is not None:
      given = np.asarray(given, dtype=np.float64)
      if given.shape not in ((gates, 3), (self.num_envs, gates, 3)):
        raise ValueError(f"{self.who}: options['course'] must be one course ({gates}, 3) or "
                         f"one per copy ({self.num_envs}, {gates}, 3), got shape "
                         f"{given.shape}")
    for i in indices.tolist():
      if given is None:
        course = regatta_core.sample_course(self._rngs[i], self.layout)
      else:
        course = regatta_core.check_course(given if given.ndim == 2 else given[i], gates,
                                           f"{self.who} copy {i}")
      self._courses[i] = course
      self._posts[i] = regatta_core.posts_of(course)
    self._next[indices] = 0

  def _advance(self, r, active):
    self._ships.control(self._states, r, active, self._samples)
    regatta_core.step_batch(
        self._states, r, active, self._samples, self._steps, self._ships.integrate,
        self._posts, self._next, self.rules.max_steps, self.gate_reward, self.finish_reward,
        self.rules.failure_reward,
        (self._event, self._reward, self._terminated, self._truncated))
    return self._reward.copy(), self._terminated.copy(), self._truncated.copy()

  def _observations(self):
    regatta_core.observe_batch(self._states, self._courses, self._next, self._obs)
    return self._obs.copy()

  def _event_table(self):
    """The regatta's events' names by number."""
    return regatta_core.EVENT_NAMES

  def _step_info(self, active):
    info = super()._step_info(active)
    info["gates_passed"] = self._next.copy()
    info["_gates_passed"] = active.copy()
    return info

  def _reset_info(self, indices):
    info = super()._reset_info(indices)
    info["gates_passed"] = self._next.copy()
    info["_gates_passed"] = info["_event"].copy()
    return info
