"""`hpg-mj verify current`, `goal`, `regatta`, `harbour`: the task ladder's two
ships against each other and the continuous ship (SPEC section 11), as `hpg_mj.verify`
checks the steering ship (its closed form, `exact_trajectory`)."""
import collections
import dataclasses

import numpy as np

from hpg_mj.verify import (HEADING_BOUND_DEG, POSITION_BOUND_M, _errors, exact_trajectory,
                           mujoco_trajectory)
from hpg_mj.worlds import ship
from hpg_mj.worlds import ship_core as core


# ---- `hpg-mj verify current`: the ships in a current against the continuous ODE -----

def exact_current_trajectory(state, controls, field):
  """The continuous ship in a current (ship_current_core): Equation 1's heading and
  turning rate, and over ground V * heading + c(x, y); states [x, y, theta_deg
  (unwrapped), theta_dot_deg] at every sampling instant, by an 8th-order Runge-Kutta
  integrator (scipy's DOP853) at tolerances far below the errors measured."""
  from scipy.integrate import solve_ivp

  from hpg_mj.worlds import ship_current_core as current_core
  field = np.asarray(field, dtype=np.float64)
  dt, k = core.SAMPLING_INTERVAL, core.SAMPLES_PER_CONTROL
  times = dt * np.arange(1, k + 1)

  def rates(_, s, r):
    theta = np.radians(s[2])
    cx, cy = current_core.current_at(field, s[0], s[1])
    return (core.SPEED * np.sin(theta) + cx, core.SPEED * np.cos(theta) + cy, s[3],
            (r - s[3]) / core.TIME_CONSTANT)

  s = np.array(state, dtype=np.float64)
  out = np.empty((len(controls) * k, 4))
  for i, r in enumerate(controls):
    solution = solve_ivp(rates, (0.0, k * dt), s, method="DOP853", t_eval=times,
                         args=(float(r),), rtol=1e-11, atol=1e-9)
    out[i * k:(i + 1) * k] = solution.y.T
    s = solution.y[:, -1].copy()
  return out


def drift_trajectory(state, controls, field):
  """The analytic ship in a current (`ship_current_core.drift_sample`) every 0.2 s."""
  from hpg_mj.worlds import ship_current_core as current_core
  s = np.array(state, dtype=np.float64)
  field = np.asarray(field, dtype=np.float64)
  out = []
  for r in controls:
    for _ in range(core.SAMPLES_PER_CONTROL):
      current_core.drift_sample(s, r, field, core.SPEED, core.TIME_CONSTANT,
                                core.SAMPLING_INTERVAL)
      out.append(s.copy())
  return np.array(out)


@dataclasses.dataclass
class CurrentVerification:
  """What `hpg-mj verify current` measured for one level's current: the two ships'
  largest errors against the continuous ship."""
  level: str
  controls: int
  starts: int
  max_current_m_s: float
  mujoco_position_m: float
  mujoco_heading_deg: float
  euler_position_m: float
  euler_heading_deg: float

  def line(self):
    """Its report line, as printed."""
    return (f"  {self.level:<7} (water up to {self.max_current_m_s:.2f} m/s): MuJoCo "
            f"{self.mujoco_position_m:.4f} m, {self.mujoco_heading_deg:.4f} deg; analytic "
            f"(Euler) {self.euler_position_m:.4f} m, {self.euler_heading_deg:.4f} deg; "
            f"MuJoCo / Euler position error "
            f"{self.mujoco_position_m / self.euler_position_m:.3f}")

  @property
  def passed(self):
    """SPEC section 1's bounds for the steering ship, kept in the current: within
    0.25 m and 0.25 deg, and at most half the Euler model's position error."""
    return (self.mujoco_position_m < POSITION_BOUND_M
            and self.mujoco_heading_deg < HEADING_BOUND_DEG
            and self.mujoco_position_m <= 0.5 * self.euler_position_m)


