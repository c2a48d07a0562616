"""The harbour as a Gymnasium environment and its native batch, on the MuJoCo or the
analytic ship (`hpg_mj.worlds.ship_harbour_core`)."""
import functools

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from hpg_mj.envs import ship as ship_env
from hpg_mj.envs import vector
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_harbour_core as harbour_core


class MujocoHarbourBackend(ship_env.MujocoBackend):
  """The steering ship on assets/ship_harbour.xml, among `level`'s obstacles, with its
  rangefinders."""

  def __init__(self, level):
    from hpg_mj.worlds import ship_harbour   # MuJoCo and dm_control only for this backend
    self.physics = ship_harbour.Physics.from_xml_string(*ship_harbour.get_model_and_assets())
    self.physics.place_obstacles(level)
    self._nstep = core.SAMPLES_PER_CONTROL * self.physics._substeps_per_sample()

  def readings(self):
    """The rangefinders' raw readings where the ship is (-1: nothing on the ray)."""
    return self.physics.rangefinder_readings()


def spaces_of(rules):
  """(observation space, action space): the steering ship's state, then the ranges, 0 to
  MAX_RANGE_M."""
  state, action = ship_env.spaces_of(rules)
  rays = harbour_core.RAYS
  observation = spaces.Box(low=np.concatenate([state.low, np.zeros(rays)]),
                           high=np.concatenate([state.high,
                                                np.full(rays, harbour_core.MAX_RANGE_M)]),
                           dtype=np.float64)
  return observation, action


