"""The task ladder's JAX worlds equal their analytic numba worlds (issue 42; SPEC
section 11): for each task and level, 1,000 starts (the regatta's and the harbour's:
500) drawn as the numba world draws them (numpy's generator seeded 1,000,000 + i,
the ship and then what the level adds: the goal's gate, the regatta's course; the
harbour's start drawn again off its obstacles), given to both worlds, sailed under
the same seeded controls by `hpg_mj.jax` (vmapped, scanned) and by the compiled
batch steps of the native vector environments, give in float64 the same
observations to 1e-9 (the harbour's rangefinders: 1e-6, `HarbourWorld`), the same
rewards and the same endings at the same steps. Float32 is measured against the
same float64 reference and held to what it gives (stated in docs/jax.md), on the
parts of the observation that move with the ship continuously.

Lean by design: each task compiles its scan once per float width, every level
sharing it (a level is the world's parameters: `params` is an argument of the
compiled scan, not a constant in it)."""
import functools

import numpy as np
import pytest

pytest.importorskip("jax.numpy")   # not `jax`: tests/ is on sys.path and holds tests/jax
import jax  # noqa: E402

import hpg_mj.jax as hpg_jax  # noqa: E402
from hpg_mj import planners  # noqa: E402
from hpg_mj.jax import ship_goal  # noqa: E402
from hpg_mj.worlds import ship_core as core  # noqa: E402
from hpg_mj.worlds import ship_current_core as current_core  # noqa: E402
from hpg_mj.worlds import ship_goal_core as goal_core  # noqa: E402
from hpg_mj.worlds import ship_harbour_core as harbour_core  # noqa: E402
from hpg_mj.worlds import ship_ladder  # noqa: E402
from hpg_mj.worlds import ship_regatta_core as regatta_core  # noqa: E402
from hpg_mj.worlds import ship_task  # noqa: E402

N = 1000
CHUNK = 100           # control steps per compiled scan (one length: one compile)
LEVELS = ("easy", "medium", "hard")
TRUNCATED = 9         # an ending's code beside the events: truncated


def _rng(i):
  return np.random.default_rng(1_000_000 + i)


class World:
  """What the worlds below share, and where they differ: the columns of their
  observations that are headings (compared the short way round), those that move
  with the ship continuously (float32 is held on them), the float64 bound on the
  observation, the endings their episodes come to, how many episodes are sailed;
  and the scripted helmsman's turning rates for the ships `rows` (`targets`, then
  `helmsman`; `phase` says who has reached the first waypoint)."""

  angles = (2,)
  smooth = slice(None)
  bound64 = 1e-9
  endings = {core.FAILURE, core.SUCCESS, TRUNCATED}
  episodes = N

  @classmethod
  def endings_of(cls, level):
    """The endings its episodes come to at `level`."""
    return cls.endings

  def rates(self, rows, phase):
    ships = self.ships[rows]
    return helmsman(ships, *self.targets(ships, phase, rows))


class CurrentWorld(World):
  """The numba ships in a level's current, stepped as `ShipCurrentVectorEnv`'s
  analytic batch: `drift_batch`, then `task_step_batch` judging the sailed samples."""

  id = "ShipCurrent-v0"

  def __init__(self, level, limit, n=N):
    self.level = level
    self.field = current_core.level_field(level)
    rules = ship_task.ShipRules("steer", limit)
    self.starts = np.array([rules.sample_start(_rng(i)) for i in range(n)])
    self.ships = self.starts.copy()
    self.limit, self.rules = limit, rules
    self.samples = np.zeros((n, core.SAMPLES_PER_CONTROL + 1, 2))
    self.steps = np.zeros(n, np.int64)
    self.outcome = (np.zeros(n, np.int64), np.zeros(n), np.zeros(n, np.bool_),
                    np.zeros(n, np.bool_))
    self.currents = np.zeros((n, 2))

  def jax_starts(self, env, params):
    return jax.vmap(lambda s: env.reset_to(s, params))(self.starts)

  def step(self, r, live):
    current_core.drift_batch(self.ships, r, live, self.samples, self.field)
    core.task_step_batch(self.ships, r, live, self.samples, self.steps, False, True,
                         np.zeros(2), core.FIELD_SIZE, self.limit, self.rules.success_reward,
                         self.rules.failure_reward, self.outcome)
    return self.outcome

  def observations(self):
    current_core.currents_of(self.ships, self.field, self.currents)
    return np.concatenate([self.ships, self.currents], axis=1)

  def targets(self, ships, phase, rows):
    """`ship_core.gate_pilot_target` over rows of ships: 150 m off the gate on the
    ship's side until within 40 m, then 60 m through it."""
    side = np.where(ships[:, 1] >= 400.0, 1.0, -1.0)
    phase |= np.hypot(ships[:, 0] - 400.0, ships[:, 1] - (400.0 + 150.0 * side)) < 40.0
    return np.full(len(ships), 400.0), np.where(phase, 400.0 - 60.0 * side,
                                                400.0 + 150.0 * side)


