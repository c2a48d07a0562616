"""`hpg_mj.jax` keeps gymnax's interface (issue 42): `make` by the Gymnasium ids,
`reset(key, params)` and `step(key, state, action, params)` jitted, vmapped and
scanned, the auto-reset of gymnax's `step`, float64 on request, one-line errors for
bad input; and the rest of hpg_mj never imports JAX."""
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("jax.numpy")   # not `jax`: tests/ is on sys.path and holds tests/jax
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import hpg_mj.jax as hpg_jax  # noqa: E402
from hpg_mj.jax import environment  # noqa: E402
from hpg_mj.worlds import ship_core  # noqa: E402

SHORT_IDS = sorted(i.split("/", 1)[1] for i in hpg_jax.ENV_IDS)


@pytest.fixture
def x64():
  previous = jax.config.jax_enable_x64
  jax.config.update("jax_enable_x64", True)
  yield
  jax.config.update("jax_enable_x64", previous)


def test_the_ids_are_the_gymnasium_ids():
  from hpg_mj import envs
  assert set(hpg_jax.ENV_IDS) == set(envs.ENV_IDS)
  env, params = hpg_jax.make("ShipSteering-v0")
  same, same_params = hpg_jax.make("hpg_mj/ShipSteering-v0")
  assert env.name == same.name == "hpg_mj/ShipSteering-v0" and params == same_params
  assert params.max_steps_in_episode == ship_core.STEER_MAX_STEPS
  assert hpg_jax.make("ShipPatrol-v0")[1].max_steps_in_episode == ship_core.HOUR_STEPS
  _, changed = hpg_jax.make("ShipSteering-v0", out_of_bounds_reward=-300.0)
  assert changed.out_of_bounds_reward == -300.0 and changed.gate_reward == 100.0


def test_bad_ids_and_parameters_are_refused_in_one_line():
  with pytest.raises(ValueError, match=r"unknown hpg_mj.jax environment id 'ShipSteering'; "
                                       r"valid ids: \['ShipCurrent-v0'"):
    hpg_jax.make("ShipSteering")
  with pytest.raises(ValueError, match=r"hpg_mj/Taxi-v0: unknown parameter\(s\) \['fuel'\]; "
                                       r"allowed: \['max_steps_in_episode'"):
    hpg_jax.make("Taxi-v0", fuel=False)
  _, params = hpg_jax.make("ShipCurrent-v0")           # a subclass's own fields named
  with pytest.raises(ValueError, match=r"CurrentParams.replace: unknown parameter\(s\) "
                                       r"\['rivr'\]; allowed: \[.*'river'"):
    params.replace(rivr=2.0)
  assert params.replace(river=2.0).river == 2.0


@pytest.mark.parametrize("env_id, given, message", [
    ("ShipSteering-v0", {"max_steps_in_episode": 0}, "max_steps_in_episode must be at least 1, got 0"),
    ("ShipSteering-v0", {"max_steps_in_episode": 2.5}, "max_steps_in_episode must be a whole number"),
    ("ShipSteering-v0", {"max_steps_in_episode": "300"}, "max_steps_in_episode must be a number, got '300'"),
    ("ShipSteering-v0", {"speed": float("nan")}, "speed must be a finite number, got nan"),
    ("ShipSteering-v0", {"time_constant": 0.0}, "time_constant must be above 0, got 0.0"),
    ("ShipRegatta-v0", {"gates": 12}, "gates must be in 1..8, got 12"),
    ("ShipGoal-v0", {"gate_low": 900.0}, r"gate_low \(900.0\) may not exceed gate_high \(500.0\)"),
    ("ShipGoal-v0", {"min_cos": 2.0}, r"min_cos must be in \[-1, 1\], got 2.0"),
    ("ShipHarbour-v0", {"islands": ((500.0, 500.0, 50.0),)},
     r"islands must be 4 rows of 3 finite numbers \(rows of zeros for none"),
    ("TaxiFuel-v0", {"fuel_row": 7}, "fuel_row must be in 0..4, got 7"),
    ("TaxiFuel-v0", {"start_fuel_max": 20}, r"start_fuel_max \(20\) may not exceed capacity \(12\)"),
])
def test_a_parameter_make_cannot_take_is_refused_naming_what_is_allowed(env_id, given, message):
  """A value of the right name but one the environment cannot take (it had sailed on: a
  step limit of 0 ended every episode at once, NaN spread through every state)."""
  with pytest.raises(ValueError, match=f"^hpg_mj/{env_id}: {message}"):
    hpg_jax.make(env_id, **given)


