"""What the regatta and the harbour draw in JAX, where their generator is JAX's and
not numpy's (SPEC section 11; their trajectories are tests/jax/test_jax_ladder.py's):
the regatta's course laid by the numba rule itself (the same course from the same
uniforms), every course from a key keeping the layout's rules and drawn as the numba
world draws its courses, laid afresh by the auto-reset only where an episode ended;
the harbour's starts off its obstacles, and its rangefinders the numba world's on
the same states."""
import math

import numpy as np
import pytest
from scipy import stats

pytest.importorskip("jax.numpy")   # not `jax`: tests/ is on sys.path and holds tests/jax
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import hpg_mj.jax as hpg_jax  # noqa: E402
from hpg_mj.jax import ship_regatta  # noqa: E402
from hpg_mj.worlds import ship_core as core  # noqa: E402
from hpg_mj.worlds import ship_harbour_core as harbour_core  # noqa: E402
from hpg_mj.worlds import ship_regatta_core as regatta_core  # noqa: E402

LEVELS = ("easy", "medium", "hard")


@pytest.fixture
def x64():
  previous = jax.config.jax_enable_x64
  jax.config.update("jax_enable_x64", True)
  yield
  jax.config.update("jax_enable_x64", previous)


def _layout(params):
  return (params.gates, params.spacing, params.smallest_turn_deg, params.largest_turn_deg)


def test_the_regattas_course_is_the_numba_rules_on_the_same_uniforms(x64):
  """`lay_course` on the uniforms numpy gives: the numba rule's course (both sides
  tried, turns drawn again, a course given up) to rounding, and the same verdict."""
  lay = jax.jit(jax.vmap(ship_regatta.lay_course, in_axes=(0, None, None, None, None)))
  rng = np.random.default_rng(5)
  for level in LEVELS:
    gates, spacing, smallest, largest = regatta_core.LEVELS[level]
    draws = rng.uniform(0.0, 1.0, (400, ship_regatta.DRAWS))
    courses, laid = map(np.asarray, lay(draws, *_layout(hpg_jax.make(
        "ShipRegatta-v0", level=level)[1])))
    expected = np.zeros((len(draws), gates, 3))
    expected_laid = np.array([regatta_core.lay_course(
        d[:regatta_core.draws_per_course(gates)], spacing, smallest, largest, out)
        for d, out in zip(draws, expected)])
    assert np.array_equal(laid, expected_laid)
    assert 0 < laid.sum() < len(laid) or level != "easy"   # easy gives courses up often
    assert np.abs(courses[laid, :gates] - expected[laid]).max() < 1e-9
    assert (courses[:, gates:] == 0.0).all()


def _check_course(course, layout, tol):
  """The layout's rules on one course (rows `gates` on are zero): the centres on
  [100, 900] m, each leg `spacing` long and along the gate it leads to, the turn at
  each gate in the level's range, no two gates within 110 m. The turns' signs."""
  gates, spacing, smallest, largest = layout
  laid = course[:gates]
  assert (course[gates:] == 0.0).all()
  assert ((laid[:, :2] >= regatta_core.LOW - tol) & (laid[:, :2] <= regatta_core.HIGH + tol)).all()
  legs = np.diff(laid[:, :2], axis=0)
  assert np.allclose(np.hypot(*legs.T), spacing, atol=tol)
  bearing = np.degrees(np.arctan2(legs[:, 0], legs[:, 1]))
  assert np.allclose(core.wrap_deg_array(bearing - laid[1:, 2]), 0.0, atol=tol)
  turn = core.wrap_deg_array(np.diff(laid[:, 2]))
  assert ((np.abs(turn) >= smallest - tol) & (np.abs(turn) <= largest + tol)).all()
  apart = np.hypot(*(laid[:, None, :2] - laid[None, :, :2]).transpose(2, 0, 1))
  assert (apart[np.triu_indices(gates, 1)] >= regatta_core.MIN_SEPARATION - tol).all()
  return turn