class GoalWorld(World):
  """The numba goal-conditioned ships, stepped as `ShipGoalVectorEnv`'s analytic batch:
  `task_step_batch` sails them, then `judge_batch` judges the goals (and at hard the
  obstacles on the track), the ranges cast by `ranges_batch`."""

  id = "ShipGoal-v0"
  bound64 = 1e-6            # the hard level's rays: `HarbourWorld`'s bound
  smooth = slice(0, 12)     # the state and the goals; not the rays, which jump

  def __init__(self, level, limit, n=N):
    self.level = level
    rules = ship_task.ShipRules("steer", limit)
    starts, gates = [], []
    for i in range(n):
      rng = _rng(i)          # as the Gymnasium environment's reset: the ship, then the gate
      starts.append(goal_core.sample_start(rules, rng, level))
      gates.append(goal_core.draw_gate(rng, level))
    self.starts, self.gates = np.array(starts), np.array(gates)
    self.desired = np.array([goal_core.check_gate(g, "test", level) for g in gates])
    self.ships = self.starts.copy()
    self.limit, self.rules = limit, rules
    self.shapes = goal_core.level_shapes(level)
    self.samples = np.zeros((n, core.SAMPLES_PER_CONTROL + 1, 2))
    self.steps = np.zeros(n, np.int64)
    self.achieved = np.array([goal_core.goal_of(s) for s in self.starts])
    self.ranges = np.zeros((n, goal_core.RAYS))
    self.outcome = (np.zeros(n, np.int64), np.zeros(n), np.zeros(n, np.bool_),
                    np.zeros(n, np.bool_))

  @classmethod
  def endings_of(cls, level):
    return cls.endings | ({goal_core.AGROUND} if goal_core.OBSTACLES[level] else set())

  def jax_starts(self, env, params):
    return jax.vmap(lambda s, g: env.reset_to(s, g, params))(self.starts, self.gates)

  def step(self, r, live):
    core.task_step_batch(self.ships, r, live, self.samples, self.steps, True, True,
                         np.zeros(2), core.FIELD_SIZE, self.limit, self.rules.success_reward,
                         self.rules.failure_reward, self.outcome)
    goal_core.judge_batch(self.ships, self.samples, live, self.steps, self.desired, self.limit,
                          self.rules.success_reward, self.rules.failure_reward,
                          goal_core.level_tolerance(self.level), *self.shapes, self.achieved,
                          self.outcome)
    return self.outcome

  def observations(self):
    harbour_core.ranges_batch(self.ships, *self.shapes, self.ranges)
    return np.concatenate([self.ships, self.achieved, self.desired, self.ranges], axis=1)

  def targets(self, ships, phase, rows):
    """`ship_goal_core.pilot_target` over rows of ships: 150 m before the gate on its
    line of approach until within 40 m, then 60 m past its centre."""
    d = self.desired[rows]
    before = d[:, :2] - 150.0 * d[:, 2:]
    phase |= np.hypot(*(ships[:, :2] - before).T) < 40.0
    target = np.where(phase[:, None], d[:, :2] + 60.0 * d[:, 2:], before)
    return target[:, 0], target[:, 1]