def test_a_ladder_task_may_be_named_as_the_scorer_names_it():
  env, params = hpg_jax.make("ship_current/hard")
  same, same_params = hpg_jax.make("ShipCurrent-v0", level="hard")
  assert env.env_id == same.env_id and params == same_params
  assert hpg_jax.make("ship_goal", level="medium")[1] == hpg_jax.make("ShipGoal-v0",
                                                                      level="medium")[1]
  with pytest.raises(ValueError, match=r"^'ship_current/hard' names level 'hard' and "
                                       r"level='easy' another; give the level once"):
    hpg_jax.make("ship_current/hard", level="easy")
  with pytest.raises(ValueError, match=r"^hpg_mj/ShipCurrent-v0: unknown level 'stormy'"):
    hpg_jax.make("ship_current/stormy")


def test_evaluate_gives_a_jitted_batched_policy_one_batch_size():
  """A batched policy `jax.jit` made compiles once an input shape; `evaluate`'s batch
  of live episodes shrinks as they end (a newcomer's took 107 s, 1.6 s with
  `fixed_batch`). Given one, `evaluate` pads the batches itself: one compile, the same
  scores as the function unjitted."""
  from hpg_mj import benchmark

  def toward_north(obs):
    return jnp.clip(-obs[:, 2:3] - obs[:, 3:4], -15.0, 15.0)
  jitted = jax.jit(toward_north)
  scored = benchmark.evaluate(jitted, "ship", 40, batched=True, num_envs=16)
  assert jitted._cache_size() == 1
  plain = benchmark.evaluate(lambda o: np.asarray(toward_north(jnp.asarray(o, jnp.float32))),
                             "ship", 40, batched=True, num_envs=16)
  assert scored.metrics == plain.metrics


def test_values_make_can_take_are_kept_as_given():
  import jax.numpy as jnp
  _, params = hpg_jax.make("ShipSteering-v0", speed=jnp.float32(2.0), max_steps_in_episode=300)
  assert float(params.speed) == 2.0 and params.max_steps_in_episode == 300
  _, params = hpg_jax.make("ShipGoal-v0", level="hard", min_cos=0.5, gate_low=150.0)
  assert params.min_cos == 0.5 and params.gate_low == 150.0


def test_bad_actions_and_states_are_refused_naming_what_is_allowed():
  key = jax.random.PRNGKey(0)
  ship, params = hpg_jax.make("ShipSteering-v0")
  _, state = ship.reset(key, params)
  with pytest.raises(ValueError, match=r"ShipSteering-v0: the action is the turning rate r in "
                                       r"deg/s, a number of shape \(1,\) or \(\), got shape \(2,\)"):
    ship.step(key, state, jnp.zeros(2), params)
  with pytest.raises(ValueError, match=r"state theta_dot_deg=20.0 is outside the allowed"):
    ship.reset_to(np.array([500.0, 500.0, 0.0, 20.0]), params)
  with pytest.raises(ValueError, match=r"reset_to takes a ship state .* shape \(4,\), got"):
    ship.reset_to(np.zeros(3), params)
  taxi, params = hpg_jax.make("Taxi-v0")
  _, state = taxi.reset(key, params)
  with pytest.raises(ValueError, match=r"Taxi-v0: the action is one integer, shape \(\) or "
                                       r"\(1,\) \(0 South, .*, 5 Dropoff\), got shape \(\) of "
                                       r"dtype float32"):
    taxi.step(key, state, jnp.float32(1.0), params)
  with pytest.raises(ValueError, match=r"state passenger=1 waits at its own destination"):
    taxi.reset_to(np.array([0, 0, 1, 1]), params)


