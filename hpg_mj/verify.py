"""`hpg-mj verify ship`: the two ships against the continuous ODE (SPEC section 1);
`hpg-mj verify golden`: the stored golden trajectories of every task, replayed. The
task ladder's checks (`verify current`, `goal`, `regatta`, `harbour`) are
`hpg_mj.verify_ladder`'s.

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
                  "ship_regatta": "hpg_mj/ShipRegatta-v0", "ship_harbour": "hpg_mj/ShipHarbour-v0"}


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
# The goal tasks' first episode sails from 9.85 m south of a gate at (560, 600) heading
# north straight through it (its pass is the episode's end at the sixth step; a gate
# clear of the hard level's obstacles); the episodes after it draw their starts and gates.
GOAL_GOLDEN_FIRST = {"state": (560.0, 590.15, 0.0, 0.0), "gate": (560.0, 600.0, 0.0)}
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


def harbour_golden_first(level):
  """The harbour's first golden episode (reset options): 12 m south of the level's first
  island heading north, into it (the episode runs aground on it; those after it draw
  their starts)."""
  from hpg_mj.worlds import ship_harbour_core as harbour_core
  x, y, radius = harbour_core.level_obstacles(level)[0][0]
  return {"state": (x, y - radius - 12.0, 0.0, 0.0)}


def _golden_first(domain, task):
  """The reset options of a ship domain's first golden episode (None: drawn)."""
  if domain == "ship_harbour":
    return harbour_golden_first(task)
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
  elif domain == "ship_harbour":
    kwargs["initial_state"] = first["state"]
  elif domain == "ship":
    kwargs["initial_state"] = SHIP_GOLDEN_STARTS.get(task)
  env = suite.load(domain, task, kwargs)
  flat = lambda ts: np.concatenate([np.ravel(v) for v in ts.observation.values()])  # noqa: E731
  ts = env.reset()
  if domain == "ship_goal":                    # the first episode only
    env.task.initial_state = env.task.gate = None
  elif domain == "ship_regatta":
    env.task.initial_state = env.task.course = None
  elif domain == "ship_harbour":
    env.task.initial_state = None
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
