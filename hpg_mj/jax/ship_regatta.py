"""The regatta in pure JAX (SPEC section 11, `hpg_mj/ShipRegatta-v0`), gymnax's
interface.

The steering ship of `hpg_mj.jax.ship` (Equation 1 in still water) round a course of
gates passed in order, the rules of `hpg_mj.worlds.ship_regatta_core` written again
over jax.numpy: only the next gate counts, and it is passed as `ship/steer`'s gate
is, a sampled segment crossing the line between its posts in either direction
(`ship.segment_crosses`); -1 a control step, `gate_reward` more for each gate but
the last, `finish_reward` for the last (terminated), `out_of_bounds_reward` off the
field (terminated; the first event in time wins); truncated after 5,000 control
steps. The observation is the numba world's eleven numbers: the ship's state, the
next gate and the one after it as the ship sees them (ahead and to starboard in m,
heading less the ship's in degrees) and the gates left. In float64 the trajectories,
rewards and endings equal the numba world's on the same course
(tests/jax/test_jax_ladder.py).

The level is a constructor argument, as the Gymnasium environment's, and gives the
default `RegattaParams`: the number of gates, their spacing and the range of the
turn at each. So one compiled step sails every level: the course in the state always
has `MAX_GATES` rows (8, the hard level's), those from `gates` on zero and unused.

The course is laid at each reset from the JAX key (`sample_course`), by the numba
world's rule operation by operation (`lay_course`: on the same uniforms it lays the
same course): the first gate uniform on [100, 900] m each way, each next one
`spacing` on along the last one's heading turned by a uniform angle to a random
side, turned to the other side where it would leave [100, 900] m or come within
110 m of another gate, its turn drawn again up to 50 times, and the whole course
laid again from new uniforms where a gate finds no room. JAX's generator is not
numpy's: the courses are drawn alike, not the same ones.

Laying a course is a loop of trials whose length varies a great deal (an easy course
is laid again half the time, after 50 trials of one gate), and gymnax's `step`
computes a start for every copy at every step; under vmap each loop would run as
long as the batch's longest. So `step`'s start goes through
`environment.where_needed`: vmapped, it is computed only for the copies whose
episode ended, one after another, each loop as long as its own
(`ShipRegatta.auto_reset`).
"""
import functools

import jax
import jax.numpy as jnp
import numpy as np

from hpg_mj.jax import environment
from hpg_mj.jax import ship
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_goal_core as goal_core
from hpg_mj.worlds import ship_regatta_core as regatta_core

MAX_GATES = regatta_core.MAX_GATES     # the course's rows in the state (the hard level's 8)
DRAWS = regatta_core.draws_per_course(MAX_GATES)   # uniforms one try at laying a course takes
MAX_COURSE_TRIES = 10_000      # courses laid again before giving up (the levels need a few)
GATE = regatta_core.GATE       # the event of a gate passed that is not the last
_LEVEL = regatta_core.LEVELS[regatta_core.DEFAULT_LEVEL]


@environment.record
class RegattaState(ship.EnvState):
  """The steering ship's `EnvState` and its course."""
  course: jax.Array          # (MAX_GATES, 3): rows [x, y, heading_deg]; from `gates` on, 0
  posts: jax.Array           # (MAX_GATES, 2, 2): each gate's posts, rows (x, y), left first
  next_gate: jax.Array       # int32: the gate to pass next (the number passed so far)


@environment.record
class RegattaParams(ship.EnvParams):
  """The steering task's `EnvParams` (`gate_reward`: each gate but the last), the
  finish's reward and the level's layout (SPEC section 11, `ship_regatta_core.LEVELS`):
  `gates` (1 to MAX_GATES), `spacing` m apart, turning by `smallest_turn_deg` to
  `largest_turn_deg` at each."""
  finish_reward: float = regatta_core.FINISH_REWARD
  gates: int = _LEVEL[0]
  spacing: float = _LEVEL[1]
  smallest_turn_deg: float = _LEVEL[2]
  largest_turn_deg: float = _LEVEL[3]


# ---- the course ------------------------------------------------------------------