# One compile each (seconds): the continuing ship (its restarts inside a step) and
# the taxi; the steering task resets in the test below, and every task steps inside
# the scans of test_jax_ship.py, test_jax_taxi.py and test_jax_ladder.py.
@pytest.mark.parametrize("env_id", ["ShipPatrol-v0", "TaxiFuel-v0"])
def test_reset_and_step_jit_vmap_and_scan_with_gymnaxs_auto_reset(env_id):
  env, params = hpg_jax.make(env_id)
  params = params.replace(max_steps_in_episode=40)   # every episode ends in the scan
  keys = jax.random.split(jax.random.PRNGKey(1), 64)
  obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
  space = env.observation_space(params)
  assert obs.shape == (64, *space.shape) and bool(jax.vmap(space.contains)(obs).all())

  @jax.jit
  def rollout(state, key):
    def body(state, key):
      act_key, step_key = jax.random.split(key)
      actions = jax.vmap(env.action_space(params).sample)(jax.random.split(act_key, 64))
      obs, state, reward, done, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
          jax.random.split(step_key, 64), state, actions, params)
      return state, (obs, state.time, reward, done, info["terminated"], info["truncated"])
    return jax.lax.scan(body, state, jax.random.split(key, 100))

  _, (obs, time, reward, done, terminated, truncated) = rollout(state, jax.random.PRNGKey(2))
  done = np.asarray(done)
  assert done.any(axis=0).all()                       # every copy ended at least once
  assert np.array_equal(done, np.asarray(terminated | truncated))
  assert (np.asarray(time)[done] == 0).all()          # auto-reset: the new episode's start
  assert (np.asarray(time)[~done] > 0).all() and np.isfinite(np.asarray(reward)).all()
  assert bool(jax.vmap(jax.vmap(space.contains))(obs).all())


def test_step_resets_from_the_second_half_of_its_key_as_gymnax():
  env, params = hpg_jax.make("ShipSteering-v0")
  _, state = env.reset_to(jnp.array([1.0, 500.0, -90.0, 0.0]), params)   # leaves at once
  key = jax.random.PRNGKey(3)
  obs, new, reward, done, info = env.step(key, state, jnp.zeros(1), params)
  start_obs, start = env.reset(jax.random.split(key)[1], params)
  assert bool(done) and int(info["event"]) == ship_core.FAILURE and float(reward) == -101.0
  assert float(info["discount"]) == 0.0 and bool(info["terminated"])
  assert np.array_equal(obs, start_obs) and int(new.time) == 0


def test_float64_on_request(x64):
  # The types of reset and step, traced and not compiled (jax.eval_shape).
  key = jax.random.PRNGKey(0)
  for env_id, obs_dtype in (("ShipSteering-v0", jnp.float64), ("TaxiFuel-v0", jnp.int32)):
    env, params = hpg_jax.make(env_id)
    obs, state = jax.eval_shape(env.reset, key, params)
    action = jax.eval_shape(env.action_space(params).sample, key)
    _, _, reward, _, info = jax.eval_shape(env.step, key, state, action, params)
    assert obs.dtype == env.observation_space(params).dtype == obs_dtype
    assert reward.dtype == info["discount"].dtype == jnp.float64
  assert state.fuel.dtype == jnp.int32


def test_the_spaces_are_gymnaxs_two_kinds():
  ship, params = hpg_jax.make("ShipSteeringDiagonal-v0")
  box = ship.action_space(params)
  assert isinstance(box, environment.Box) and box.shape == (1,) and ship.num_actions == 1
  assert (box.low, box.high) == (-15.0, 15.0)
  taxi, params = hpg_jax.make("TaxiFuel-v0")
  discrete = taxi.action_space(params)
  assert isinstance(discrete, environment.Discrete) and discrete.n == 7 == taxi.num_actions
  samples = jax.vmap(discrete.sample)(jax.random.split(jax.random.PRNGKey(0), 500))
  assert set(np.asarray(samples).tolist()) == set(range(7))
  assert hpg_jax.make("Taxi-v0")[0].action_space().n == 6


def _run(code):
  done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
  assert done.returncode == 0, done.stderr[-3000:]
  return done.stdout


def test_the_core_never_imports_jax():
  out = _run("import sys, hpg_mj, hpg_mj.envs.vector, hpg_mj.worlds.ship_task, "
             "hpg_mj.worlds.taxi_rules, hpg_mj.benchmark, hpg_mj.cli, hpg_mj.jax\n"
             "print(sorted(m for m in sys.modules if m == 'jax' or m.startswith('jax.')))")
  assert out.strip() == "[]"


