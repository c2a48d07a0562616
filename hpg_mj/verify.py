"""`hpg-mj verify ship`: the two ships against the continuous ODE (SPEC section 1);
`hpg-mj verify current`: the two ships in each level's current, likewise;
`hpg-mj verify goal`, `hpg-mj verify regatta`: the two ships' episodes of those tasks;
`hpg-mj verify golden`: the stored golden trajectories of every task, replayed.

The continuous ship: d(theta_dot)/dt = (r - theta_dot)/T, d(theta)/dt = theta_dot,
dx/dt = V sin(theta), dy/dt = V cos(theta), with r held over each control.
Heading and turning rate have a closed form; the position is its integral,
taken with 24-point Gauss-Legendre quadrature on every 0.2 s interval (the
integrand is smooth, so this is exact to rounding).
"""
import dataclasses

import numpy as np

from hpg_mj.worlds import ship
from hpg_mj.worlds import ship_core as core

_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(24)

# SPEC section 1's verification bounds: the MuJoCo ship within these of the continuous
# ship (and the MJX ship of hpg_mj.jax.mjx_ship within them of the MuJoCo ship).
POSITION_BOUND_M = 0.25
HEADING_BOUND_DEG = 0.25


def exact_trajectory(state, controls, speed=core.SPEED, time_constant=core.TIME_CONSTANT,
                     dt=core.SAMPLING_INTERVAL, samples_per_control=core.SAMPLES_PER_CONTROL):
  """States [x, y, theta_deg (unwrapped), theta_dot_deg] at every sampling instant."""
  x, y, theta, theta_dot = (float(v) for v in state)
  t = (_NODES + 1.0) * dt / 2.0
  w = _WEIGHTS * dt / 2.0
  decay_t = time_constant * (1.0 - np.exp(-t / time_constant))
  decay_dt = time_constant * (1.0 - np.exp(-dt / time_constant))
  out = np.empty((len(controls) * samples_per_control, 4))
  row = 0
  for r in controls:
    for _ in range(samples_per_control):
      heading = np.radians(theta + r * t + (theta_dot - r) * decay_t)
      x += speed * np.dot(w, np.sin(heading))
      y += speed * np.dot(w, np.cos(heading))
      theta += r * dt + (theta_dot - r) * decay_dt
      theta_dot = r + (theta_dot - r) * np.exp(-dt / time_constant)
      out[row] = (x, y, theta, theta_dot)
      row += 1
  return out


def euler_trajectory(state, controls):
  """The analytic ship (Equation 1) sampled every 0.2 s."""
  s = np.array(state, dtype=np.float64)
  out = []
  for r in controls:
    for _ in range(core.SAMPLES_PER_CONTROL):
      core.euler_sample(s, r, core.SPEED, core.TIME_CONSTANT, core.SAMPLING_INTERVAL)
      out.append(s.copy())
  return np.array(out)


def mujoco_trajectory(state, controls, physics=None):
  """The MJCF ship sampled every 0.2 s (the position at each sample, the heading
  and turning rate at the end of each control)."""
  physics = physics or ship.Physics.from_xml_string(*ship.get_model_and_assets())
  physics.set_ship_state(state)
  substeps = physics._substeps_per_sample()
  out = []
  for r in controls:
    physics.set_turn_command(r)
    for _ in range(core.SAMPLES_PER_CONTROL):
      physics.step(substeps)
      out.append(physics.ship_state())
  return np.array(out)


def _errors(trajectory, reference):
  position = np.hypot(trajectory[:, 0] - reference[:, 0], trajectory[:, 1] - reference[:, 1])
  heading = np.abs(core.wrap_deg_array(trajectory[:, 2] - reference[:, 2]))
  return float(position.max()), float(heading.max())


