"""The goal-conditioned ship in pure JAX (SPEC section 11, `hpg_mj/ShipGoal-v0`),
gymnax's interface.

The steering ship of `hpg_mj.jax.ship` (Equation 1 in still water) and a gate whose
centre and heading are drawn at each reset from the level's ranges; the rule of
`hpg_mj.worlds.ship_goal_core`, written again over jax.numpy, judges the end of
each control step from the goals alone: reached (+100, terminated) when the ship is
between the posts (|lateral| <= 50 m), `0 <= forward < 1.8` m past the gate's line
and heading within 45 degrees of the gate's; off the field (-100, terminated) where
the step ends outside [0, 1000]^2; truncated after 5,000 control steps. In float64
the trajectories, rewards and endings equal the numba world's
(tests/jax/test_jax_ladder.py: 1,000 seeded episodes per level).

The observation is one flat vector of 12, not Gymnasium's dictionary: the
dictionary's three parts one after the other, at the slices `OBSERVATION`,
`ACHIEVED_GOAL` and `DESIRED_GOAL`:

| index | part | what |
|---|---|---|
| 0-3 | `observation` | `[x, y, theta_deg, theta_dot_deg]`, the ship's state |
| 4-7 | `achieved_goal` | `[x, y, sin(theta), cos(theta)]` of the ship |
| 8-11 | `desired_goal` | `[x, y, sin, cos]` of the gate's centre and heading |

One array because gymnax's interface is one: its `Box` space, PureJaxRL's and
rejax's networks and gymnax's wrappers read `observation_space(params).shape`, the
auto-reset of `step` selects the new episode's observation as one array, and
hpg_mj's own JAX learners map a `Box` onto [-1, 1]; a dictionary would need each
of them changed. `split_obs` gives the dictionary back (any batch shape), and
`compute_reward(achieved_goal, desired_goal, params)` is the rule on goals alone,
jittable, for Hindsight Experience Replay written in JAX.
"""
import functools

import jax
import jax.numpy as jnp
import numpy as np

from hpg_mj.jax import environment
from hpg_mj.jax import ship
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_goal_core as goal_core

OBSERVATION = slice(0, 4)      # the ship's state [x, y, theta_deg, theta_dot_deg]
ACHIEVED_GOAL = slice(4, 8)    # the ship's [x, y, sin(theta), cos(theta)]
DESIRED_GOAL = slice(8, 12)    # the gate's [x, y, sin(heading), cos(heading)]


@environment.record
class GoalState(ship.EnvState):
  """The steering ship's `EnvState` and the episode's gate."""
  desired: jax.Array         # (4,): the gate's [x, y, sin(heading), cos(heading)]


@environment.record
class GoalParams(ship.EnvParams):
  """The steering task's `EnvParams` and the level's gate ranges (SPEC section 11,
  `ship_goal_core.LEVELS`): the centre uniform on [gate_low, gate_high] m each way,
  the heading uniform on [-gate_heading_deg, gate_heading_deg); and how exactly it is
  reached (`ship_goal_core.TOLERANCES`): within `half_width` m of the centre across the
  gate, the heading's cosine to the gate's at least `min_cos`."""
  gate_low: float = goal_core.LEVELS[goal_core.DEFAULT_LEVEL][0]
  gate_high: float = goal_core.LEVELS[goal_core.DEFAULT_LEVEL][1]
  gate_heading_deg: float = goal_core.LEVELS[goal_core.DEFAULT_LEVEL][2]
  half_width: float = float(goal_core.STEER_TOLERANCE[0])
  min_cos: float = float(goal_core.STEER_TOLERANCE[1])


def split_obs(obs):
  """Gymnasium's goal-conditioned dictionary of a flat observation (or of a batch of
  them, the last axis 12): `observation`, `achieved_goal`, `desired_goal`."""
  return {"observation": obs[..., OBSERVATION], "achieved_goal": obs[..., ACHIEVED_GOAL],
          "desired_goal": obs[..., DESIRED_GOAL]}


def goal_of(x, y, theta_deg):
  """The achieved goal `[x, y, sin(theta), cos(theta)]` of a ship (`ship_goal_core.goal_of`)."""
  rad = jnp.radians(theta_deg)
  return jnp.stack([x, y, jnp.sin(rad), jnp.cos(rad)])