def test_without_jax_make_names_the_extra_in_one_line():
  out = _run("import sys\nsys.modules['jax'] = None\nimport hpg_mj.jax\n"
             "print(len(hpg_mj.jax.ENV_IDS))\n"
             "try:\n  hpg_mj.jax.make('TaxiFuel-v0')\nexcept ImportError as e:\n  print(e)")
  assert out.splitlines() == [str(len(hpg_jax.ENV_IDS)), "hpg_mj.jax needs JAX, which is not "
                               "installed: pip install hpg_mj[jax]"]


def test_a_plain_import_reaches_every_submodule_by_name():
  out = _run("import hpg_mj.jax\n"
             "print(hpg_mj.jax.ship_regatta.MAX_GATES, hpg_mj.jax.ship_harbour.MAX_ISLANDS)\n"
             "print(callable(hpg_mj.jax.ship_goal.split_obs))\n"
             "try:\n  hpg_mj.jax.ship_gaol\nexcept AttributeError as e:\n  print(e)")
  assert out.splitlines() == ["8 4", "True",
                              "module 'hpg_mj.jax' has no attribute 'ship_gaol'"]
  out = _run("import sys\nsys.modules['jax'] = None\nimport hpg_mj.jax\n"
             "try:\n  hpg_mj.jax.ship_goal\nexcept ImportError as e:\n  print(e)")
  assert out.strip() == "hpg_mj.jax needs JAX, which is not installed: pip install hpg_mj[jax]"


def test_with_gymnax_installed_the_spaces_are_gymnaxs():
  spaces = pytest.importorskip("gymnax.environments.spaces")
  assert isinstance(hpg_jax.make("Taxi-v0")[0].action_space(), spaces.Discrete)
  assert isinstance(hpg_jax.make("ShipSteering-v0")[0].action_space(), spaces.Box)


def test_where_needed_computes_only_the_copies_that_need_it():
  """`environment.where_needed`: `fn` where needed, zeros elsewhere, alike unbatched,
  vmapped (its rule: one copy at a time), vmapped twice and under jit; an unbatched
  argument is shared by every copy. (One compile: the four ways in one function.)"""
  def fn(key, scale):
    return {"draw": scale * jax.random.uniform(key, (3,)), "count": jnp.int32(7)}
  lazy = environment.where_needed(fn)

  @jax.jit
  def four_ways(needed, keys):
    return (jax.vmap(fn, in_axes=(0, None))(keys, 2.0),
            jax.vmap(lazy, in_axes=(0, 0, None))(needed, keys, 2.0),
            jax.vmap(jax.vmap(lazy, in_axes=(0, 0, None)), in_axes=(0, 0, None))(
                needed.reshape(2, 3), keys.reshape(2, 3, 2), 2.0),
            [lazy(needed[i], keys[i], 2.0) for i in range(2)])

  needed = np.array([True, False, True, True, False, False])
  want, got, twice, alone = four_ways(needed, jax.random.split(jax.random.PRNGKey(4), 6))
  for name in ("draw", "count"):
    assert np.array_equal(got[name][needed], want[name][needed])
    assert not np.asarray(got[name][~needed]).any()
    assert np.array_equal(np.asarray(twice[name]).reshape(got[name].shape), got[name])
    assert np.array_equal(alone[0][name], want[name][0]) and not np.asarray(alone[1][name]).any()


def test_xla_s_compiling_is_timed_apart_from_training_while_the_timer_is_open():
  """`hpg-mj train`'s and the runs' compile_seconds (`hpg_mj._compiling.timer`) count
  XLA's compiles of a JAX agent, not only numba's (a newcomer saw 0 for every JAX run)."""
  from hpg_mj import _compiling
  seconds = []
  with _compiling.timer(seconds.append):
    jax.jit(lambda x: jnp.tanh(x) @ x.T + 41.0)(jnp.ones((7, 7))).block_until_ready()
  told = len(seconds)
  assert told >= len(hpg_jax.COMPILE_EVENTS) and sum(seconds) > 0.0   # (jnp.ones is one too)
  jax.jit(lambda x: jnp.tanh(x) @ x.T + 43.0)(jnp.ones((7, 7))).block_until_ready()
  assert len(seconds) == told                              # closed: told nothing more
  from hpg_mj import agents
  assert _compiling.uses_jax(agents.build(agents.load_task("ship_ppo_jax"), seed=0))
  assert not _compiling.uses_jax(agents.build(agents.load_task("ship_hybrid"), seed=0))
