"""The JAX taxis equal the numba taxis (issue 42): 1,000 seeded starts of taxi-fuel and
of the classic taxi, driven by the same seeded actions through `hpg_mj.jax`'s taxi
(vmapped, scanned) and through `taxi_rules.step_batch` (the compiled step of the
native vector environment), give the same observations, rewards and endings at every
step, exactly (integer rules), in float64 and in float32 alike."""
import numpy as np
import pytest

pytest.importorskip("jax.numpy")   # not `jax`: tests/ is on sys.path and holds tests/jax
import jax  # noqa: E402

import hpg_mj.jax as hpg_jax  # noqa: E402
from hpg_mj.worlds import taxi_core as core  # noqa: E402
from hpg_mj.worlds import taxi_pilot  # noqa: E402
from hpg_mj.worlds import taxi_rules  # noqa: E402
from hpg_mj.worlds import taxi_values  # noqa: E402

N = 1000


def starts(rules, n=N):
  """Start i drawn as the rules draw it, from numpy's generator seeded 1,000,000 + i."""
  return np.array([rules.sample_start(np.random.default_rng(1_000_000 + i)) for i in range(n)])


# Episode i's driver, by i % 5: the optimal action (value iteration, `taxi_values`)
# with probability 1 - epsilon, else a uniform one, for each epsilon below; and a
# driver who goes to F and fills up there for ever (`taxi_pilot`'s shortest path;
# without fuel, uniform actions), so that deliveries, illegal actions, empty tanks
# and the time limit all come.
EPSILONS = (0.0, 0.2, 0.5, 1.0)


def compare(fuel, x64, n=N, seed=0):
  """Drives `n` episodes through both worlds under the same actions (the JAX taxi's
  epsilon-greedy choices, replayed in the numba world) and returns the counts of
  what differs and how the episodes ended."""
  previous = jax.config.jax_enable_x64
  jax.config.update("jax_enable_x64", x64)
  try:
    return _compare(fuel, n, seed)
  finally:
    jax.config.update("jax_enable_x64", previous)


def _compare(fuel, n, seed):
  env, params = hpg_jax.make("TaxiFuel-v0" if fuel else "Taxi-v0")
  rules = core.TaxiRules(fuel)
  limit = rules.max_steps
  step = jax.vmap(env.step_env, in_axes=(None, 0, 0, None))
  greedy = jax.numpy.asarray(taxi_values.taxi_values(fuel).q.argmax(axis=1), np.int32)
  epsilon = jax.numpy.asarray(np.resize(EPSILONS + (1.0,), n))
  refuels = jax.numpy.asarray((np.arange(n) % 5 == 4) & fuel)
  _, first = taxi_pilot.distances_to(core.FUEL_STATION)
  to_fuel = np.full(core.GRID_SIZE * core.GRID_SIZE, core.FILLUP, np.int32)
  for (row, col), move in first.items():
    to_fuel[row * core.GRID_SIZE + col] = move
  to_fuel = jax.numpy.asarray(to_fuel)

  def choose(key, state):
    index = ((state.row * core.GRID_SIZE + state.col) * 5 + state.passenger) * 4 \
        + state.destination                       # taxi_core.encode_state
    if fuel:
      index = index + core.NUM_CLASSIC_STATES * state.fuel
    explore, uniform = jax.random.split(key)
    random = jax.random.randint(uniform, index.shape, 0, rules.num_actions)
    chosen = jax.numpy.where(jax.random.uniform(explore, index.shape) < epsilon, random,
                             greedy[index])
    return jax.numpy.where(refuels, to_fuel[state.row * core.GRID_SIZE + state.col], chosen)

  @jax.jit
  def run(state, keys):
    def body(state, key):
      action = choose(key, state)
      obs, state, reward, _, info = step(key, state, action, params)
      return state, (action, obs, reward, info["terminated"], info["truncated"],
                     info["outcome"])
    return jax.lax.scan(body, state, keys)

  begin = starts(rules, n)
  n_obs = 5 if fuel else 4
  _, state = jax.vmap(lambda s: env.reset_to(s, params))(begin[:, :n_obs])
  _, out = run(state, jax.random.split(jax.random.PRNGKey(seed), limit))
  actions, obs, reward, term, trunc, outcome = map(np.asarray, out)

  world = taxi_rules.world_config(rules)
  taxis = begin.astype(np.int64)
  steps = np.zeros(n, dtype=np.int64)
  n_reward, n_term, n_trunc = np.zeros(n), np.zeros(n, np.bool_), np.zeros(n, np.bool_)
  masks = np.zeros((n, rules.num_actions), dtype=np.int8)
  live = np.ones(n, dtype=np.bool_)
  differ = {"obs": 0, "reward": 0, "terminated": 0, "truncated": 0}
  endings = {}
  for t in range(limit):
    if not live.any():
      break
    taxi_rules.step_batch(taxis, actions[t].astype(np.int64), live, steps, world, n_reward, n_term, n_trunc,
                          masks)
    differ["obs"] += int((obs[t][live] != taxis[live, :n_obs]).any(axis=1).sum())
    differ["reward"] += int((reward[t][live] != n_reward[live]).sum())
    differ["terminated"] += int((term[t][live] != n_term[live]).sum())
    differ["truncated"] += int((trunc[t][live] != n_trunc[live]).sum())
    ended = live & (n_term | n_trunc)
    how = np.where(n_trunc, taxi_rules.TRUNCATED, outcome[t])
    for code in how[ended].tolist():
      endings[code] = endings.get(code, 0) + 1
    live &= ~(ended | term[t] | trunc[t])
  return {"differ": differ, "endings": endings}


@pytest.mark.parametrize("fuel", [True, False], ids=["fuel", "classic"])
@pytest.mark.parametrize("x64", [True, False], ids=["float64", "float32"])
def test_the_jax_taxi_drives_the_numba_taxis_episodes_exactly(fuel, x64):
  result = compare(fuel, x64)
  assert result["differ"] == {"obs": 0, "reward": 0, "terminated": 0, "truncated": 0}, result
  assert sum(result["endings"].values()) == N
  # Deliveries, empty tanks (with fuel) and the time limit all come, so each is compared.
  expected = {taxi_rules.DELIVERED, taxi_rules.TRUNCATED}
  assert set(result["endings"]) == expected | ({taxi_rules.OUT_OF_FUEL} if fuel else set())
  # The episode's outcome code agrees with the rule that ended it.
  assert result["endings"][taxi_rules.DELIVERED] > 10, result