class RegattaWorld(World):
  """The numba ships on their courses, stepped as `ShipRegattaVectorEnv`'s analytic
  batch: `ship_regatta_core.step_batch` sails and judges them; each course drawn after
  its ship from the same generator, as the Gymnasium environment's reset."""

  id = "ShipRegatta-v0"
  angles = (2, 6, 9)        # the ship's heading, and each gate's less the ship's
  # The gates seen jump where one is passed: a step apart in float32, by a leg.
  smooth = slice(0, 4)
  episodes = N // 2         # two ladder tasks more in the tests' time

  def __init__(self, level, limit, n=N):
    self.level = level
    rules = ship_task.ShipRules("steer", limit)
    layout = regatta_core.LEVELS[level]
    starts, courses = [], []
    for i in range(n):
      rng = _rng(i)
      starts.append(rules.sample_start(rng))
      courses.append(regatta_core.sample_course(rng, layout))
    self.starts, self.courses = np.array(starts), np.array(courses)
    self.posts = np.array([regatta_core.posts_of(c) for c in self.courses])
    self.ships = self.starts.copy()
    self.limit = limit
    self.next = np.zeros(n, np.int64)
    self.samples = np.zeros((n, core.SAMPLES_PER_CONTROL + 1, 2))
    self.steps = np.zeros(n, np.int64)
    self.outcome = (np.zeros(n, np.int64), np.zeros(n), np.zeros(n, np.bool_),
                    np.zeros(n, np.bool_))
    self.obs = np.zeros((n, regatta_core.OBSERVATION_SIZE))
    self.helmsman = planners.Helmsman("ship_regatta", level)

  def jax_starts(self, env, params):
    return jax.vmap(lambda s, c: env.reset_to(s, c, params))(self.starts, self.courses)

  def step(self, r, live):
    regatta_core.step_batch(self.ships, r, live, self.samples, self.steps, True, self.posts,
                            self.next, self.limit, regatta_core.GATE_REWARD,
                            regatta_core.FINISH_REWARD, regatta_core.OUT_OF_BOUNDS_REWARD,
                            self.outcome)
    return self.outcome

  def observations(self):
    regatta_core.observe_batch(self.ships, self.courses, self.next, self.obs)
    return self.obs

  def rates(self, rows, phase):
    """The regatta's scripted helmsman (`planners.Helmsman`, a policy of the
    observation) round each course."""
    return self.helmsman(self.observations()[rows])


class HarbourWorld(World):
  """The numba ships among a level's obstacles, stepped as `ShipHarbourVectorEnv`'s
  analytic batch: `ship_harbour_core.step_batch` sails and judges them, the ranges cast
  by `observe_batch`; each start drawn again off the obstacles (`sample_start`)."""

  id = "ShipHarbour-v0"
  # A ray grazing an island: its range moves as the square root of the ship's distance
  # from the tangent, so 1e-11 m between the ships can make 1e-9 m (8.3e-10 seen);
  # and it jumps where a ray meets an obstacle's edge, a step apart in float32.
  bound64 = 1e-6
  smooth = slice(0, 4)
  endings = World.endings | {harbour_core.AGROUND}
  episodes = N // 2

  def __init__(self, level, limit, n=N):
    self.level = level
    rules = ship_task.ShipRules("steer", limit)
    self.islands, self.piers = harbour_core.level_shapes(level)
    self.cells = harbour_core.level_cells(level)
    self.starts = np.array([harbour_core.sample_start(rules, _rng(i), self.islands, self.piers)
                            for i in range(n)])
    self.ships = self.starts.copy()
    self.limit = limit
    self.samples = np.zeros((n, core.SAMPLES_PER_CONTROL + 1, 2))
    self.steps = np.zeros(n, np.int64)
    self.outcome = (np.zeros(n, np.int64), np.zeros(n), np.zeros(n, np.bool_),
                    np.zeros(n, np.bool_))
    self.obs = np.zeros((n, harbour_core.OBSERVATION_SIZE))
    self.helmsman = planners.Helmsman("ship_harbour", level)

  def jax_starts(self, env, params):
    return jax.vmap(lambda s: env.reset_to(s, params))(self.starts)

  def step(self, r, live):
    harbour_core.step_batch(self.ships, r, live, self.samples, self.steps, True, self.islands,
                            self.piers, self.cells, self.limit, harbour_core.GATE_REWARD,
                            harbour_core.OUT_OF_BOUNDS_REWARD, self.outcome)
    return self.outcome

  def observations(self):
    harbour_core.observe_batch(self.ships, self.islands, self.piers, self.cells, self.obs)
    return self.obs

  def rates(self, rows, phase):
    """The harbour's scripted helmsman (`planners.Helmsman`: down the level's distance
    field round the obstacles, a policy of the observation)."""
    return self.helmsman(self.observations()[rows])