def reached(achieved, desired, params):
  """`ship_goal_core.reached` over the last axis of goals: the ship between the posts,
  within one control step's sailing past the gate's line, heading within the level's
  tolerance (`params`: 45 degrees, 30 at hard)."""
  ax, ay, asin, acos = (achieved[..., i] for i in range(4))
  dx, dy, dsin, dcos = (desired[..., i] for i in range(4))
  rx, ry = ax - dx, ay - dy
  forward = rx * dsin + ry * dcos
  lateral = rx * dcos - ry * dsin
  return ((0.0 <= forward) & (forward < goal_core.WINDOW)
          & (jnp.abs(lateral) <= params.half_width)
          & (asin * dsin + acos * dcos >= params.min_cos))


def outcome_of(achieved, desired, params):
  """`ship_goal_core.outcome_of` over the last axis of goals: (event, reward), SUCCESS
  and -1 + `gate_reward` at the gate, FAILURE and -1 + `out_of_bounds_reward` off the
  field, else NO_EVENT and -1."""
  ax, ay = achieved[..., 0], achieved[..., 1]
  at_gate = reached(achieved, desired, params)
  off = (ax < 0.0) | (ax > core.FIELD_SIZE) | (ay < 0.0) | (ay > core.FIELD_SIZE)
  event = jnp.where(at_gate, core.SUCCESS, jnp.where(off, core.FAILURE, core.NO_EVENT))
  step = jnp.asarray(core.STEP_REWARD, achieved.dtype)
  reward = jnp.where(at_gate, step + params.gate_reward,
                     jnp.where(off, step + params.out_of_bounds_reward, step))
  return event.astype(jnp.int32), reward.astype(achieved.dtype)


def compute_reward(achieved_goal, desired_goal, params):
  """The reward of achieved and desired goals of any (broadcast) batch shape, the last
  axis 4 (`ShipGoalEnv.compute_reward`): what Hindsight Experience Replay asks of
  relabelled goals. Jittable."""
  achieved, desired = jnp.broadcast_arrays(jnp.asarray(achieved_goal), jnp.asarray(desired_goal))
  return outcome_of(achieved, desired, params)[1]


