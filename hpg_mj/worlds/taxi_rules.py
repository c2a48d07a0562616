"""The taxi world's rules for compiled loops (SPEC section 5): the int64 state and
world arrays, one primitive step with the episode's bookkeeping, and how an
episode ended. Every taxi agent's fused loop and step-by-step path use them.

A world state is an int64[5] array `(row, col, passenger, destination, fuel)`
(`taxi_core`'s layout); `world` is the int64 array of `world_config`.
"""
import numba
import numpy as np

from hpg_mj.worlds import taxi_core as core

N_STATIONS = 4
N_SQUARES = core.GRID_SIZE * core.GRID_SIZE

# The state array's fields.
ROW, COL, PASSENGER, DESTINATION, FUEL = range(5)

# `world_config`'s fields.
W_FUEL_ENABLED, W_FUEL_ROW, W_FUEL_COL, W_CAPACITY, W_MAX_STEPS, W_START_FUEL_MIN, \
    W_START_FUEL_MAX = range(7)

# The episode array: primitive steps, outcome, illegal Pickups/Dropoffs.
E_STEPS, E_OUTCOME, E_ILLEGAL = range(3)
RUNNING, DELIVERED, OUT_OF_FUEL, TRUNCATED = range(4)


def world_config(rules: core.TaxiRules = None) -> np.ndarray:
  """The int64 `world` array of a `taxi_core.TaxiRules` (SPEC defaults if None)."""
  if rules is None:
    rules = core.TaxiRules()
  if not isinstance(rules, core.TaxiRules):
    raise ValueError(f"world_config: rules must be a taxi_core.TaxiRules, got {type(rules).__name__}")
  return np.array([rules.fuel_enabled, rules.fuel_station[0], rules.fuel_station[1],
                   rules.capacity, rules.max_steps, rules.start_fuel[0], rules.start_fuel[1]],
                  dtype=np.int64)


@numba.njit(cache=True, inline="always")
def encoded(obs, world):
  """The state index (`taxi_core.encode_state`) of an observation given as numbers
  (row, col, passenger, destination[, fuel]; the fuel is not read in the classic task)."""
  fuel_enabled = world[W_FUEL_ENABLED] != 0
  fuel = np.int64(obs[FUEL]) if fuel_enabled else core.CLASSIC_FUEL
  return core.encode_state(np.int64(obs[ROW]), np.int64(obs[COL]), np.int64(obs[PASSENGER]),
                           np.int64(obs[DESTINATION]), fuel, fuel_enabled)


@numba.njit(cache=True, inline="always")
def episode_over(episode):
  """Whether the episode array says it has ended (delivered, out of fuel or cut)."""
  return episode[E_OUTCOME] != RUNNING


@numba.njit(cache=True, inline="always")
def step_state(state, action, world, fuel_enabled):
  """`taxi_step` on a state array, written back in place; returns (reward, terminated)."""
  row, col, passenger, destination, fuel, reward, terminated = core.taxi_step(
      state[ROW], state[COL], state[PASSENGER], state[DESTINATION], state[FUEL], action,
      fuel_enabled, world[W_FUEL_ROW], world[W_FUEL_COL], world[W_CAPACITY])
  state[ROW] = row
  state[COL] = col
  state[PASSENGER] = passenger
  state[DESTINATION] = destination
  state[FUEL] = fuel
  return reward, terminated


@numba.njit(cache=True, inline="always")
def primitive_step(state, episode, action, world):
  """Executes a primitive action (Algorithm 1, line 4) and returns its reward.

  Updates `state` and `episode` (steps, illegal count, outcome: DELIVERED, OUT_OF_FUEL,
  or TRUNCATED after `world[W_MAX_STEPS]` steps - not terminal, SPEC section 5).
  """
  reward, terminated = step_state(state, action, world, world[W_FUEL_ENABLED] != 0)
  episode[E_STEPS] += 1
  if reward == core.ILLEGAL_REWARD:
    episode[E_ILLEGAL] += 1
  if terminated:
    episode[E_OUTCOME] = DELIVERED if reward == core.DELIVERY_REWARD else OUT_OF_FUEL
  elif episode[E_STEPS] >= world[W_MAX_STEPS]:
    episode[E_OUTCOME] = TRUNCATED
  return float(reward)


def outcome_of(last):
  """How an episode ended, from the last `Step` of a step-by-step run (the codes above)."""
  return outcome(last.truncated, last.reward)


def outcome(truncated, reward):
  """How an episode ended, from its last step's truncation flag and reward."""
  return TRUNCATED if truncated else DELIVERED if reward == core.DELIVERY_REWARD else OUT_OF_FUEL


@numba.njit(cache=True)
def step_batch(states, actions, active, steps, world, reward, terminated, truncated, masks):
  """One primitive step of every `active` taxi of a batch, in one call (the
  Gymnasium vector taxi): `taxi_step` on each, its step count, truncation after
  `world[W_MAX_STEPS]` steps (SPEC section 5) and the new state's action mask.
  Inactive taxis keep their state, counts and outputs."""
  fuel_enabled = world[W_FUEL_ENABLED] != 0
  for i in range(states.shape[0]):
    if not active[i]:
      continue
    s = states[i]
    r, done = step_state(s, actions[i], world, fuel_enabled)
    steps[i] += 1
    reward[i] = r
    terminated[i] = done
    truncated[i] = not done and steps[i] >= world[W_MAX_STEPS]
    core.fill_legal_actions(masks[i], s[ROW], s[COL], s[PASSENGER], s[DESTINATION], s[FUEL],
                            fuel_enabled, world[W_FUEL_ROW], world[W_FUEL_COL],
                            world[W_CAPACITY])


@numba.njit(cache=True)
def fill_masks(states, indices, world, masks):
  """The action masks of the taxis `indices` (after a reset)."""
  fuel_enabled = world[W_FUEL_ENABLED] != 0
  for i in indices:
    s = states[i]
    core.fill_legal_actions(masks[i], s[ROW], s[COL], s[PASSENGER], s[DESTINATION], s[FUEL],
                            fuel_enabled, world[W_FUEL_ROW], world[W_FUEL_COL],
                            world[W_CAPACITY])