def verify_current(controls=1000, starts=3, seed=0, levels=None):
  """Largest errors of both ships in each level's current against the continuous
  solution (as `verify_ship`): one CurrentVerification per level."""
  from hpg_mj.worlds import ship_current
  from hpg_mj.worlds import ship_current_core as current_core
  if controls < 1 or starts < 1:
    raise ValueError(f"controls and starts must be positive, got {controls} and {starts}")
  results = []
  physics = ship_current.Physics.from_xml_string(*ship_current.get_model_and_assets())
  for level in levels or tuple(current_core.LEVELS):
    field = current_core.level_field(level, "hpg-mj verify current")
    physics.set_field(field)
    rng = np.random.default_rng(seed)
    rules = ship.ShipRules("steer")
    worst = np.zeros(4)
    for _ in range(starts):
      start = rules.sample_start(rng)
      rs = rng.uniform(-core.MAX_TURN_RATE, core.MAX_TURN_RATE, controls)
      reference = exact_current_trajectory(start, rs, field)
      mj_err = _errors(mujoco_trajectory(start, rs, physics), reference)
      eu_err = _errors(drift_trajectory(start, rs, field), reference)
      worst = np.maximum(worst, (*mj_err, *eu_err))
    results.append(CurrentVerification(level, controls, starts, current_core.max_speed(field),
                                       *worst))
  return results


# ---- `hpg-mj verify goal`: the goal task's two backends, episode by episode ------------

@dataclasses.dataclass
class GoalVerification:
  """What `hpg-mj verify goal` measured for one level: the two ships' episodes
  compared."""
  level: str
  episodes: int
  analytic_passes: int          # episodes the scripted helmsman ended at the gate
  same_outcome: int             # episodes both ships ended alike, within one control step
  largest_position_m: float     # MuJoCo against analytic, over every step sailed
  gate_geoms_m: float           # the MuJoCo gate's posts against the rule's, largest
  aground: int = 0              # episodes the helmsman (blind to obstacles) ran aground
  ranges_m: float = 0.0         # MuJoCo's rangefinders against the analytic rays cast
                                # from the MuJoCo ship's own states, largest

  def line(self):
    """Its report line, as printed."""
    return (f"  {self.level:<7} {self.episodes} episodes: helmsman passed "
            f"{self.analytic_passes}, ran aground {self.aground}; same end within a step "
            f"on both ships {self.same_outcome}; MuJoCo vs analytic position at most "
            f"{self.largest_position_m:.3f} m; MuJoCo gate posts off the rule's by "
            f"{self.gate_geoms_m:.1e} m; rangefinders against the rays {self.ranges_m:.1e} m")

  @property
  def passed(self):
    """The ships differ by their discretisations only (the analytic ship strays about
    1 m from the continuous one in 600 s, `hpg-mj verify ship`; MuJoCo's 0.04 m), the
    MuJoCo gate stands where the rule's is, and at most one episode in 20 ends
    differently. A pass is seen one control step earlier or later when the ships are a
    metre apart along the track (the window is 1.8 m deep): that counts as the same end."""
    return (self.largest_position_m < 1.5 and self.gate_geoms_m < 1e-9
            and self.same_outcome >= 0.95 * self.episodes and self.ranges_m < 1e-6)


def _goal_episode(env, seed, actions=None, start=None, steps=2000):
  """(states, events, actions, ranges) of one episode of `env` (a ShipGoalEnv): the
  scripted helmsman's choices, or `actions` replayed from `start` (and the last one held
  for one more control step, should the episode not have ended)."""
  from hpg_mj.worlds import ship_goal_core as goal_core
  obs, _ = env.reset(seed=seed, options=start)
  states, events, chosen, phase = [obs["observation"]], [None], [], 0
  ranges = [obs["ranges"]]
  for t in range(steps if actions is None else len(actions) + 1):
    if actions is None:
      tx, ty, phase = goal_core.pilot_target(obs["observation"], phase, obs["desired_goal"])
      r = core.pilot_turn_rate(obs["observation"], tx, ty)
    else:
      r = actions[min(t, len(actions) - 1)]
    obs, _, terminated, truncated, info = env.step(np.array([r]))
    states.append(obs["observation"])
    events.append(info["event"])
    ranges.append(obs["ranges"])
    chosen.append(r)
    if terminated or truncated:
      break
  return np.array(states), events, chosen, np.array(ranges)