def lay_course(draws, gates, spacing, smallest_turn_deg, largest_turn_deg):
  """`ship_regatta_core.lay_course` over jax.numpy: `(course, laid)`, the course
  (MAX_GATES, 3) laid from `draws` (DRAWS uniforms on [0, 1), consumed in the numba
  rule's order: the first gate's x, y and heading, then a turn and a side for each
  try of each gate), its rows from `gates` on zero; `laid` false where a gate found
  no room in `ship_regatta_core.TRIES` turns. On the same draws (the numba rule reads
  the first `draws_per_course(gates)`) the same course, to rounding."""
  dtype = draws.dtype
  low, high = regatta_core.LOW, regatta_core.HIGH
  spacing, smallest, largest = (jnp.asarray(v, dtype) for v in
                                (spacing, smallest_turn_deg, largest_turn_deg))
  first = jnp.stack([low + (high - low) * draws[0], low + (high - low) * draws[1],
                     -180.0 + 360.0 * draws[2]])
  course = jnp.zeros((MAX_GATES, 3), dtype).at[0].set(first)
  rows = jnp.arange(MAX_GATES)

  def lay_gate(k, carry):
    course, at, laid = carry
    wanted = laid & (k < gates)
    before = course[k - 1]

    def trying(s):
      tries, placed, _, _ = s
      return wanted & ~placed & (tries < regatta_core.TRIES)

    def one_try(s):
      tries, _, _, at = s
      turn = smallest + (largest - smallest) * draws[at]
      side = jnp.where(draws[at + 1] < 0.5, 1.0, -1.0)
      # The drawn side first, then the other (`lay_course`'s `for sign in (side, -side)`).
      heading = ship.wrap_deg(before[2] + jnp.stack([side, -side]).astype(dtype) * turn)
      rad = jnp.radians(heading)
      x = before[0] + spacing * jnp.sin(rad)
      y = before[1] + spacing * jnp.cos(rad)
      fits = (low <= x) & (x <= high) & (low <= y) & (y <= high)   # `_fits`
      apart = jnp.hypot(x[:, None] - course[:, 0], y[:, None] - course[:, 1])
      fits &= jnp.all((apart >= regatta_core.MIN_SEPARATION) | (rows >= k), axis=1)
      pick = jnp.where(fits[0], 0, 1)
      return tries + 1, fits.any(), jnp.stack([x[pick], y[pick], heading[pick]]), at + 2

    start = (jnp.int32(0), jnp.asarray(False), before, at)
    _, placed, row, at = jax.lax.while_loop(trying, one_try, start)
    course = course.at[k].set(jnp.where(wanted & placed, row, 0.0))
    return course, at, laid & (placed | ~wanted)

  course, _, laid = jax.lax.fori_loop(1, MAX_GATES, lay_gate,
                                      (course, jnp.int32(3), jnp.asarray(True)))
  return course, laid


def sample_course(key, gates, spacing, smallest_turn_deg, largest_turn_deg):
  """A course (MAX_GATES, 3) drawn from `key` (`ship_regatta_core.sample_course`):
  `lay_course` on DRAWS uniforms, laid again from new ones until every gate finds
  room. A layout with no room (possible only with parameters no level has) gives up
  after MAX_COURSE_TRIES and returns a course of NaN."""
  dtype = environment.float_dtype()

  def again(carry):
    _, tries, _, laid = carry
    return ~laid & (tries < MAX_COURSE_TRIES)

  def one_course(carry):
    key, tries, _, _ = carry
    key, draw_key = jax.random.split(key)
    course, laid = lay_course(jax.random.uniform(draw_key, (DRAWS,), dtype), gates, spacing,
                              smallest_turn_deg, largest_turn_deg)
    return key, tries + 1, course, laid

  start = (key, jnp.int32(0), jnp.zeros((MAX_GATES, 3), dtype), jnp.asarray(False))
  _, _, course, laid = jax.lax.while_loop(again, one_course, start)
  return jnp.where(laid, course, jnp.nan)


_lay_one_by_one = environment.where_needed(sample_course)


def posts_of(course):
  """The posts of every gate of a course, (rows, 2, 2): rows (x, y), left then right of
  a ship passing it (`ship_regatta_core.posts_into`)."""
  rad = jnp.radians(course[:, 2])
  s, c = jnp.sin(rad), jnp.cos(rad)
  x, y, half = course[:, 0], course[:, 1], goal_core.HALF_WIDTH
  left = jnp.stack([x - half * c, y + half * s], axis=-1)
  right = jnp.stack([x + half * c, y - half * s], axis=-1)
  return jnp.stack([left, right], axis=1)