WORLDS = {"current": CurrentWorld, "goal": GoalWorld, "regatta": RegattaWorld,
          "harbour": HarbourWorld}


def helmsman(ships, target_x, target_y):
  """`ship_core.pilot_turn_rate` over rows of ships: the turning rate that heads for
  the targets, led past the heading error against the 5 s lag."""
  bearing = np.degrees(np.arctan2(target_x - ships[:, 0], target_y - ships[:, 1]))
  error = core.wrap_deg_array(bearing - ships[:, 2])
  wanted = np.clip(0.4 * error, -core.MAX_TURN_RATE, core.MAX_TURN_RATE)
  rate = wanted + 4.0 * (wanted - ships[:, 3]) / core.TIME_CONSTANT * 2.0
  return np.clip(rate, -core.MAX_TURN_RATE, core.MAX_TURN_RATE)


def controls(task, level, limit, seed, n=N):
  """(limit, n) turning rates: uniform in [-20, 20] deg/s (the clipping to 15 is
  exercised too); every tenth episode held hard over (it circles until the time
  limit, or until the current takes it off the field); every tenth from the fifth
  the scripted helmsman's, closed loop on a scout copy of the numba world (the
  rates it gave, replayed in both worlds, are the same controls for both), so that
  every ending comes."""
  rng = np.random.default_rng(seed)
  r = rng.uniform(-20.0, 20.0, (limit, n))
  r[:, ::10] = rng.uniform(14.0, 20.0, (limit, len(range(0, n, 10))))
  scout = WORLDS[task](level, limit, n)
  piloted = np.arange(5, n, 10)
  phase = np.zeros(len(piloted), np.bool_)
  live = np.ones(n, np.bool_)
  for t in range(limit):
    r[t, piloted] = scout.rates(piloted, phase)
    _, _, terminated, truncated = scout.step(np.clip(r[t], -core.MAX_TURN_RATE,
                                                     core.MAX_TURN_RATE), live)
    live &= ~(terminated | truncated)
    if not live[piloted].any():
      break
  return r


@functools.cache
def runner(env_id, x64):
  """`(env, run)`: `env_id`'s world and the compiled scan of `CHUNK` vmapped steps of
  it, its parameters an argument (one compile serves every level, as one `env`
  serves their starts: `reset_to` is compiled for the instance)."""
  env, _ = hpg_jax.make(env_id)
  step = jax.vmap(env.step_env, in_axes=(None, 0, 0, None))
  key = jax.random.PRNGKey(0)          # the ladder's steps draw nothing

  @jax.jit
  def run(state, controls, params):
    def body(state, r):
      obs, state, reward, _, info = step(key, state, r, params)
      return state, (obs, reward, info["terminated"], info["truncated"], info["event"])
    return jax.lax.scan(body, state, controls)
  return env, run


def compare(task, level, limit, *, x64, seed=0):
  """Sails the 1,000 episodes of `task` at `level` in both worlds under the same
  controls and returns what differs: the largest observation and reward errors over
  every step both took, the episodes whose ending (how and at which step) differs,
  and the endings' counts."""
  previous = jax.config.jax_enable_x64
  jax.config.update("jax_enable_x64", x64)
  try:
    return _compare(task, level, limit, x64, seed)
  finally:
    jax.config.update("jax_enable_x64", previous)