def verify_goal(episodes=20, seed=0, levels=None):
  """Per level, `episodes` episodes of the scripted helmsman on the analytic ship, its
  turning rates replayed on the MuJoCo ship from the same start through the same gate:
  one GoalVerification per level."""
  import gymnasium

  import hpg_mj  # noqa: F401  (registers the ids)
  from hpg_mj.worlds import ship_goal_core as goal_core
  if episodes < 1:
    raise ValueError(f"episodes must be positive, got {episodes}")
  results = []
  for level in levels or tuple(goal_core.LEVELS):
    goal_core.level_range(level, "hpg-mj verify goal")
    analytic = gymnasium.make("hpg_mj/ShipGoal-v0", level=level, backend="analytic").unwrapped
    mujoco = gymnasium.make("hpg_mj/ShipGoal-v0", level=level, backend="mujoco").unwrapped
    rays = goal_core.OneShip(analytic.rules, level)
    passes = same = aground = 0
    largest = posts_off = ranges_off = 0.0
    for episode in range(episodes):
      states, events, actions, _ = _goal_episode(analytic, seed * 100_003 + episode)
      desired = analytic._desired
      start = {"state": states[0], "gate": [desired[0], desired[1],
                                            goal_core.gate_heading_deg(desired)]}
      replay, replay_events, _, seen = _goal_episode(mujoco, None, actions, start)
      n = min(len(states), len(replay))
      largest = max(largest, float(np.hypot(*(states[:n, :2] - replay[:n, :2]).T).max()))
      passes += events[-1] == "gate"
      aground += events[-1] == "obstacle"
      same += abs(len(replay) - len(states)) <= 1 and replay_events[-1] == events[-1]
      drawn = np.array([mujoco.backend.physics.named.model.geom_pos[name][:2]
                        for name in ("gate_post_west", "gate_post_east")])
      posts_off = max(posts_off, float(np.abs(drawn - goal_core.gate_posts(
          analytic._desired, analytic.tolerance[0])).max()))
      cast = np.array([rays.ranges(np.ascontiguousarray(state)) for state in replay])
      ranges_off = max(ranges_off, float(np.abs(cast - seen).max()))
    results.append(GoalVerification(level, episodes, passes, same, largest, posts_off, aground,
                                    ranges_off))
  return results


# ---- `hpg-mj verify regatta`: the regatta's two backends against the continuous ship --

@dataclasses.dataclass
class RegattaVerification:
  """What `hpg-mj verify regatta` measured for one level: the two ships' courses
  against the continuous ship."""
  level: str
  episodes: int
  analytic_finishes: int        # courses the scripted helmsman sailed to the finish
  mujoco_position_m: float      # the MuJoCo environment against the continuous ship
  mujoco_heading_deg: float
  euler_position_m: float       # the analytic environment against the continuous ship
  mujoco_same: int              # courses where the MuJoCo ship passed the continuous
                                # ship's gates, each within a control step, and ended alike
  euler_same: int               # the same for the analytic ship (reported)
  course_geoms_m: float         # the MuJoCo course's posts against the rule's, largest

  def line(self):
    """Its report line, as printed."""
    return (f"  {self.level:<7} {self.episodes} courses, helmsman finished "
            f"{self.analytic_finishes}; against the continuous ship: MuJoCo "
            f"{self.mujoco_position_m:.4f} m, {self.mujoco_heading_deg:.4f} deg, same gates "
            f"and end {self.mujoco_same}; analytic (Euler) {self.euler_position_m:.4f} m, "
            f"same gates and end {self.euler_same}; MuJoCo course posts off the rule's by "
            f"{self.course_geoms_m:.1e} m")

  @property
  def passed(self):
    """SPEC section 1's bounds over whole courses (within 0.25 m and 0.25 deg of the
    continuous ship, at most half the Euler ship's error); the MuJoCo course where the
    rule's is; and in at least 19 courses of 20 the MuJoCo ship passes the continuous
    ship's gates, each within one control step (1.8 m of sailing), and ends alike. The
    Euler ship, metres off after the hard level's ten minutes of hairpins, is
    reported."""
    return (self.mujoco_position_m < POSITION_BOUND_M
            and self.mujoco_heading_deg < HEADING_BOUND_DEG
            and self.mujoco_position_m <= 0.5 * self.euler_position_m
            and self.course_geoms_m < 1e-9 and self.mujoco_same >= 0.95 * self.episodes)


def _regatta_episode(env, seed, actions=None, start=None, steps=5000):
  """(states at each control step, the steps at which gates were passed, the last event,
  the turning rates) of one episode of `env` (a ShipRegattaEnv): the scripted
  helmsman's choices round the course, or `actions` replayed from `start` (the last one
  held for one more control step, should the episode not have ended)."""
  from hpg_mj.worlds import ship_regatta_core as regatta_core
  obs, info = env.reset(seed=seed, options=start)
  course, reach = info["course"], 0.5 * env.layout[1]
  states, passes, chosen, phase, event = [obs[:4]], [], [], 0, None
  for t in range(steps if actions is None else len(actions) + 1):
    if actions is None:
      tx, ty, phase = regatta_core.pilot_target(obs[:4], phase, course, len(passes), reach)
      r = core.pilot_turn_rate(obs[:4], tx, ty)
    else:
      r = actions[min(t, len(actions) - 1)]
    obs, _, terminated, truncated, info = env.step(np.array([r]))
    states.append(obs[:4])
    chosen.append(r)
    event = info["event"]
    if info["gates_passed"] > len(passes):
      passes.append(t)
      phase = 0
    if terminated or truncated:
      break
  return np.array(states), passes, event, chosen