class ShipGoal(ship.ShipSteering):
  """`hpg_mj/ShipGoal-v0` as a gymnax environment: the steering ship and a gate drawn
  at each reset from the ranges of `level` ("easy", "medium" or "hard"; they give
  the default `GoalParams`). Observation a flat vector of 12 (the module's table:
  `observation`, `achieved_goal`, `desired_goal`; `split_obs`); action the turning
  rate r in deg/s, shape (1,) (or ()), clipped to [-15, 15]. `info`: `terminated`,
  `truncated`, `event` (1 the gate reached, -1 off the field), `is_success` and
  `discount`. The manual is `hpg_mj.envs.ship_goal.ShipGoalEnv`'s.
  """

  def __init__(self, level=goal_core.DEFAULT_LEVEL, env_id=None):
    self.level = level
    self.level_range = goal_core.level_range(level, env_id or "ShipGoal")
    self.time_limit = goal_core.TIME_LIMITS[level]
    super().__init__("steer", env_id or f"ShipGoal({level})")

  @property
  def default_params(self):
    low, high, largest = self.level_range
    half_width, min_cos = (float(v) for v in goal_core.level_tolerance(self.level))
    return GoalParams(max_steps_in_episode=goal_core.episode_steps(self.level),
                      gate_low=low, gate_high=high,
                      gate_heading_deg=largest, half_width=half_width, min_cos=min_cos)

  def observation_space(self, params=None):
    # `hpg_mj.envs.ship_goal.spaces_of`, flat: the ship's state, then two goals on the
    # field with one control step's margin.
    state = super().observation_space(params)
    goal_low = jnp.append(state.low[:2], jnp.array([-1.0, -1.0]))
    goal_high = jnp.append(state.high[:2], jnp.array([1.0, 1.0]))
    return environment.Box(jnp.concatenate([state.low, goal_low, goal_low]),
                           jnp.concatenate([state.high, goal_high, goal_high]), (12,),
                           environment.float_dtype())

  def get_obs(self, state, params=None, key=None):
    return jnp.concatenate([jnp.stack([state.x, state.y, state.theta_deg, state.theta_dot_deg]),
                            goal_of(state.x, state.y, state.theta_deg), state.desired])

  # ---- starts -------------------------------------------------------------------

  def _with_gate(self, state, gate_x, gate_y, heading_deg):
    rad = jnp.radians(heading_deg)
    desired = jnp.stack([gate_x, gate_y, jnp.sin(rad), jnp.cos(rad)]).astype(state.x.dtype)
    return GoalState(**{name: getattr(state, name) for name in ship.EnvState.__dataclass_fields__},
                     desired=desired)

  def reset_env(self, key, params):
    """The ship uniform on the field (the steering task's start), then the gate from
    the level's ranges (`ship_goal_core.sample_gate`), each from its half of `key`."""
    ship_key, gate_key = jax.random.split(key)
    dtype = environment.float_dtype()
    low = jnp.stack([params.gate_low, params.gate_low, -params.gate_heading_deg]).astype(dtype)
    high = jnp.stack([params.gate_high, params.gate_high, params.gate_heading_deg]).astype(dtype)
    gate_x, gate_y, heading = jax.random.uniform(gate_key, (3,), dtype, low, high)
    state = self._with_gate(self._draw_start(ship_key), gate_x, gate_y, heading)
    return self.get_obs(state, params), state

  def reset_to(self, ship_state, gate, params=None):
    """`(obs, state)` starting exactly at `ship_state` = `[x, y, theta_deg,
    theta_dot_deg]` with the gate `gate` = `[x, y, heading_deg]` (the Gymnasium
    environment's `reset(options={"state": ..., "gate": ...})`). Both are checked as
    there where their values are known (not under jit or vmap): the ship on the
    field, the gate's posts on it."""
    arr, gate = jnp.asarray(ship_state), jnp.asarray(gate)
    if arr.shape != (4,):
      raise ValueError(f"{self.env_id}: reset_to takes a ship state [x, y, theta_deg, "
                       f"theta_dot_deg] of shape (4,), got shape {arr.shape}")
    if gate.shape != (3,):
      raise ValueError(f"{self.env_id}: reset_to takes a gate [x, y, heading_deg] of shape "
                       f"(3,), got shape {gate.shape}")
    if environment.is_concrete(arr):
      core.check_state(np.asarray(arr, dtype=np.float64), self.env_id, 0.0, self.size)
    if environment.is_concrete(gate):
      goal_core.check_gate(np.asarray(gate, dtype=np.float64), self.env_id)
    return self._start_with_gate(arr, gate, params)

  @functools.partial(jax.jit, static_argnames=("self",))
  def _start_with_gate(self, arr, gate, params=None):
    params = self.default_params if params is None else params
    start = self._state(arr[0], arr[1], arr[2], arr[3])
    dtype = start.x.dtype
    state = self._with_gate(start, gate[0].astype(dtype), gate[1].astype(dtype),
                            gate[2].astype(dtype))
    return self.get_obs(state, params), state

  # ---- one control step ---------------------------------------------------------

  def step_env(self, key, state, action, params):
    r = self._turn_rate(action, state.x.dtype)
    x, y, theta, rate, _ = self._sail(state, r, params)
    time = state.time + 1
    # `ship_goal_core.judge_batch`: the rule on the goals at the end of the step.
    event, reward = outcome_of(goal_of(x, y, theta), state.desired, params)
    end = state.replace(x=x, y=y, theta_deg=theta, theta_dot_deg=rate, time=time, event=event)
    terminated = event != core.NO_EVENT
    truncated = ~terminated & (time >= self.closes(params))
    info = {"terminated": terminated, "truncated": truncated, "event": event,
            "is_success": event == core.SUCCESS,
            "discount": jnp.where(terminated, 0.0, 1.0).astype(x.dtype)}
    return self.get_obs(end, params), end, reward, terminated | truncated, info

  def compute_reward(self, achieved_goal, desired_goal, params=None):
    """The module's `compute_reward` with this environment's parameters (default:
    the level's)."""
    return compute_reward(achieved_goal, desired_goal,
                          self.default_params if params is None else params)