def _compare(task, level, limit, x64, seed):
  world = WORLDS[task](level, limit, WORLDS[task].episodes)
  n = len(world.starts)
  _, params = hpg_jax.make(world.id, level=level, max_steps_in_episode=limit)
  rates = controls(task, level, limit, seed, n)
  env, run = runner(world.id, x64)
  _, state = world.jax_starts(env, params)
  dtype = env.action_space(params).dtype
  live = np.ones(n, np.bool_)                 # followed in both worlds
  obs_error = state_error = smooth_error = reward_error = 0.0
  ended_jax = np.full((n, 2), -9, np.int64)   # (how, step) of each ending: the event,
  ended_numba = np.full((n, 2), -9, np.int64)  # or TRUNCATED
  t0 = 0
  while live.any() and t0 < limit:
    length = min(CHUNK, limit - t0)
    chunk = np.zeros((CHUNK, n))
    chunk[:length] = rates[t0:t0 + length]
    state, out = run(state, chunk[:, :, None].astype(dtype), params)
    obs, reward, term, trunc, event = map(np.asarray, out)
    seen = np.empty((length, *obs.shape[1:]))    # the numba world's, compared after
    rewards = np.empty((length, n))
    followed = np.empty((length, n), np.bool_)
    for k in range(length):
      n_event, n_reward, n_term, n_trunc = world.step(
          np.clip(chunk[k], -core.MAX_TURN_RATE, core.MAX_TURN_RATE), live)
      seen[k], rewards[k], followed[k] = world.observations(), n_reward, live
      t = t0 + k + 1
      n_end = live & (n_term | n_trunc)
      j_end = live & (term[k] | trunc[k])
      if n_end.any():
        ended_numba[n_end] = np.stack([np.where(n_trunc, TRUNCATED, n_event)[n_end],
                                       np.full(n_end.sum(), t)], axis=1)
      if j_end.any():
        ended_jax[j_end] = np.stack([np.where(trunc[k], TRUNCATED, event[k])[j_end],
                                     np.full(j_end.sum(), t)], axis=1)
      live &= ~(n_end | j_end)      # an episode that ended in either is followed no further
    error = np.abs(obs[:length] - seen)
    for a in world.angles:          # a heading either side of 180
      error[..., a] = np.minimum(error[..., a], 360.0 - error[..., a])
    error[~followed] = 0.0
    obs_error = max(obs_error, float(error.max()))
    state_error = max(state_error, float(error[..., :4].max()))
    smooth_error = max(smooth_error, float(error[..., world.smooth].max()))
    reward_error = max(reward_error, float(np.abs(reward[:length] - rewards)[followed].max(
        initial=0.0)))
    t0 += length
  differ = np.flatnonzero((ended_jax != ended_numba).any(axis=1))
  how, counts = np.unique(ended_numba[:, 0], return_counts=True)
  return {"obs_error": obs_error, "state_error": state_error, "smooth_error": smooth_error,
          "reward_error": reward_error, "differ": differ,
          "endings": dict(zip(how.tolist(), counts.tolist())), "steps": t0}


# (task, level) -> the step limit: every ending comes (the gate or the finish, leaving
# the field, an obstacle, truncation); the regatta's helmsman takes 590-930 steps a lap.
LIMITS = ({("current", level): 600 for level in LEVELS} | {("goal", level): 800 for level in LEVELS}
          | {("regatta", level): 1000 for level in LEVELS}
          | {("harbour", level): 600 for level in LEVELS})


@pytest.mark.parametrize("case", sorted(LIMITS), ids="-".join)
def test_the_ladders_jax_worlds_sail_the_numba_worlds_trajectories_in_float64(case):
  result = compare(*case, LIMITS[case], x64=True)
  print(case, result)
  world = WORLDS[case[0]]
  assert result["state_error"] < 1e-9 and result["reward_error"] < 1e-9, result
  assert result["obs_error"] < world.bound64, result
  assert result["differ"].size == 0, result
  assert set(result["endings"]) == world.endings_of(case[1]), result


@pytest.mark.parametrize("case", sorted(LIMITS), ids="-".join)
def test_float32_keeps_the_endings_and_stays_within_centimetres(case):
  result = compare(*case, LIMITS[case], x64=False)
  print(case, result)
  assert result["smooth_error"] < 0.05, result
  assert result["differ"].size <= WORLDS[case[0]].episodes // 100, result