class ShipHarbourEnv(ship_env.ShipSteeringEnv):
  """The harbour: the steering task's gate behind islands and piers
  (`hpg_mj/ShipHarbour-v0`).

  ## Description
  The steering task of `hpg_mj/ShipSteering-v0` (a 1 km field, the gate between
  (350, 400) and (450, 400), a ship at 3 m/s whose turning rate follows the command
  with a 5 s lag) with obstacles in the way: islands (circles) and piers (rectangles),
  the same at every reset of a level. Touching one ends the episode as leaving the
  field does. The ship sees them only through seven rangefinders; the layout is fixed
  per level, so a learner may also learn the map.

  | level | islands: centre (m), radius (m) | piers: end to end (m), 12 m wide |
  |---|---|---|
  | easy | (400, 620) 60; (650, 230) 60 | none |
  | medium | (400, 570) 60; (400, 220) 60; | (180, 400)-(340, 400); |
  | | (720, 680) 70; (200, 780) 60 | (460, 400)-(760, 400) |
  | hard | (760, 780) 80; (180, 780) 70; | (40, 400)-(340, 400); (460, 400)-(960, 400); |
  | | (780, 180) 60; (180, 180) 60 | (270, 450)-(530, 450); (270, 350)-(530, 350); |
  | | | (270, 406)-(270, 450); (530, 394)-(530, 350); |
  | | | (220, 406)-(220, 560); (580, 394)-(580, 240) |

  At medium the gate's line is prolonged by breakwaters, so that it is passed nearly
  square; at hard they reach within 40 m of the field's edges, the gate the only way
  through the middle, and the mouth lies in a walled pocket on either side, 50 m deep
  and closed at one end (the northern one is entered from the east, the southern from
  the west): the gate is reached by a channel and a quarter turn. At hard the episode
  also closes after 1,000 control steps (10 minutes).

  ## Action space
  `Box(-15, 15, (1,), float64)`: the desired turning rate r in deg/s, held for one
  0.6 s control interval, as in `hpg_mj/ShipSteering-v0` (clipped, or refused with
  `strict=True`; NaN, infinity or a wrong shape raise `ValueError`).

  ## Observation space
  `Box(float64, (11,))`: the ship's state as in `hpg_mj/ShipSteering-v0`, then the
  rangefinders: the distance from the ship to the first obstacle along a ray in the
  water plane, 150 m where none is nearer (MuJoCo's rangefinder reads -1 there).

  | Num | Observation | Unit |
  |---|---|---|
  | 0 | `x`: the ship's position east | m |
  | 1 | `y`: the ship's position north | m |
  | 2 | `theta_deg`: the ship's heading, clockwise from north (+y), in [-180, 180) | deg |
  | 3 | `theta_dot_deg`: the ship's turning rate | deg/s |
  | 4 | `range_port_90`: the range along the ray 90 deg to port (left) of the heading | m |
  | 5 | `range_port_60`: the range along the ray 60 deg to port | m |
  | 6 | `range_port_30`: the range along the ray 30 deg to port | m |
  | 7 | `range_ahead`: the range along the heading | m |
  | 8 | `range_starboard_30`: the range along the ray 30 deg to starboard (right) | m |
  | 9 | `range_starboard_60`: the range along the ray 60 deg to starboard | m |
  | 10 | `range_starboard_90`: the range along the ray 90 deg to starboard | m |

  Each range is 0 to 150 m (bearings -90, -60, -30, 0, 30, 60, 90 deg from the heading,
  clockwise, `ship_harbour_core.BEARINGS_DEG`). The rays see the islands and the piers
  only: the field's edges are not obstacles (leaving ends the episode, as on every
  ship task). After a step that ran aground, the step's last position may lie inside
  the obstacle; a ray from there reads the way out, as MuJoCo's does.

  On MuJoCo the ranges are the rangefinder sensors of assets/ship_harbour.xml; on the
  analytic ship the same rays cast in closed form (they agree within 1e-9 m).

  ## Rewards
  -1 per control step; +100 more for passing the gate (in either direction, between the
  posts; `gate_reward`); -100 more for leaving the field or touching an obstacle
  (`out_of_bounds_reward`).

  ## Starting state
  As in `hpg_mj/ShipSteering-v0` (x, y uniform on [0, 1000] m, heading uniform on
  [-180, 180) deg, turning rate uniform on [-15, 15] deg/s), drawn again while the
  position lies on an obstacle. `reset(options={"state": [x, y, theta_deg,
  theta_dot_deg]})` starts from an exact state off the obstacles.

  ## Episode end
  Terminated at the gate (`info["event"] == "gate"`), off the field
  (`"out_of_bounds"`) or on touching an obstacle (`"obstacle"`: a segment of the track
  sampled every 0.2 s meets its shape; the ship is a point, as for the gate and the
  bounds). Truncated after 5,000 control steps (`max_steps`), at hard after 1,000
  whatever a larger `max_steps` asks.

  ## Information
  `reset()` returns `{"event": None}`; `step()` returns `event` and `positions`, the
  `(4, 2)` positions sampled every 0.2 s during the step (row 0 where it began), on
  which the gate, the bounds and the obstacles are checked.

  ## Arguments
  - `level="easy"`: "easy", "medium" or "hard".
  - `backend="mujoco"`: the steering ship on assets/ship_harbour.xml (the level's
    obstacles as geoms, rangefinder sensors), or "analytic" (Equation 1, explicit Euler
    at 0.2 s, the rays in closed form); `hpg-mj verify harbour` sails both.
  - `render_mode=None`: or "rgb_array": a top-down frame with the wake and the level's
    obstacles; `width=640`, `height=480`, `camera=None` ("top"; or "overview",
    "chase", "local").
  - `strict=False`: refuse out-of-range turning rates instead of clipping them.
  - `max_steps=None`: the episode limit in control steps (5,000; at most 1,000 at
    `hard`).
  - `gate_reward=100.0`, `out_of_bounds_reward=-100.0`: the rewards above.

  ## References
  [1] M. Ghavamzadeh and S. Mahadevan, "Hierarchical Policy Gradient
  Algorithms," Proceedings of the 20th International Conference on Machine
  Learning (ICML), 2003 (the ship of Equation 1 and its gate).

  [2] hpg_mj's specification, docs/SPEC.md section 11: this task's levels and numbers.

  ## Version history
  - v0: the first release (not yet tagged: until then a v0 task may still change;
    each change is dated in docs/changelog.md, and scores made before it are not
    comparable with later ones).
  - v0, 2026-12-06: `hard`'s mouth lies in a walled pocket on either side, and the
    level closes after 1,000 control steps.
  - v0, 2026-12-07: frames no longer draw the rangefinders' rays; a step before the
    first reset is refused, one after the episode's end warned of (refused with
    `strict=True`).
  """

  model_file = "ship_harbour.xml"

  def __init__(self, level=harbour_core.DEFAULT_LEVEL, backend="mujoco", render_mode=None,
               strict=False, max_steps=None, width=640, height=480, camera=None,
               gate_reward=harbour_core.GATE_REWARD,
               out_of_bounds_reward=harbour_core.OUT_OF_BOUNDS_REWARD):
    self.level = level
    harbour_core.level_obstacles(level, "ShipHarbourEnv")
    super().__init__("steer", backend, render_mode, strict,
                     harbour_core.episode_steps(level, max_steps), width, height, camera,
                     gate_reward, out_of_bounds_reward)
    self._name = f"ShipHarbour({level}, backend={backend})"
    self.observation_space, self.action_space = spaces_of(self.rules)
    self._ship = harbour_core.OneShip(level, self.rules.max_steps, gate_reward,
                                      out_of_bounds_reward)

  def _make_backend(self, name):
    if name == "mujoco":
      return MujocoHarbourBackend(self.level)
    return ship_env.make_backend(name)

  def _observe(self, state):
    readings = self.backend.readings() if hasattr(self.backend, "readings") else None
    return self._ship.observe(state, readings)

  def _start(self, options, *extra):
    options = dict(options or {})
    unknown = set(options) - {"state"}
    if unknown:
      raise ValueError(f"{self._name}: unknown reset options {sorted(unknown)}; allowed: "
                       "['state']")
    islands, piers = self._ship.islands, self._ship.piers
    if options.get("state") is not None:
      return harbour_core.check_start(self.rules, options["state"], islands, piers,
                                      self._name), options
    return harbour_core.sample_start(self.rules, self.np_random, islands, piers), options

  def reset(self, *, seed=None, options=None):
    state, info = super().reset(seed=seed, options=options)
    return self._observe(state), info

  def step(self, action):
    samples, state = self._sail(action)
    event, reward, terminated, truncated = self._ship(samples, self._steps)
    info = {"event": harbour_core.EVENT_NAMES[event], "positions": samples}
    return self._result(self._observe(state), reward, terminated, truncated, info)

  def _drawn(self):
    return {"obstacles": self.level}


