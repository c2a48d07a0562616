"""`hpg-mj verify ship`: the two ships against the continuous ODE (SPEC section 1).

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
  controls: int
  starts: int
  seconds_per_start: float
  mujoco_position_m: float
  mujoco_heading_deg: float
  euler_position_m: float
  euler_heading_deg: float
  mujoco_timestep_s: float

  def lines(self):
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