def test_a_level_is_the_worlds_default_parameters():
  for level in LEVELS:
    _, params = hpg_jax.make("ShipCurrent-v0", level=level)
    assert (params.uniform_x, params.uniform_y, params.river, params.cross) == \
        current_core.LEVELS[level]
    _, params = hpg_jax.make("hpg_mj/ShipGoal-v0", level=level)
    assert (params.gate_low, params.gate_high, params.gate_heading_deg) == \
        goal_core.LEVELS[level]
    _, params = hpg_jax.make("ShipRegatta-v0", level=level)
    assert (params.gates, params.spacing, params.smallest_turn_deg,
            params.largest_turn_deg) == regatta_core.LEVELS[level]
    _, params = hpg_jax.make("ShipHarbour-v0", level=level)
    islands, piers = harbour_core.LEVELS[level]
    assert params.islands[:len(islands)] == islands and params.piers[:len(piers)] == piers
  assert hpg_jax.make("ShipGoal-v0")[1] == hpg_jax.make("ShipGoal-v0", level="easy")[1]
  with pytest.raises(ValueError, match=r"^hpg_mj/ShipCurrent-v0: unknown level 'stormy'; "
                                       r"allowed levels: \['easy', 'medium', 'hard'\]$"):
    hpg_jax.make("ShipCurrent-v0", level="stormy")
  with pytest.raises(ValueError, match=r"^hpg_mj/ShipSteering-v0 has no levels \(level='hard'\); "
                                       r"the ids with levels: \['ShipCurrent-v0', 'ShipGoal-v0'"):
    hpg_jax.make("ShipSteering-v0", level="hard")



@pytest.mark.parametrize("task", ship_ladder.TASKS)
def test_each_levels_time_limit_closes_the_jax_episode_whatever_the_params_ask(task):
  # The default step limit is the level's (`ship_ladder.episode_steps`); a larger
  # `max_steps_in_episode` does not reopen an episode that a time limit closed, a smaller
  # one holds (the regatta's truncation itself: test_jax_regatta_harbour.py).
  for level in LEVELS:
    env, params = hpg_jax.make(ship_ladder.ENV_IDS[task], level=level)
    limit = ship_ladder.episode_steps(task, level)
    assert params.max_steps_in_episode == limit, level
    assert int(env.closes(params.replace(max_steps_in_episode=10_000))) == \
        ship_ladder.episode_steps(task, level, 10_000), level
    assert int(env.closes(params.replace(max_steps_in_episode=300))) == 300, level

def test_the_goals_gates_are_drawn_from_the_levels_ranges():
  env, _ = hpg_jax.make("ShipGoal-v0")
  n = 1000
  reset = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))   # one compile: a level is params
  for seed, level in enumerate(LEVELS):
    params = hpg_jax.make("ShipGoal-v0", level=level)[1]
    keys = jax.random.split(jax.random.PRNGKey(seed), n)
    obs, state = reset(keys, params)
    parts = {k: np.asarray(v, np.float64) for k, v in ship_goal.split_obs(obs).items()}
    low, high, largest = goal_core.LEVELS[level]
    gate = parts["desired_goal"]
    assert np.array_equal(gate, np.asarray(state.desired, np.float64))
    assert (gate[:, :2] >= low).all() and (gate[:, :2] <= high).all()
    heading = np.abs(np.degrees(np.arctan2(gate[:, 2], gate[:, 3])))
    assert largest * 0.99 < heading.max() <= largest + 1e-3
    assert np.allclose(np.hypot(gate[:, 2], gate[:, 3]), 1.0, atol=1e-6)
    ship = parts["observation"]
    assert np.allclose(parts["achieved_goal"][:, 2], np.sin(np.radians(ship[:, 2])), atol=1e-5)
    assert (ship[:, :2] >= 0.0).all() and (ship[:, :2] <= 1000.0).all()
    space = env.observation_space(params)
    assert (np.asarray(obs) >= space.low).all() and (np.asarray(obs) <= space.high).all()


def test_a_policy_of_the_flat_observation_is_scored_through_join_obs():
  """A policy written on the JAX goal's flat observation is scored by `evaluate`, which
  hands it the Gymnasium dictionary, through `join_obs` (`split_obs`'s inverse): the
  same numbers as the same rule written on the dictionary. A wrong shape is refused."""
  from hpg_mj import benchmark
  env, params = hpg_jax.make("ShipGoal-v0", level="medium")
  obs, _ = env.reset(jax.random.PRNGKey(0), params)
  assert np.array_equal(np.asarray(ship_goal.join_obs(ship_goal.split_obs(obs))), np.asarray(obs))

  def toward_gate(ship, gate):          # full rudder towards the gate's point
    bearing = np.degrees(np.arctan2(gate[..., 0] - ship[..., 0], gate[..., 1] - ship[..., 1]))
    error = (bearing - ship[..., 2] + 180.0) % 360.0 - 180.0
    return np.clip(error, -15.0, 15.0)[..., None]
  def on_flat(x):                       # a policy of the JAX environment's observation
    return toward_gate(x[..., ship_goal.OBSERVATION], x[..., ship_goal.DESIRED_GOAL])
  flat = benchmark.evaluate(lambda o: on_flat(ship_goal.join_obs(o)), "ship_goal", 30,
                            level="medium", batched=True)
  on_dict = benchmark.evaluate(lambda o: toward_gate(o["observation"], o["desired_goal"]),
                               "ship_goal", 30, level="medium", batched=True)
  assert flat.metrics == on_dict.metrics
  with pytest.raises(ValueError, match=r"^split_obs takes the goal's flat observation, a "
                                       r"last axis of 19; got shape \(6,\)"):
    ship_goal.split_obs(jax.numpy.zeros(6))
  with pytest.raises(ValueError, match=r"^join_obs takes the goal's dictionary of .*\['ranges'\] "
                                       r"missing"):
    ship_goal.join_obs({k: v for k, v in ship_goal.split_obs(obs).items() if k != "ranges"})


