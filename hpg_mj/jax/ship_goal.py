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

At `hard` the water holds the harbour's medium obstacles (`ship_goal_core.OBSTACLES`),
parameters as the harbour's are (`GoalParams.islands`, `piers`; rows of zeros in the
open water of `easy` and `medium`): a step whose sampled track touches one runs aground
(AGROUND, -3: -100, terminated) before the goals are judged, the ship's start is drawn
again while it lies on one and the gate until it stands clear of them
(`ship_goal_core.gate_clear`), each from the next part of its key (the first try from
the key itself, so that the open water's starts are as before).

The observation is one flat vector of 19, not Gymnasium's dictionary: the
dictionary's four parts one after the other, at the slices `OBSERVATION`,
`ACHIEVED_GOAL`, `DESIRED_GOAL` and `RANGES`:

| index | part | what |
|---|---|---|
| 0-3 | `observation` | `[x, y, theta_deg, theta_dot_deg]`, the ship's state |
| 4-7 | `achieved_goal` | `[x, y, sin(theta), cos(theta)]` of the ship |
| 8-11 | `desired_goal` | `[x, y, sin, cos]` of the gate's centre and heading |
| 12-18 | `ranges` | the harbour's seven rangefinders (m; 150 where none is nearer) |

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
from hpg_mj.jax import ship_harbour as harbour
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_goal_core as goal_core
from hpg_mj.worlds import ship_harbour_core as harbour_core
from hpg_mj.worlds import ship_task

OBSERVATION = slice(0, 4)      # the ship's state [x, y, theta_deg, theta_dot_deg]
ACHIEVED_GOAL = slice(4, 8)    # the ship's [x, y, sin(theta), cos(theta)]
DESIRED_GOAL = slice(8, 12)    # the gate's [x, y, sin(heading), cos(heading)]
RANGES = slice(12, 12 + goal_core.RAYS)    # the rangefinders (m)
AGROUND = goal_core.AGROUND


def level_obstacles(level, who="ShipGoal"):
  """(islands, piers) of goal `level` as `GoalParams` holds them (`ship_harbour`'s
  `level_obstacles` of `ship_goal_core.OBSTACLES[level]`; rows of zeros, no obstacle,
  in open water), or a one-line error for an unknown level."""
  goal_core.level_range(level, who)
  if goal_core.OBSTACLES[level] is None:
    return (((0.0, 0.0, 0.0),) * harbour.MAX_ISLANDS, ((0.0,) * 5,) * harbour.MAX_PIERS)
  return harbour.level_obstacles(goal_core.OBSTACLES[level], who)


_OPEN = level_obstacles(goal_core.DEFAULT_LEVEL)


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
  islands: tuple = _OPEN[0]
  piers: tuple = _OPEN[1]


_PARTS = {"observation": OBSERVATION, "achieved_goal": ACHIEVED_GOAL,
          "desired_goal": DESIRED_GOAL, "ranges": RANGES}
OBS_SIZE = RANGES.stop          # 19


def split_obs(obs):
  """Gymnasium's goal-conditioned dictionary of a flat observation (or of a batch of
  them, the last axis 19): `observation`, `achieved_goal`, `desired_goal`, `ranges`.
  Another last axis is refused in one line."""
  if jnp.ndim(obs) == 0 or jnp.shape(obs)[-1] != OBS_SIZE:
    raise ValueError(f"split_obs takes the goal's flat observation, a last axis of "
                     f"{OBS_SIZE}; got shape {jnp.shape(obs)}")
  return {name: obs[..., where] for name, where in _PARTS.items()}


def join_obs(parts):
  """The flat observation (the last axis 19) of Gymnasium's goal-conditioned dictionary
  (`split_obs`'s inverse, for any batch shape): what a policy of this environment's
  observation reads when `hpg_mj.benchmark.evaluate` hands it the Gymnasium
  environment's dictionary, `evaluate(lambda o: f(join_obs(o)), "ship_goal")`. numpy
  arrays in, a numpy array out; JAX's, JAX's. A key missing is refused naming the four."""
  missing = [name for name in _PARTS if name not in parts]
  if missing:
    raise ValueError(f"join_obs takes the goal's dictionary of {list(_PARTS)}; "
                     f"{missing} missing")
  arrays = [parts[name] for name in _PARTS]
  stack = jnp if any(isinstance(a, jax.Array) for a in arrays) else np
  return stack.concatenate(arrays, axis=-1)


def gate_clear(gate_x, gate_y, heading_deg, obstacles):
  """`ship_goal_core.gate_clear` of the gate [x, y, heading_deg] among `obstacles`
  (`ship_harbour.obstacles_of`): its posts' line and the APPROACH_M before its centre
  at least CLEARANCE_M from each obstacle."""
  rad = jnp.radians(heading_deg)
  s, c = jnp.sin(rad), jnp.cos(rad)
  half, back, margin = goal_core.HALF_WIDTH, goal_core.APPROACH_M, goal_core.CLEARANCE_M
  line = harbour.segment_touches(gate_x - half * c, gate_y + half * s, gate_x + half * c,
                                 gate_y - half * s, obstacles, margin)
  approach = harbour.segment_touches(gate_x, gate_y, gate_x - back * s, gate_y - back * c,
                                     obstacles, margin)
  return ~(line[0].any() | line[1].any() | approach[0].any() | approach[1].any())


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


def compute_reward(achieved_goal, desired_goal, params, aground=False):
  """The reward of achieved and desired goals of any (broadcast) batch shape, the last
  axis 4 (`ShipGoalEnv.compute_reward`): what Hindsight Experience Replay asks of
  relabelled goals; -1 and the out-of-bounds penalty where `aground` (the steps whose
  track touched an obstacle: `info["event"] == AGROUND`). Jittable."""
  achieved, desired = jnp.broadcast_arrays(jnp.asarray(achieved_goal), jnp.asarray(desired_goal))
  reward = outcome_of(achieved, desired, params)[1]
  return jnp.where(aground, jnp.asarray(core.STEP_REWARD, reward.dtype)
                   + params.out_of_bounds_reward, reward).astype(reward.dtype)


class ShipGoal(ship.ShipSteering):
  """`hpg_mj/ShipGoal-v0` as a gymnax environment: the steering ship and a gate drawn
  at each reset from the ranges of `level` ("easy", "medium" or "hard"; they give
  the default `GoalParams`). Observation a flat vector of 19 (the module's table:
  `observation`, `achieved_goal`, `desired_goal`, `ranges`; `split_obs`); action the turning
  rate r in deg/s, shape (1,) (or ()), clipped to [-15, 15]. `info`: `terminated`,
  `truncated`, `event` (1 the gate reached, -1 off the field, -3 an obstacle touched),
  `is_success` and
  `discount`. The manual is `hpg_mj.envs.ship_goal.ShipGoalEnv`'s.
  """

  def __init__(self, level=goal_core.DEFAULT_LEVEL, env_id=None):
    self.level = level
    self.level_range = goal_core.level_range(level, env_id or "ShipGoal")
    self.obstacles = level_obstacles(level, env_id or "ShipGoal")
    self.time_limit = goal_core.TIME_LIMITS[level]
    super().__init__("steer", env_id or f"ShipGoal({level})")
    self._reset_where = environment.where_needed(self.reset_env)

  @property
  def default_params(self):
    low, high, largest = self.level_range
    half_width, min_cos = (float(v) for v in goal_core.level_tolerance(self.level))
    islands, piers = self.obstacles
    return GoalParams(max_steps_in_episode=goal_core.episode_steps(self.level),
                      gate_low=low, gate_high=high,
                      gate_heading_deg=largest, half_width=half_width, min_cos=min_cos,
                      islands=islands, piers=piers)

  def observation_space(self, params=None):
    # `hpg_mj.envs.ship_goal.spaces_of`, flat: the ship's state, then two goals on the
    # field with one control step's margin, then the ranges.
    state = super().observation_space(params)
    goal_low = jnp.append(state.low[:2], jnp.array([-1.0, -1.0]))
    goal_high = jnp.append(state.high[:2], jnp.array([1.0, 1.0]))
    rays = goal_core.RAYS
    return environment.Box(
        jnp.concatenate([state.low, goal_low, goal_low, jnp.zeros(rays)]),
        jnp.concatenate([state.high, goal_high, goal_high,
                         jnp.full(rays, harbour_core.MAX_RANGE_M)]),
        (goal_core.OBSERVATION_SIZE,), environment.float_dtype())

  def get_obs(self, state, params=None, key=None):
    params = self.default_params if params is None else params
    seen = harbour.ranges(state.x, state.y, state.theta_deg,
                          harbour.obstacles_of(params, state.x.dtype))
    return jnp.concatenate([jnp.stack([state.x, state.y, state.theta_deg, state.theta_dot_deg]),
                            goal_of(state.x, state.y, state.theta_deg), state.desired, seen])

  # ---- starts -------------------------------------------------------------------

  def _with_gate(self, state, gate_x, gate_y, heading_deg):
    rad = jnp.radians(heading_deg)
    desired = jnp.stack([gate_x, gate_y, jnp.sin(rad), jnp.cos(rad)]).astype(state.x.dtype)
    return GoalState(**{name: getattr(state, name) for name in ship.EnvState.__dataclass_fields__},
                     desired=desired)

  def reset_env(self, key, params):
    """The ship uniform on the field (the steering task's start), drawn again while it
    lies on an obstacle, then the gate from the level's ranges, drawn again until it
    stands clear of them (`ship_goal_core.sample_start`, `sample_gate`), each from its
    half of `key` (the first try from that half, the next ones from its next parts)."""
    ship_key, gate_key = jax.random.split(key)
    dtype = environment.float_dtype()
    obstacles = harbour.obstacles_of(params, dtype)

    def on_obstacle(carry):
      _, tries, state = carry
      return harbour.inside(state.x, state.y, obstacles) & (tries < harbour_core.START_TRIES)

    def draw_ship(carry):
      key, tries, _ = carry
      key, next_key = jax.random.split(key)
      return key, tries + 1, self._draw_start(next_key)

    _, _, start = jax.lax.while_loop(on_obstacle, draw_ship,
                                     (ship_key, jnp.int32(1), self._draw_start(ship_key)))
    low = jnp.stack([params.gate_low, params.gate_low, -params.gate_heading_deg]).astype(dtype)
    high = jnp.stack([params.gate_high, params.gate_high, params.gate_heading_deg]).astype(dtype)

    def in_the_way(carry):
      _, tries, gate = carry
      return ~gate_clear(gate[0], gate[1], gate[2], obstacles) & (tries < goal_core.GATE_TRIES)

    def draw_gate(carry):
      key, tries, _ = carry
      key, next_key = jax.random.split(key)
      return key, tries + 1, jax.random.uniform(next_key, (3,), dtype, low, high)

    _, _, gate = jax.lax.while_loop(in_the_way, draw_gate, (gate_key, jnp.int32(1),
                                    jax.random.uniform(gate_key, (3,), dtype, low, high)))
    state = self._with_gate(start, gate[0], gate[1], gate[2])
    return self.get_obs(state, params), state

  def auto_reset(self, key, params, done):
    """`reset_env`'s start, computed only where `done` (`environment.where_needed`):
    its rays and its draws off the obstacles are most of a step's work."""
    return self._reset_where(done, key, jax.tree.map(jnp.asarray, params))

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
    params = self.default_params if params is None else params
    obstacles = harbour.known_obstacles(params)
    if environment.is_concrete(arr):
      core.check_state(np.asarray(arr, dtype=np.float64), self.env_id, 0.0, self.size)
      if obstacles is not None:
        harbour_core.check_start(ship_task.ShipRules("steer"), np.asarray(arr, np.float64),
                                 *obstacles, self.env_id)
    if environment.is_concrete(gate):      # among obstacles not known here: none
      goal_core.check_gate(np.asarray(gate, dtype=np.float64), self.env_id,
                           obstacles=obstacles or (np.zeros((0, 3)), np.zeros((0, 6))))
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
    x, y, theta, rate, positions = self._sail(state, r, params)
    time = state.time + 1
    # `ship_goal_core.step_outcome`: the obstacles on the track, then the rule on the
    # goals at the end of the step.
    _, _, segments = harbour.segments_aground(positions, harbour.obstacles_of(params, x.dtype))
    aground = segments.any()
    event, reward = outcome_of(goal_of(x, y, theta), state.desired, params)
    event = jnp.where(aground, AGROUND, event).astype(jnp.int32)
    reward = jnp.where(aground, jnp.asarray(core.STEP_REWARD, x.dtype)
                       + params.out_of_bounds_reward, reward).astype(x.dtype)
    end = state.replace(x=x, y=y, theta_deg=theta, theta_dot_deg=rate, time=time, event=event)
    terminated = event != core.NO_EVENT
    truncated = ~terminated & (time >= self.closes(params))
    info = {"terminated": terminated, "truncated": truncated, "event": event,
            "is_success": event == core.SUCCESS,
            "discount": jnp.where(terminated, 0.0, 1.0).astype(x.dtype)}
    return self.get_obs(end, params), end, reward, terminated | truncated, info

  def compute_reward(self, achieved_goal, desired_goal, params=None, aground=False):
    """The module's `compute_reward` with this environment's parameters (default:
    the level's)."""
    return compute_reward(achieved_goal, desired_goal,
                          self.default_params if params is None else params, aground)