def _judged_passes(course, positions):
  """(the steps at which gates were passed, the last event) of a track, positions (x, y)
  every 0.2 s from its start, by the regatta's rule (`ship_regatta_core.OneShip`)."""
  from hpg_mj.worlds import ship_regatta_core as regatta_core
  one = regatta_core.OneShip(core.STEER_MAX_STEPS)
  one.set_course(course)
  k = core.SAMPLES_PER_CONTROL
  passes, event = [], None
  for t in range((len(positions) - 1) // k):
    code, _, terminated, _ = one(np.ascontiguousarray(positions[t * k:(t + 1) * k + 1]), t + 1)
    event = regatta_core.EVENT_NAMES[code]
    if one.next_gate > len(passes):
      passes.append(t)
    if terminated:
      break
  return passes, event


def _alike(passes, event, reference):
  """Whether a ship passed the reference ship's gates, each within a control step, and
  ended as it did."""
  ref_passes, ref_event = reference
  return (len(passes) == len(ref_passes) and event == ref_event
          and all(abs(a - b) <= 1 for a, b in zip(passes, ref_passes)))


def verify_regatta(episodes=20, seed=0, levels=None):
  """Per level, `episodes` courses sailed by the scripted helmsman on the analytic
  environment; its turning rates replayed on the MuJoCo environment from the same start
  round the same course, and on the continuous ship (`exact_trajectory`), whose track
  the regatta's rule judges too: one RegattaVerification per level."""
  import gymnasium

  import hpg_mj  # noqa: F401  (registers the ids)
  from hpg_mj.worlds import ship_regatta_core as regatta_core
  if episodes < 1:
    raise ValueError(f"episodes must be positive, got {episodes}")
  k = core.SAMPLES_PER_CONTROL
  results = []
  for level in levels or tuple(regatta_core.LEVELS):
    regatta_core.level_layout(level, "hpg-mj verify regatta")
    analytic = gymnasium.make("hpg_mj/ShipRegatta-v0", level=level,
                              backend="analytic").unwrapped
    mujoco = gymnasium.make("hpg_mj/ShipRegatta-v0", level=level, backend="mujoco").unwrapped
    finishes = mujoco_same = euler_same = 0
    worst = np.zeros(3)
    posts_off = 0.0
    for episode in range(episodes):
      states, passes, event, actions = _regatta_episode(analytic, seed * 100_003 + episode)
      course = analytic.course
      start = {"state": states[0], "course": course}
      replay, replay_passes, replay_event, _ = _regatta_episode(mujoco, None, actions, start)
      exact = exact_trajectory(states[0], list(actions) + actions[-1:])
      reference = _judged_passes(course, np.concatenate([states[:1, :2], exact[:, :2]]))
      ends = exact[k - 1::k]                       # the continuous ship at each step's end
      n = min(len(replay), len(states)) - 1
      worst = np.maximum(worst, (*_errors(replay[1:n + 1], ends[:n]),
                                 _errors(states[1:n + 1], ends[:n])[0]))
      finishes += event == "finish"
      mujoco_same += _alike(replay_passes, replay_event, reference)
      euler_same += _alike(passes, event, reference)
      physics = mujoco.backend.physics
      posts = regatta_core.posts_of(course)
      drawn = np.array([[physics.model.ptr.geom_pos[i][:2] for i in ids[:2]]
                        for ids in physics._course_geoms[:len(posts)]])
      posts_off = max(posts_off, float(np.abs(drawn - posts).max()))
    results.append(RegattaVerification(level, episodes, finishes, *worst, mujoco_same,
                                       euler_same, posts_off))
  return results


# ---- `hpg-mj verify harbour`: the harbour's two ships and their rangefinders ----------

@dataclasses.dataclass
class HarbourVerification:
  """What `hpg-mj verify harbour` measured for one level: the two ships' episodes,
  and MuJoCo's rangefinders and obstacles against the rule's closed form."""
  level: str
  episodes: int
  gates: int              # episodes the (blind) helmsman sailed through the gate
  aground: int            # ... that ran aground on an obstacle
  same: int               # MuJoCo episodes ending as the analytic ones, within a step
  largest_m: float        # the two ships apart, largest
  ranges_m: float         # MuJoCo's rangefinders against the closed form at its states
  geoms_m: float          # the MuJoCo obstacles against the rule's shapes

  def line(self):
    """The level's line of the report."""
    return (f"  {self.level:<7} {self.episodes} episodes: gate {self.gates}, aground "
            f"{self.aground}; MuJoCo ends alike {self.same}, ships at most "
            f"{self.largest_m:.3f} m apart; rangefinders off the closed form by "
            f"{self.ranges_m:.1e} m; obstacle geoms off the rule's by {self.geoms_m:.1e} m")

  @property
  def passed(self):
    """The goal task's bounds (ships within 1.5 m, >= 95% alike ends), the rays within
    1e-9 m of the closed form and the geoms at the rule's shapes."""
    return (self.largest_m < 1.5 and self.same >= 0.95 * self.episodes
            and self.ranges_m < 1e-9 and self.geoms_m < 1e-9)


def _harbour_episode(env, seed, actions=None, start=None, steps=1500):
  """(observations, events, turning rates) of one episode of `env` (a ShipHarbourEnv):
  the steering task's helmsman (blind to the obstacles), or `actions` replayed (the
  last held for one more control step, should the episode not have ended)."""
  obs, _ = env.reset(seed=seed, options=start)
  rows, events, chosen, phase = [obs], [None], [], 0
  for t in range(steps if actions is None else len(actions) + 1):
    if actions is None:
      tx, ty, phase = core.gate_pilot_target(obs[:4], phase)
      r = core.pilot_turn_rate(obs[:4], tx, ty)
    else:
      r = actions[min(t, len(actions) - 1)]
    obs, _, terminated, truncated, info = env.step(np.array([r]))
    rows.append(obs)
    events.append(info["event"])
    chosen.append(r)
    if terminated or truncated:
      break
  return np.array(rows), events, chosen


def verify_harbour(episodes=20, seed=0, levels=None):
  """Per level, `episodes` episodes of the steering task's helmsman on the analytic
  harbour, its turning rates replayed on the MuJoCo harbour from the same start: their
  ends, the ships apart, MuJoCo's rangefinders against the closed-form rays at the
  MuJoCo ship's states, and the obstacle geoms against the rule's shapes."""
  import gymnasium

  import hpg_mj  # noqa: F401  (registers the ids)
  from hpg_mj.worlds import ship_harbour_core as harbour_core
  from hpg_mj.worlds import ship_model
  if episodes < 1:
    raise ValueError(f"episodes must be positive, got {episodes}")
  results = []
  for level in levels or tuple(harbour_core.LEVELS):
    harbour_core.level_obstacles(level, "hpg-mj verify harbour")
    analytic = gymnasium.make("hpg_mj/ShipHarbour-v0", level=level,
                              backend="analytic").unwrapped
    mujoco = gymnasium.make("hpg_mj/ShipHarbour-v0", level=level, backend="mujoco").unwrapped
    one = harbour_core.OneShip(level, core.STEER_MAX_STEPS)
    counts, largest, ranges = collections.Counter(), 0.0, 0.0
    for episode in range(episodes):
      rows, events, actions = _harbour_episode(analytic, seed * 100_003 + episode)
      replay, replay_events, _ = _harbour_episode(mujoco, None, actions,
                                                  {"state": rows[0, :4]})
      n = min(len(rows), len(replay))
      largest = max(largest, float(np.hypot(*(rows[:n, :2] - replay[:n, :2]).T).max()))
      closed = np.array([one.observe(np.ascontiguousarray(o[:4]))[4:] for o in replay])
      ranges = max(ranges, float(np.abs(closed - replay[:, 4:]).max()))
      counts[events[-1]] += 1
      counts["same"] += (abs(len(replay) - len(rows)) <= 1
                         and replay_events[-1] == events[-1])
    model = mujoco.backend.physics.model.ptr
    islands, piers = harbour_core.level_shapes(level)
    island_ids, pier_ids = ship_model.harbour_obstacle_geoms(model, level)
    drawn = [np.abs(model.geom_pos[i][:2] - row[:2]).max() for i, row in
             zip(island_ids + pier_ids, list(islands) + list(piers))]
    drawn += [abs(model.geom_size[i][0] - row[2]) for i, row in zip(island_ids, islands)]
    drawn += [np.abs(model.geom_size[i][:2] - row[4:]).max() for i, row in zip(pier_ids, piers)]
    results.append(HarbourVerification(level, episodes, counts["gate"], counts["obstacle"],
                                       counts["same"], largest, ranges, float(max(drawn))))
  return results