def test_the_auto_reset_lays_courses_by_the_rule_only_where_an_episode_ended():
  """Per level, 512 copies stepped by `step` (gymnax's, with its auto-reset) vmapped
  and scanned over 48 steps, circling in episodes of 12 steps: where one ended, the
  new state is `reset`'s from the second half of the step's key (its course laid
  through `where_needed`, one copy at a time); where none ended, the course stays.
  Every new course (about 2,000 a level, float32) keeps the layout's rules, and their
  first and last gates' places and their turns are distributed as as many of the
  numba world's: two-sample Kolmogorov-Smirnov, each of the 12 held to p > 1e-4 (a
  false alarm for 0.1% of seeds; 100,000 courses of each world at medium, in
  float64, gave p >= 0.14 on all six coordinates of the first and last gates)."""
  env, _ = hpg_jax.make("ShipRegatta-v0")
  n, steps = 512, 48
  reset = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))   # one compile: a level is params

  @jax.jit
  def rollout(state, key, params):
    def body(state, key):
      keys = jax.random.split(key, n)
      _, state, _, done, _ = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
          keys, state, jnp.full((n, 1), 15.0), params)
      # The keys `step` resets from: the second half of each copy's.
      return state, (jax.vmap(lambda k: jax.random.split(k)[1])(keys), state, done)
    return jax.lax.scan(body, state, jax.random.split(key, steps))

  for seed, level in enumerate(LEVELS):
    params = hpg_jax.make("ShipRegatta-v0", level=level, max_steps_in_episode=12)[1]
    keys = np.asarray(jax.random.split(jax.random.PRNGKey(seed), n + 1))
    _, start = reset(keys[:n], params)
    _, (resets, states, done) = rollout(start, keys[n], params)
    courses, done = np.asarray(states.course, np.float64), np.asarray(done)
    assert done.any(axis=0).all() and done.sum() >= 4 * n
    assert (np.asarray(states.time)[done] == 0).all()
    assert (np.asarray(states.next_gate)[done] == 0).all()
    before = np.concatenate([np.asarray(start.course)[None], courses[:-1]])
    assert np.array_equal(courses[~done], before[~done])
    _, fresh = reset(np.asarray(resets)[done][:n], params)
    for name in ("course", "posts", "x", "y", "theta_deg", "theta_dot_deg"):
      assert np.array_equal(np.asarray(getattr(states, name))[done][:n],
                            np.asarray(getattr(fresh, name))), name
    layout = regatta_core.LEVELS[level]
    new = courses[done]
    turns = np.concatenate([_check_course(c, layout, 2e-3) for c in new])
    rng = np.random.default_rng(seed)
    numba = np.array([regatta_core.sample_course(rng, layout) for _ in range(len(new))])
    numba_turns = core.wrap_deg_array(np.diff(numba[:, :, 2], axis=1)).ravel()
    last = layout[0] - 1
    for ours, theirs in ((new[:, 0, 0], numba[:, 0, 0]), (new[:, 0, 1], numba[:, 0, 1]),
                         (new[:, last, 0], numba[:, last, 0]), (turns, numba_turns)):
      assert stats.ks_2samp(ours, theirs).pvalue > 1e-4, level
    assert 0.45 < (turns > 0).mean() < 0.55, level


def test_the_hard_course_closes_at_its_time_limit_whatever_the_params_ask():
  """At hard the default step limit is the level's time limit (1,000), and a larger
  `max_steps_in_episode` does not reopen the course: a circling ship is truncated at
  1,000 control steps, as the numba world's (tests/envs/test_ship_regatta_env.py)."""
  limit = regatta_core.TIME_LIMITS["hard"]
  env, params = hpg_jax.make("ShipRegatta-v0", level="hard")
  assert params.max_steps_in_episode == limit
  assert hpg_jax.make("ShipRegatta-v0", level="medium")[1].max_steps_in_episode == 5000
  params = params.replace(max_steps_in_episode=5000)
  _, state = env.reset_env(jax.random.PRNGKey(0), params)
  state = state.replace(x=jnp.asarray(500.0, state.x.dtype), y=jnp.asarray(500.0, state.x.dtype),
                        theta_dot_deg=jnp.asarray(15.0, state.x.dtype))

  def body(state, key):
    _, state, _, _, info = env.step_env(key, state, jnp.array([15.0]), params)
    return state, (info["terminated"], info["truncated"])
  _, (terminated, truncated) = jax.lax.scan(body, state, jax.random.split(
      jax.random.PRNGKey(1), limit))
  assert not np.asarray(terminated).any()
  assert np.flatnonzero(np.asarray(truncated)).tolist() == [limit - 1]