@dataclasses.dataclass
class ShipVerification:
  """What `hpg-mj verify ship` measured: the two ships' largest errors against the
  continuous ODE."""
  controls: int
  starts: int
  seconds_per_start: float
  mujoco_position_m: float
  mujoco_heading_deg: float
  euler_position_m: float
  euler_heading_deg: float
  mujoco_timestep_s: float

  def lines(self):
    """Its report, as printed."""
    return [
        f"ship verification: {self.starts} random starts x {self.controls} random controls "
        f"(r uniform on [-15, 15] deg/s, each held 0.6 s: {self.seconds_per_start:.0f} s of "
        "sailing per start), against the continuous ODE",
        f"  MuJoCo ship (timestep {self.mujoco_timestep_s} s): max position error "
        f"{self.mujoco_position_m:.4f} m, max heading error {self.mujoco_heading_deg:.4f} deg",
        f"  analytic ship (Euler, 0.2 s): max position error {self.euler_position_m:.4f} m, "
        f"max heading error {self.euler_heading_deg:.4f} deg",
        f"  MuJoCo / Euler position error: {self.mujoco_position_m / self.euler_position_m:.3f}",
    ]


def verify_ship(controls=1000, starts=3, seed=0):
  """Largest errors of both ships against the continuous solution."""
  if controls < 1 or starts < 1:
    raise ValueError(f"controls and starts must be positive, got {controls} and {starts}")
  rng = np.random.default_rng(seed)
  rules = ship.ShipRules("steer")
  physics = ship.Physics.from_xml_string(*ship.get_model_and_assets())
  worst = np.zeros(4)
  for _ in range(starts):
    start = rules.sample_start(rng)
    rs = rng.uniform(-core.MAX_TURN_RATE, core.MAX_TURN_RATE, controls)
    reference = exact_trajectory(start, rs)
    mj_err = _errors(mujoco_trajectory(start, rs, physics), reference)
    eu_err = _errors(euler_trajectory(start, rs), reference)
    worst = np.maximum(worst, (*mj_err, *eu_err))
  return ShipVerification(controls, starts, controls * core.CONTROL_INTERVAL, *worst,
                          mujoco_timestep_s=float(physics.model.opt.timestep))


# ---- `hpg-mj verify golden`: the stored trajectories of every task ------------------
#
# golden/*.npz (shipped in the wheel as hpg_mj.golden) hold, per task, a fixed action
# sequence and what the task answered when they were made: the ship on the analytic
# path (Gymnasium, numba) and on MuJoCo (dm_control), the taxi on its dm_control
# board. Replaying them against the installed mujoco, dm_control and numba shows
# whether an upgrade changed the physics or the rules. Regenerate them only when a
# rule changes on purpose: tests/golden/make_golden_ship.py, make_golden_taxi.py.

GOLDEN_SEED = 123        # the ship tasks' seed
GOLDEN_STEPS = 80        # the ship's control steps
# MuJoCo's arithmetic may differ in the last bits across CPUs and builds; a change
# of integrator, actuation or model moves these trajectories by far more.
MUJOCO_TOLERANCE = 1e-6
SHIP_GYMNASIUM_IDS = {"steer": "hpg_mj/ShipSteering-v0",
                      "diagonal": "hpg_mj/ShipSteeringDiagonal-v0",
                      "straight": "hpg_mj/ShipSteeringStraight-v0",
                      "patrol": "hpg_mj/ShipPatrol-v0"}
# The other ship domains, whose tasks are levels: domain -> its Gymnasium id (`level=`).
SHIP_LEVEL_IDS = {"ship_current": "hpg_mj/ShipCurrent-v0", "ship_goal": "hpg_mj/ShipGoal-v0",
                  "ship_regatta": "hpg_mj/ShipRegatta-v0"}


def _flat(obs):
  """An observation as one row: a goal-conditioned dictionary's parts in key order."""
  if isinstance(obs, dict):
    return np.concatenate([np.ravel(obs[key]) for key in sorted(obs)])
  return obs


def _ship_gymnasium(domain, task):
  """(Gymnasium id, make() arguments) of a ship domain's task, on the analytic ship."""
  if domain == "ship":
    return SHIP_GYMNASIUM_IDS[task], {"backend": "analytic"}
  return SHIP_LEVEL_IDS[domain], {"backend": "analytic", "level": task}


def golden_dir():
  """The folder of the golden trajectories: installed, else the checkout's."""
  import pathlib
  here = pathlib.Path(__file__).resolve().parent
  for folder in (here / "golden", here.parent / "golden"):
    if folder.is_dir():
      return folder
  raise FileNotFoundError(f"no golden trajectories beside {here}: reinstall hpg_mj")