class ShipHarbourVectorEnv(vector.ShipSteeringVectorEnv):
  """A batch of `num_envs` harbours (`ShipHarbourEnv`'s manual; the batch as
  `ShipSteeringVectorEnv`'s): `gymnasium.make_vec("hpg_mj/ShipHarbour-v0", num_envs=N,
  level="hard", backend="analytic")` sails, judges and casts the rays of every copy in
  compiled calls. Observations `(N, 11)`, each row as the single environment's; on
  MuJoCo the ranges are each ship's rangefinders. Reset options: `state` and
  `reset_mask`, as the steering batch's (a start on an obstacle is refused)."""

  def __init__(self, num_envs=1, level=harbour_core.DEFAULT_LEVEL, backend="mujoco",
               strict=False, max_steps=None, gate_reward=harbour_core.GATE_REWARD,
               out_of_bounds_reward=harbour_core.OUT_OF_BOUNDS_REWARD,
               autoreset_mode=AutoresetMode.NEXT_STEP, render_mode=None):
    self.level = level
    harbour_core.level_obstacles(level, "ShipHarbourVectorEnv")
    self._islands, self._piers = harbour_core.level_shapes(level)
    self._cells = harbour_core.level_cells(level)
    super().__init__(num_envs, "steer", backend, strict,
                     harbour_core.episode_steps(level, max_steps), gate_reward,
                     out_of_bounds_reward, autoreset_mode, render_mode)
    self.who = f"ShipHarbourVectorEnv({level}, backend={backend})"
    self.single_observation_space, _ = spaces_of(self.rules)
    self.observation_space = batch_space(self.single_observation_space, self.num_envs)
    self._obs = np.zeros((self.num_envs, harbour_core.OBSERVATION_SIZE))

  def _make_ships(self, backend):
    if backend == "mujoco":
      return vector._MujocoShips(self.num_envs,
                                 functools.partial(MujocoHarbourBackend, self.level))
    return super()._make_ships(backend)      # analytic: sailed in `step_batch`

  def _start(self, indices, options):
    given = self._option_rows(options, "state", 4, "state")
    for i in indices.tolist():
      if given is None:
        state = harbour_core.sample_start(self.rules, self._rngs[i], self._islands,
                                          self._piers)
      else:
        state = harbour_core.check_start(self.rules, given if given.ndim == 1 else given[i],
                                         self._islands, self._piers, f"{self.who} copy {i}")
      self._ships.set_state(self._states, i, state)
    self._steps[indices] = 0

  def _advance(self, r, active):
    self._ships.control(self._states, r, active, self._samples)
    harbour_core.step_batch(
        self._states, r, active, self._samples, self._steps, self._ships.integrate,
        self._islands, self._piers, self._cells, self.rules.max_steps, self.rules.success_reward,
        self.rules.failure_reward, (self._event, self._reward, self._terminated,
                                    self._truncated))
    return self._reward.copy(), self._terminated.copy(), self._truncated.copy()

  def _observations(self):
    if self._ships.integrate:
      harbour_core.observe_batch(self._states, self._islands, self._piers, self._cells,
                                 self._obs)
    else:
      self._obs[:, :4] = self._states
      for i, ship in enumerate(self._ships.ships):
        harbour_core.seen_ranges(ship.readings(), self._obs[i], 4)
    return self._obs.copy()

  def _event_table(self):
    """The harbour's events' names by number."""
    return harbour_core.EVENT_NAMES