def test_the_harbours_starts_are_off_the_obstacles_and_its_ranges_the_numbas(x64):
  """Per level, 512 copies stepped by `step` vmapped and scanned over 40 steps, hard
  over in episodes of 10 (float64): where one ended, the new state and observation
  are `reset`'s from the second half of the step's key (computed through
  `where_needed`); every new start (about 2,000 a level) is on the field and off the
  obstacles (`ship_harbour_core.inside`), and its observation, the rangefinders
  included, is the numba world's on the same state."""
  env, _ = hpg_jax.make("ShipHarbour-v0")
  n, steps = 512, 40
  reset = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))

  @jax.jit
  def rollout(state, key, params):
    def body(state, key):
      keys = jax.random.split(key, n)
      obs, state, _, done, _ = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
          keys, state, jnp.full((n, 1), 15.0), params)
      return state, (jax.vmap(lambda k: jax.random.split(k)[1])(keys), obs, state, done)
    return jax.lax.scan(body, state, jax.random.split(key, steps))

  for seed, level in enumerate(LEVELS):
    params = hpg_jax.make("ShipHarbour-v0", level=level, max_steps_in_episode=10)[1]
    keys = np.asarray(jax.random.split(jax.random.PRNGKey(seed), n + 1))
    _, start = reset(keys[:n], params)
    _, (resets, obs, states, done) = rollout(start, keys[n], params)
    done, obs = np.asarray(done), np.asarray(obs)
    assert done.any(axis=0).all() and done.sum() >= 3 * n
    assert (np.asarray(states.time)[done] == 0).all()
    fresh_obs, fresh = reset(np.asarray(resets)[done][:n], params)
    assert np.array_equal(obs[done][:n], np.asarray(fresh_obs))
    for name in ("x", "y", "theta_deg", "theta_dot_deg"):
      assert np.array_equal(np.asarray(getattr(states, name))[done][:n],
                            np.asarray(getattr(fresh, name))), name
    new = obs[done]
    islands, piers = harbour_core.level_shapes(level)
    assert ((new[:, :2] >= 0.0) & (new[:, :2] <= core.FIELD_SIZE)).all()
    assert not any(harbour_core.inside(x, y, islands, piers) for x, y in new[:, :2])
    expected = np.zeros(new.shape)
    harbour_core.observe_batch(np.ascontiguousarray(new[:, :4]), islands, piers,
                               harbour_core.level_cells(level), expected)
    assert np.abs(new - expected).max() < 1e-9
    assert (new[:, 4:] < harbour_core.MAX_RANGE_M).any(axis=1).mean() > 0.1
    space = env.observation_space(params)
    assert ((new >= np.asarray(space.low)) & (new <= np.asarray(space.high))).all()


def test_the_harbour_refuses_a_start_on_an_obstacle_and_its_levels_are_parameters():
  env, params = hpg_jax.make("ShipHarbour-v0", level="hard")
  with pytest.raises(ValueError, match=r"^hpg_mj/ShipHarbour-v0: start position \(760.0, "
                                       r"780.0\) lies on an obstacle"):
    env.reset_to(np.array([760.0, 780.0, 0.0, 0.0]), params)
  islands, piers = harbour_core.LEVELS["hard"]
  assert params.islands == islands and params.piers == piers
  # Every level's parameters have the same shapes: the most islands and piers of any,
  # the unused rows zero.
  most_islands, most_piers = len(params.islands), len(params.piers)
  easy = hpg_jax.make("ShipHarbour-v0")[1]
  assert easy.islands[:2] == harbour_core.LEVELS["easy"][0]
  assert easy.piers == ((0.0,) * 5,) * most_piers and len(easy.islands) == most_islands
  # A harbour of one's own: one island across the steering task's start, in parameters.
  mine = params.replace(islands=((500.0, 500.0, 100.0),) + ((0.0,) * 3,) * (most_islands - 1),
                        piers=((0.0,) * 5,) * most_piers)
  obs, _ = env.reset_to(np.array([500.0, 300.0, 0.0, 0.0]), mine)
  assert math.isclose(float(obs[7]), 100.0, rel_tol=1e-5)     # the ray ahead meets it
  with pytest.raises(ValueError, match=r"^hpg_mj/ShipRegatta-v0: a course is 8 gates"):
    hpg_jax.make("ShipRegatta-v0", level="hard")[0].reset_to(
        np.array([500.0, 500.0, 0.0, 0.0]), np.array([[500.0, 500.0, 0.0]] * 3))