# The continuing task's defining events, a gate pass and a restart after leaving the
# field, lie hundreds of metres apart: its golden trajectory starts 10 m south of the
# gate heading almost west, sails straight (r = 0) through the gate and on out of
# the field, and after the restart turns as the other tasks' do.
SHIP_GOLDEN_STARTS = {"patrol": (440.0, 390.15, -80.0, 0.0)}
# The goal tasks' first episode sails from 9.85 m south of a gate at (400, 400) heading
# north straight through it (its pass is the episode's end at the sixth step); the
# episodes after it draw their starts and gates.
GOAL_GOLDEN_FIRST = {"state": (400.0, 390.15, 0.0, 0.0), "gate": (400.0, 400.0, 0.0)}
PATROL_GOLDEN_STRAIGHT = 260     # control steps at r = 0 before the random turns


def regatta_golden_first(level):
  """The regatta's first golden episode (reset options): the level's course laid out by
  a generator seeded with GOLDEN_SEED, the ship 9.85 m before its first gate heading
  with it (its pass is the sixth step's, and the episode sails on); the episodes after
  it draw their starts and courses."""
  from hpg_mj.worlds import ship_regatta_core as regatta_core
  course = regatta_core.sample_course(np.random.default_rng(GOLDEN_SEED),
                                      regatta_core.level_layout(level))
  x, y, heading = course[0]
  rad = np.radians(heading)
  return {"state": (x - 9.85 * np.sin(rad), y - 9.85 * np.cos(rad), heading, 0.0),
          "course": course}


def _golden_first(domain, task):
  """The reset options of a ship domain's first golden episode (None: drawn)."""
  if domain == "ship_goal":
    return GOAL_GOLDEN_FIRST
  if domain == "ship_regatta":
    return regatta_golden_first(task)
  if domain == "ship" and task in SHIP_GOLDEN_STARTS:
    return {"state": SHIP_GOLDEN_STARTS[task]}
  return None


def ship_golden_actions(task=None):
  """The fixed turning rates of a ship task's golden trajectory."""
  turns = np.random.default_rng(7).uniform(-15.0, 15.0, (GOLDEN_STEPS, 1))
  if task == "patrol":
    return np.concatenate([np.zeros((PATROL_GOLDEN_STRAIGHT, 1)), turns])
  return turns


def ship_analytic_rollout(task, actions=None, domain="ship"):
  """(observations, rewards, ends) of the analytic ship through Gymnasium; ends:
  0 going on, 1 truncated, 2 terminated (then reset)."""
  import gymnasium

  import hpg_mj  # noqa: F401  (registers the ids)
  env_id, kwargs = _ship_gymnasium(domain, task)
  env = gymnasium.make(env_id, **kwargs).unwrapped
  obs, _ = env.reset(seed=GOLDEN_SEED, options=_golden_first(domain, task))
  rows, rewards, ends = [_flat(obs)], [], []
  for a in ship_golden_actions(task) if actions is None else actions:
    obs, reward, terminated, truncated, _ = env.step(a)
    rewards.append(reward)
    ends.append(2 * terminated + truncated)
    if terminated or truncated:
      obs, _ = env.reset()
    rows.append(_flat(obs))
  return np.array(rows), np.array(rewards), np.array(ends)


def ship_mujoco_rollout(task, actions=None, domain="ship"):
  """The same on the MuJoCo ship through the dm_control suite."""
  from hpg_mj import suite
  kwargs = {"random": GOLDEN_SEED}
  first = _golden_first(domain, task)
  if domain == "ship_goal":
    kwargs.update(initial_state=first["state"], gate=first["gate"])
  elif domain == "ship_regatta":
    kwargs.update(initial_state=first["state"], course=first["course"])
  elif domain == "ship":
    kwargs["initial_state"] = SHIP_GOLDEN_STARTS.get(task)
  env = suite.load(domain, task, kwargs)
  flat = lambda ts: np.concatenate([np.ravel(v) for v in ts.observation.values()])  # noqa: E731
  ts = env.reset()
  if domain == "ship_goal":                    # the first episode only
    env.task.initial_state = env.task.gate = None
  elif domain == "ship_regatta":
    env.task.initial_state = env.task.course = None
  rows, rewards, ends = [flat(ts)], [], []
  for a in ship_golden_actions(task) if actions is None else actions:
    ts = env.step(a)
    rewards.append(ts.reward)
    ends.append(0 if not ts.last() else (2 if ts.discount == 0.0 else 1))
    if ts.last():
      ts = env.reset()
    rows.append(flat(ts))
  return np.array(rows), np.array(rewards), np.array(ends)