def test_the_goals_compute_reward_is_the_numba_rule(x64):
  """Relabelled goals (what Hindsight Experience Replay asks): the JAX rule gives
  `ship_goal_core.compute_reward`'s rewards exactly, gates passed or not."""
  rng = np.random.default_rng(7)
  desired = np.array([goal_core.sample_gate(rng, "hard") for _ in range(4000)])
  achieved = desired.copy()
  achieved[:, :2] += rng.uniform(-60.0, 60.0, (4000, 2)) * rng.uniform(0.0, 1.0, (4000, 1)) ** 3
  turn = np.radians(rng.uniform(-90.0, 90.0, 4000))
  achieved[:, 2:] = np.stack([desired[:, 2] * np.cos(turn) + desired[:, 3] * np.sin(turn),
                              desired[:, 3] * np.cos(turn) - desired[:, 2] * np.sin(turn)], 1)
  achieved[::7, :2] = rng.uniform(-50.0, 1050.0, (len(range(0, 4000, 7)), 2))  # off the field too
  for level in ("medium", "hard"):                  # the hard gate's tolerances are its own
    tolerance = goal_core.level_tolerance(level)
    env, params = hpg_jax.make("ShipGoal-v0", level=level, gate_reward=50.0)
    expected = goal_core.compute_reward(achieved, desired, 50.0, -100.0, tolerance)
    got = np.asarray(jax.jit(env.compute_reward)(achieved, desired, params))
    assert np.array_equal(got, expected)
    assert {-1.0, 49.0, -101.0} <= set(expected.tolist())
    assert float(env.compute_reward(achieved[0], desired[0])) == goal_core.compute_reward(
        achieved[0], desired[0], 100.0, -100.0, tolerance)
  medium, hard = (goal_core.compute_reward(achieved, desired, 50.0, -100.0,
                                           goal_core.level_tolerance(level)) == 49.0
                  for level in ("medium", "hard"))
  assert hard.sum() < medium.sum() and not (hard & ~medium).any()   # hard's a subset


@pytest.fixture
def x64():
  previous = jax.config.jax_enable_x64
  jax.config.update("jax_enable_x64", True)
  yield
  jax.config.update("jax_enable_x64", previous)


def test_the_benchmark_times_any_ladder_world_at_any_level_and_refuses_others(capsys):
  """`python -m hpg_mj.jax.bench --task WORLD/LEVEL` (a newcomer timing their own
  task's world): the ladder's worlds and levels are the package's, a run prints the
  named task's row, and a name outside them is refused naming what is allowed."""
  from hpg_mj.jax import bench
  assert {bench.task(f"{world}/{level}")[0] for world in ("current", "goal", "regatta", "harbour")
          for level in ship_ladder.LEVELS} == set(ship_ladder.ENV_IDS.values())
  assert bench.task("ship_goal/medium") == bench.task("goal/medium")     # the scorer's name
  bench.main(["--envs", "4", "--steps", "3", "--task", "current/hard"])
  rows = capsys.readouterr().out.splitlines()[1:]
  assert len(rows) == 1 and rows[0].startswith("current/hard ") and "numba" in rows[0]
  with pytest.raises(SystemExit):
    bench.main(["--task", "current/extreme"])
  assert "--task 'current/extreme': allowed ship, taxi_fuel" in capsys.readouterr().err