def course_outcome(positions, posts, next_gate, gates, params):
  """`ship_regatta_core.course_outcome`: `(event, reward, next_gate)` after a control
  step that sampled `positions` (the start first) with gate `next_gate` of `posts` to
  pass. Segment by segment: the next gate crossed is passed (+`gate_reward`, GATE; the
  last, +`finish_reward`, SUCCESS, which ends the reckoning), then a position off the
  field fails (+`out_of_bounds_reward`, FAILURE, likewise); one gate at most a
  segment, the next one counting from the segment after it."""
  dtype = positions[0][0].dtype
  reward = jnp.asarray(core.STEP_REWARD, dtype)
  event = jnp.asarray(core.NO_EVENT, jnp.int32)
  ended = jnp.asarray(False)
  for (px, py), (x, y) in zip(positions[:-1], positions[1:]):
    live = ~ended & (next_gate < gates)
    (q0x, q0y), (q1x, q1y) = posts[jnp.minimum(next_gate, MAX_GATES - 1)]
    crossed = live & ship.segment_crosses(px, py, x, y, q0x, q0y, q1x, q1y)
    next_gate = next_gate + crossed.astype(next_gate.dtype)
    finished = crossed & (next_gate == gates)
    passed = crossed & ~finished
    left = live & ~finished & ((x < 0.0) | (x > core.FIELD_SIZE) | (y < 0.0)
                               | (y > core.FIELD_SIZE))
    # The numba rule's sums in its order: each gate as it comes, then the ending's.
    reward = reward + jnp.where(passed, params.gate_reward, 0.0).astype(dtype)
    reward = reward + jnp.where(finished, params.finish_reward, 0.0).astype(dtype)
    reward = reward + jnp.where(left, params.out_of_bounds_reward, 0.0).astype(dtype)
    event = jnp.where(finished, core.SUCCESS, jnp.where(
        left, core.FAILURE, jnp.where(passed, GATE, event))).astype(jnp.int32)
    ended = ended | finished | left
  return event, reward, next_gate


def _seen(x, y, theta_deg, s, c, gate):
  """A gate [x, y, heading_deg] as the ship sees it (`ship_regatta_core._seen`): the
  centre ahead and to starboard, its heading less the ship's."""
  dx, dy = gate[0] - x, gate[1] - y
  return [dx * s + dy * c, dx * c - dy * s, ship.wrap_deg(gate[2] - theta_deg)]