def taxi_trajectory(task_name, actions, seed):
  """The taxi's dm_control board under `actions` (dm_control resets on the step
  after LAST, ignoring that step's action): observations, rewards, discounts,
  step types."""
  from hpg_mj.worlds import taxi
  env = getattr(taxi, task_name)(random=seed)
  time_steps = [env.reset()]
  for action in actions:
    time_steps.append(env.step(action))
  record = {f"obs_{k}": np.stack([ts.observation[k] for ts in time_steps])
            for k in time_steps[0].observation}
  record["reward"] = np.array([np.nan if ts.reward is None else ts.reward for ts in time_steps])
  record["discount"] = np.array([np.nan if ts.discount is None else ts.discount
                                 for ts in time_steps])
  record["step_type"] = np.array([int(ts.step_type) for ts in time_steps], dtype=np.int64)
  return record


def _deviation(got, want):
  """Largest absolute difference (NaN where both are NaN counts as equal; a shape
  or NaN mismatch as infinite)."""
  got, want = np.asarray(got, dtype=np.float64), np.asarray(want, dtype=np.float64)
  if got.shape != want.shape or not np.array_equal(np.isnan(got), np.isnan(want)):
    return float("inf")
  both = ~np.isnan(want)
  return float(np.max(np.abs(got[both] - want[both]), initial=0.0))


@dataclasses.dataclass
class GoldenCheck:
  """One stored golden trajectory replayed on one path: its largest deviation."""
  task: str                 # "ship/steer"
  path: str                 # "analytic (Gymnasium)", "MuJoCo (dm_control)"
  deviation: float          # largest over observations and rewards
  tolerance: float
  events_match: bool        # episode ends (and discounts, step types) exactly as stored
  problem: str = ""         # why it could not be checked at all

  @property
  def passed(self):
    """Whether it was checked, its episode ends match and it is within tolerance."""
    return not self.problem and self.events_match and self.deviation <= self.tolerance

  def line(self):
    """Its report line, as printed."""
    what = f"{self.task:<14} {self.path:<22}"
    if self.problem:
      return f"{what} FAIL  {self.problem}"
    tolerance = "exact" if self.tolerance == 0 else f"{self.tolerance:g}"
    events = "" if self.events_match else ", episode ends differ"
    return (f"{what} {'pass' if self.passed else 'FAIL'}  largest deviation "
            f"{self.deviation:.3g} (tolerance {tolerance}){events}")


def _check_ship(task, golden, domain="ship"):
  rows = []
  obs, rewards, ends = ship_analytic_rollout(task, golden["actions"], domain)
  rows.append(GoldenCheck(f"{domain}/{task}", "analytic (Gymnasium)",
                          max(_deviation(obs, golden["analytic_obs"]),
                              _deviation(rewards, golden["analytic_rewards"])), 0.0,
                          np.array_equal(ends, golden["analytic_ends"])))
  obs, rewards, ends = ship_mujoco_rollout(task, golden["actions"], domain)
  rows.append(GoldenCheck(f"{domain}/{task}", "MuJoCo (dm_control)",
                          max(_deviation(obs, golden["mujoco_obs"]),
                              _deviation(rewards, golden["mujoco_rewards"])), MUJOCO_TOLERANCE,
                          np.array_equal(ends, golden["mujoco_ends"])))
  return rows


def _check_taxi(task, golden):
  got = taxi_trajectory(task, golden["actions"], int(golden["seed"]))
  names = sorted(k for k in golden.files if k.startswith("obs_"))
  if sorted(k for k in got if k.startswith("obs_")) != names:
    return [GoldenCheck(f"taxi/{task}", "dm_control", float("inf"), 0.0, False,
                        f"observations {sorted(got)} differ from the stored {names}")]
  deviation = max(_deviation(got[k], golden[k]) for k in names + ["reward"])
  events = (np.array_equal(got["step_type"], golden["step_type"])
            and _deviation(got["discount"], golden["discount"]) == 0.0)
  return [GoldenCheck(f"taxi/{task}", "dm_control", deviation, 0.0, events)]


