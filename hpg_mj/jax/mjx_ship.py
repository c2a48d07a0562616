"""The MuJoCo ship (SPEC section 1, assets/ship.xml) stepped by MJX, MuJoCo's JAX
port (`pip install "hpg_mj[mjx]"`): batches of ships jitted and vmapped, on a GPU
where JAX has one.

```python
ship = mjx_ship.MjxShip()
final, states = ship.rollout(starts, controls)   # starts (n, 4), controls (steps, n)
```

The model is the MuJoCo backend's own, read from the shipped MJCF, and a ship is
driven as that backend drives it (`hpg_mj.worlds.ship_model.ShipPhysics` under the
dm_control task): a start set as `set_ship_state` sets it, a turning rate clipped to
[-15, 15] deg/s as the task clips it (`ShipTask.before_step`, not strict) and put on
both rudders, held over a control of 0.6 s (`core.CONTROL_INTERVAL`: 3 samples of
0.2 s, each `substeps` MuJoCo steps of the model's timestep), and the state read as
`bow_readings` reads it: the bow site's position, the heading wrapped to [-180, 180)
and the turning rate, the lead rudder's activation. The MuJoCo ship stays the
reference: `tests/jax/test_jax_mjx_ship.py` holds this one equal to its `mj_step`.

What MJX 3.17.0 lacks, and what is done about it (nothing else is changed):

- `mjx.put_model` refuses any model with a geom pair that has no MJX collision
  function (here the hull's cylinder against the boxes of the field's bounds), even
  when the model disables contact as the ship's does (`<flag contact="disable">`).
  The model given to MJX has every geom's `contype` and `conaffinity` set to 0
  (`mjx_model`): with contact disabled MuJoCo never reads them, so its steps are
  the same to the bit.
- MJX's JAX step reads `actuator_actearly` into its Model but never uses it: every
  actuator pushes with its activation at the start of the step. The ship's lead
  rudder is `actearly` (its pair with the lag rudder makes the heading's
  trapezoidal rule, assets/ship.xml); without it the MJX ship drifts 6.8 m and 1.0
  deg from the MuJoCo ship in 180 s. `step` does what MuJoCo does for it
  (`mj_fwdActuation`'s `mj_nextActivation`): before `mjx.step` the slot of each
  `actearly` activation holds its next value, and after it that value again, which
  is where MuJoCo's step leaves it (MJX would have advanced it once more).
"""
import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from hpg_mj import _assets
from hpg_mj.jax.ship import wrap_deg
from hpg_mj.worlds import ship_core as core

try:        # the module imports without MJX (the API reference reads it); MjxShip needs it
  from mujoco import mjx
except ImportError:
  mjx = None

RUDDERS = ("rudder_lead", "rudder_lag")   # the actuators the turning rate drives
# Activation dynamics whose next value `step` computes for an `actearly` actuator.
_EARLY_DYNAMICS = (mujoco.mjtDyn.mjDYN_INTEGRATOR, mujoco.mjtDyn.mjDYN_FILTER,
                   mujoco.mjtDyn.mjDYN_FILTEREXACT)


def mjx_model(xml=None):
  """The `mujoco.MjModel` of the ship (`xml`, assets/ship.xml when None) as MJX takes
  it: contact disabled, so every geom's contype and conaffinity 0 (the module's
  docstring says why). Raises ValueError where the model collides, and
  NotImplementedError for an `actearly` actuator whose dynamics `step` cannot
  advance early."""
  model = mujoco.MjModel.from_xml_string(_assets.read_model("ship.xml") if xml is None else xml)
  if not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT:
    raise ValueError("the ship model given to MJX must disable contact (<flag "
                     "contact=\"disable\"/>): its geoms' contype and conaffinity are cleared")
  for i in np.flatnonzero(model.actuator_actearly):
    dyntype = mujoco.mjtDyn(model.actuator_dyntype[i])
    if dyntype not in _EARLY_DYNAMICS:
      raise NotImplementedError(
          f"actuator {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i)!r} is actearly "
          f"with dyntype {dyntype.name}; MJX ignores actearly and hpg_mj.jax.mjx_ship advances "
          f"only {[d.name for d in _EARLY_DYNAMICS]} early")
  model.geom_contype[:] = 0
  model.geom_conaffinity[:] = 0
  return model