class ShipRegatta(ship.ShipSteering):
  """`hpg_mj/ShipRegatta-v0` as a gymnax environment: the steering ship round a course
  of gates laid at each reset by the rule of `level` ("easy", "medium" or "hard"; it
  gives the default `RegattaParams`). Observation the numba world's eleven numbers
  (`hpg_mj.envs.ship_regatta.ShipRegattaEnv`'s table) in the default float dtype;
  action the turning rate r in deg/s, shape (1,) (or ()), clipped to [-15, 15].
  `info`: `terminated`, `truncated`, `event` (2 a gate passed, 1 the finish, -1 off
  the field), `gates_passed` and `discount`. The manual is `ShipRegattaEnv`'s.
  """

  def __init__(self, level=regatta_core.DEFAULT_LEVEL, env_id=None):
    self.level = level
    self.layout = regatta_core.level_layout(level, env_id or "ShipRegatta")
    self.time_limit = regatta_core.TIME_LIMITS[level]
    super().__init__("steer", env_id or f"ShipRegatta({level})")
    self._reset_where = environment.where_needed(self.reset_env)

  @property
  def default_params(self):
    gates, spacing, smallest, largest = self.layout
    return RegattaParams(max_steps_in_episode=regatta_core.episode_steps(self.level),
                         gates=gates,
                         spacing=spacing, smallest_turn_deg=smallest,
                         largest_turn_deg=largest)

  def observation_space(self, params=None):
    # `hpg_mj.envs.ship_regatta.spaces_of`: the ship's state, two gates seen within the
    # field's diagonal and a step's sailing (whole metres), and the gates left.
    state = super().observation_space(params)
    reach = float(np.ceil(np.hypot(float(state.high[0]), float(state.high[1]))))
    gates = self.layout[0] if params is None else params.gates
    seen = jnp.array([reach, reach, 180.0] * 2)
    return environment.Box(jnp.concatenate([state.low, -seen, jnp.zeros(1)]),
                           jnp.concatenate([state.high, seen,
                                            jnp.asarray(gates, state.high.dtype).reshape(1)]),
                           (regatta_core.OBSERVATION_SIZE,), environment.float_dtype())

  def get_obs(self, state, params=None, key=None):
    params = self.default_params if params is None else params
    last = params.gates - 1
    rad = jnp.radians(state.theta_deg)
    s, c = jnp.sin(rad), jnp.cos(rad)
    ship_at = (state.x, state.y, state.theta_deg, s, c)
    nearest = _seen(*ship_at, state.course[jnp.minimum(state.next_gate, last)])
    after = _seen(*ship_at, state.course[jnp.minimum(state.next_gate + 1, last)])
    left = jnp.asarray(params.gates - state.next_gate, state.x.dtype)
    return jnp.stack([state.x, state.y, state.theta_deg, state.theta_dot_deg,
                      *nearest, *after, left])

  def is_terminal(self, state, params):
    # A gate passed (GATE) is no ending: only the finish, the field and the clock.
    ended = (state.event == core.SUCCESS) | (state.event == core.FAILURE)
    return ended | (state.time >= self.closes(params))

  # ---- starts -------------------------------------------------------------------

  def _on_course(self, ship_state, course):
    return RegattaState(**{name: getattr(ship_state, name)
                           for name in ship.EnvState.__dataclass_fields__},
                        course=course, posts=posts_of(course),
                        next_gate=jnp.asarray(0, jnp.int32))

  def reset_env(self, key, params):
    """The ship uniform on the field (the steering task's start), then the course
    (`sample_course`), each from its half of `key`."""
    ship_key, course_key = jax.random.split(key)
    # Vmapped, one copy after another (`where_needed`), each loop its own length: 4,096
    # courses in 0.27 s here, where the batch's loops in lock step took 1.8 s.
    layout = (params.gates, params.spacing, params.smallest_turn_deg, params.largest_turn_deg)
    course = _lay_one_by_one(jnp.asarray(True), course_key, *map(jnp.asarray, layout))
    state = self._on_course(self._draw_start(ship_key), course)
    return self.get_obs(state, params), state

  def auto_reset(self, key, params, done):
    """`reset_env`'s start, computed only where `done` (`environment.where_needed`;
    module docstring)."""
    return self._reset_where(done, key, jax.tree.map(jnp.asarray, params))

  def reset_to(self, ship_state, course, params=None):
    """`(obs, state)` starting exactly at `ship_state` = `[x, y, theta_deg,
    theta_dot_deg]` on `course`, rows `[x, y, heading_deg]` of its gates (the Gymnasium
    environment's `reset(options={"state": ..., "course": ...})`). Both are checked as
    there where their values are known (not under jit or vmap): the ship on the field,
    `params.gates` gates each with its posts on the field."""
    params = self.default_params if params is None else params
    arr, course = jnp.asarray(ship_state), jnp.asarray(course)
    if arr.shape != (4,):
      raise ValueError(f"{self.env_id}: reset_to takes a ship state [x, y, theta_deg, "
                       f"theta_dot_deg] of shape (4,), got shape {arr.shape}")
    if course.ndim != 2 or course.shape[1] != 3 or not 1 <= course.shape[0] <= MAX_GATES:
      raise ValueError(f"{self.env_id}: reset_to takes a course of 1 to {MAX_GATES} gates "
                       f"[x, y, heading_deg] (shape (gates, 3)), got shape {course.shape}")
    if environment.is_concrete(arr):
      core.check_state(np.asarray(arr, dtype=np.float64), self.env_id, 0.0, self.size)
    if environment.is_concrete(course) and environment.is_concrete(params.gates):
      regatta_core.check_course(np.asarray(course, dtype=np.float64), int(params.gates),
                                self.env_id)
    return self._start_on_course(arr, course, params)

  @functools.partial(jax.jit, static_argnames=("self",))
  def _start_on_course(self, arr, course, params):
    start = self._state(arr[0], arr[1], arr[2], arr[3])
    dtype = start.x.dtype
    rows = course.astype(dtype)
    rows = rows.at[:, 2].set(ship.wrap_deg(rows[:, 2]))
    padded = jnp.zeros((MAX_GATES, 3), dtype).at[:course.shape[0]].set(rows)
    state = self._on_course(start, padded)
    return self.get_obs(state, params), state

  # ---- one control step ---------------------------------------------------------

  def step_env(self, key, state, action, params):
    r = self._turn_rate(action, state.x.dtype)
    x, y, theta, rate, positions = self._sail(state, r, params)
    time = state.time + 1
    event, reward, next_gate = course_outcome(positions, state.posts, state.next_gate,
                                              params.gates, params)
    end = state.replace(x=x, y=y, theta_deg=theta, theta_dot_deg=rate, time=time, event=event,
                        next_gate=next_gate)
    terminated = (event == core.SUCCESS) | (event == core.FAILURE)
    truncated = ~terminated & (time >= self.closes(params))
    info = {"terminated": terminated, "truncated": truncated, "event": event,
            "gates_passed": next_gate,
            "discount": jnp.where(terminated, 0.0, 1.0).astype(x.dtype)}
    return self.get_obs(end, params), end, reward, terminated | truncated, info