def verify_golden():
  """Replays the golden trajectory of every task of the dm_control suite (the ship's
  also on its analytic Gymnasium path); one GoldenCheck per task and path."""
  from hpg_mj import suite
  folder = golden_dir()
  checks = []
  for domain, task in suite.ALL_TASKS:
    path = folder / f"{domain}_{task}.npz"
    if not path.is_file():
      checks.append(GoldenCheck(f"{domain}/{task}", "-", float("inf"), 0.0, False,
                                f"no golden trajectory stored ({path.name})"))
      continue
    try:
      with np.load(path, allow_pickle=False) as golden:
        checks += (_check_taxi(task, golden) if domain == "taxi"
                   else _check_ship(task, golden, domain))
    except Exception as err:  # noqa: BLE001  (a failed replay is a failed check, named)
      checks.append(GoldenCheck(f"{domain}/{task}", "-", float("inf"), 0.0, False,
                                f"replay failed: {type(err).__name__}: {err}"))
  return checks


def golden_versions():
  """The versions the replay ran against, for its header line."""
  from hpg_mj import provenance
  v = provenance.versions()
  return ", ".join(f"{k} {v[k]}" for k in ("mujoco", "dm_control", "numba", "numpy", "gymnasium"))


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

  def line(self):
    """Its report line, as printed."""
    return (f"  {self.level:<7} {self.episodes} episodes: helmsman passed "
            f"{self.analytic_passes}; same end within a step on both ships "
            f"{self.same_outcome}; MuJoCo vs analytic position at most "
            f"{self.largest_position_m:.3f} m; MuJoCo gate posts off the rule's by "
            f"{self.gate_geoms_m:.1e} m")

  @property
  def passed(self):
    """The ships differ by their discretisations only (the analytic ship strays about
    1 m from the continuous one in 600 s, `hpg-mj verify ship`; MuJoCo's 0.04 m), the
    MuJoCo gate stands where the rule's is, and at most one episode in 20 ends
    differently. A pass is seen one control step earlier or later when the ships are a
    metre apart along the track (the window is 1.8 m deep): that counts as the same end."""
    return (self.largest_position_m < 1.5 and self.gate_geoms_m < 1e-9
            and self.same_outcome >= 0.95 * self.episodes)


def _goal_episode(env, seed, actions=None, start=None, steps=2000):
  """(states, events, actions) of one episode of `env` (a ShipGoalEnv): the scripted
  helmsman's choices, or `actions` replayed from `start` (and the last one held for
  one more control step, should the episode not have ended)."""
  from hpg_mj.worlds import ship_goal_core as goal_core
  obs, _ = env.reset(seed=seed, options=start)
  states, events, chosen, phase = [obs["observation"]], [None], [], 0
  for t in range(steps if actions is None else len(actions) + 1):
    if actions is None:
      tx, ty, phase = goal_core.pilot_target(obs["observation"], phase, obs["desired_goal"])
      r = core.pilot_turn_rate(obs["observation"], tx, ty)
    else:
      r = actions[min(t, len(actions) - 1)]
    obs, _, terminated, truncated, info = env.step(np.array([r]))
    states.append(obs["observation"])
    events.append(info["event"])
    chosen.append(r)
    if terminated or truncated:
      break
  return np.array(states), events, chosen


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
    passes = same = 0
    largest = posts_off = 0.0
    for episode in range(episodes):
      states, events, actions = _goal_episode(analytic, seed * 100_003 + episode)
      desired = analytic._desired
      start = {"state": states[0], "gate": [desired[0], desired[1],
                                            goal_core.gate_heading_deg(desired)]}
      replay, replay_events, _ = _goal_episode(mujoco, None, actions, start)
      n = min(len(states), len(replay))
      largest = max(largest, float(np.hypot(*(states[:n, :2] - replay[:n, :2]).T).max()))
      passes += events[-1] == "gate"
      same += abs(len(replay) - len(states)) <= 1 and replay_events[-1] == events[-1]
      drawn = np.array([mujoco.backend.physics.named.model.geom_pos[name][:2]
                        for name in ("gate_post_west", "gate_post_east")])
      posts_off = max(posts_off, float(np.abs(drawn - goal_core.gate_posts(
          analytic._desired)).max()))
    results.append(GoalVerification(level, episodes, passes, same, largest, posts_off))
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