class MjxShip:
  """The MuJoCo ship in MJX: one ship's functions (`make_data`, `step`, `control`,
  `ship_state`), pure and vmappable, and `rollout`, a batch jitted. States are
  rows [x, y, theta_deg, theta_dot_deg] (metres, degrees, deg/s), as the MuJoCo
  ship's `ship_state()`. The floats are JAX's: float32 by default, float64 after
  `jax.config.update("jax_enable_x64", True)` (before building the ship)."""

  def __init__(self, xml=None):
    if mjx is None:
      raise ImportError("hpg_mj.jax.mjx_ship needs MJX, which is not installed: "
                        'pip install "hpg_mj[mjx]" (mujoco-mjx==3.17.0, mujoco\'s version)')
    self.mj_model = mjx_model(xml)
    self.model = mjx.put_model(self.mj_model)
    m = self.mj_model
    ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, name) for name in RUDDERS]
    if min(ids) < 0:
      raise ValueError(f"the ship model has no actuators {list(RUDDERS)}")
    self.rudders = np.array(ids)
    self.bow = float(m.site_pos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "bow"), 1])
    substeps = core.SAMPLING_INTERVAL / m.opt.timestep   # as ShipPhysics._substeps_per_sample
    self.substeps = int(round(substeps))
    if self.substeps < 1 or abs(self.substeps - substeps) > 1e-9:
      raise ValueError(f"ship model timestep {m.opt.timestep} s must divide the "
                       f"{core.SAMPLING_INTERVAL} s sampling interval")
    # The activation slots of the actearly actuators, with what their next value needs.
    early = np.flatnonzero((m.actuator_actearly != 0) & (m.actuator_actnum > 0))
    self._early = early
    self._early_slots = m.actuator_actadr[early] + m.actuator_actnum[early] - 1
    self._template = mjx.make_data(self.model)
    self._rollout = None

  def make_data(self, state):
    """One ship's `mjx.Data` at `state` [x, y, theta_deg, theta_dot_deg], sailing at V:
    `ShipPhysics.set_ship_state` (the joint origin behind the bow, both rudders'
    activation and command the turning rate)."""
    state = jnp.asarray(state, dtype=self._template.qpos.dtype)
    theta = jnp.radians(state[2])
    sin, cos = jnp.sin(theta), jnp.cos(theta)
    data = self._template
    return data.replace(
        qpos=jnp.stack([state[0] - self.bow * sin, state[1] - self.bow * cos, theta]),
        qvel=jnp.stack([core.SPEED * sin, core.SPEED * cos, jnp.radians(state[3])]),
        act=jnp.full_like(data.act, state[3]),
        ctrl=data.ctrl.at[self.rudders].set(state[3]))

  def ship_state(self, data):
    """[x, y, theta_deg, theta_dot_deg] of one ship: `ship_model.bow_readings`."""
    x, y, theta = data.qpos[0], data.qpos[1], data.qpos[2]
    return jnp.stack([x + self.bow * jnp.sin(theta), y + self.bow * jnp.cos(theta),
                      wrap_deg(jnp.degrees(theta)), data.act[0]])

  def _next_activation(self, data):
    """The next value of the actearly actuators' activations, as `mj_nextActivation`
    advances them from the clamped control (MJX's `_next_activation`, for these)."""
    m, i = self.mj_model, self._early
    ctrl = data.ctrl[i]
    if not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL:
      ctrl = jnp.where(m.actuator_ctrllimited[i], jnp.clip(ctrl, m.actuator_ctrlrange[i, 0],
                                                           m.actuator_ctrlrange[i, 1]), ctrl)
    act = data.act[self._early_slots]
    tau = np.maximum(m.actuator_dynprm[i, 0], mujoco.mjMINVAL)
    dyntype = m.actuator_dyntype[i]
    filtered = (dyntype == mujoco.mjtDyn.mjDYN_FILTER) | (dyntype == mujoco.mjtDyn.mjDYN_FILTEREXACT)
    act_dot = np.where(filtered, 0.0, 1.0) * ctrl + np.where(filtered, 1.0 / tau, 0.0) * (ctrl - act)
    step = np.where(dyntype == mujoco.mjtDyn.mjDYN_FILTEREXACT,
                    tau * -np.expm1(-m.opt.timestep / tau), m.opt.timestep)
    act = act + act_dot * step
    return jnp.where(m.actuator_actlimited[i], jnp.clip(act, m.actuator_actrange[i, 0],
                                                        m.actuator_actrange[i, 1]), act)

  def step(self, data):
    """One MuJoCo step (`mj_step`) of one ship: `mjx.step` with the actearly
    activations MJX lacks put in place (the module's docstring)."""
    if not len(self._early):
      return mjx.step(self.model, data)
    early = self._next_activation(data)
    data = mjx.step(self.model, data.replace(act=data.act.at[self._early_slots].set(early)))
    return data.replace(act=data.act.at[self._early_slots].set(early))

  def control(self, data, r_deg):
    """One control step of one ship: the turning rate `r_deg` clipped to [-15, 15] deg/s
    and put on both rudders, then 0.6 s of MuJoCo steps. Returns the data and the
    ship's state at each of its three 0.2 s samples, shape (3, 4)."""
    r = jnp.clip(r_deg, -core.MAX_TURN_RATE, core.MAX_TURN_RATE)
    data = data.replace(ctrl=data.ctrl.at[self.rudders].set(r))

    def sample(data, _):
      data = jax.lax.fori_loop(0, self.substeps, lambda _, d: self.step(d), data)
      return data, self.ship_state(data)
    return jax.lax.scan(sample, data, None, length=core.SAMPLES_PER_CONTROL)

  def sail(self, states, controls):
    """`states` (ships, 4) sailed under `controls` (steps, ships) deg/s, every ship
    vmapped and the steps scanned: a pure function to jit (`rollout` is it jitted).
    Returns the ships' final `mjx.Data` and their sampled states, shape (steps,
    ships, 3, 4)."""
    data = jax.vmap(self.make_data)(states)
    return jax.lax.scan(jax.vmap(self.control), data, controls)

  def rollout(self, states, controls):
    """`sail`, jitted (compiled at the first call for each shape)."""
    if self._rollout is None:
      self._rollout = jax.jit(self.sail)
    return self._rollout(jnp.asarray(states), jnp.asarray(controls))
