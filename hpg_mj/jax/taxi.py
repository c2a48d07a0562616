"""Taxi-fuel and the classic taxi in pure JAX (SPEC section 5), gymnax's interface.

`hpg_mj.worlds.taxi_core.taxi_step` written again over jax.numpy, rule by rule:
the moves and Dietterich's walls, Pickup and Dropoff (illegal: -10, nothing
changes), the fuel (every action burns a unit, Fillup at F fills the tank even
from 0 and burns none, an action with an empty tank is -20 and ends the episode),
the 200-step time limit (truncation, not termination). Integer rules, so the
trajectories, rewards and endings equal the numba world's exactly (the tests: 1,000
seeded episodes per task). The numba world, the dm_control and the Gymnasium tasks
stay the reference; `taxi_core` gives the constants only.

`TaxiFuel-v0` and `Taxi-v0` are `hpg_mj.envs.taxi.TaxiEnv`'s two tasks (its
docstring is the manual). Differences from the Gymnasium environment, forced by
running under jit: an action outside 0..n-1 is clipped into it (an action of the
wrong shape or kind is refused when the step is traced); gymnax has no
MultiDiscrete, so the observation space is an integer `Box`; there is no
`action_mask` in the info.
"""
import functools

import jax
import jax.numpy as jnp
import numpy as np

from hpg_mj.jax import environment
from hpg_mj.worlds import taxi_core as core
from hpg_mj.worlds import taxi_rules

# SPEC section 5's board, as arrays the rules index.
_WALL_EAST = jnp.asarray(core.WALL_EAST)
_STATIONS = jnp.asarray(core.STATIONS, jnp.int32)


@environment.record
class EnvState:
  """A taxi and its episode (`taxi_core`'s five ints, named)."""
  row: jax.Array           # 0..4, row 0 at the top
  col: jax.Array           # 0..4
  passenger: jax.Array     # 0..3 waiting at R, G, Y, B; 4 in the taxi
  destination: jax.Array   # 0..3
  fuel: jax.Array          # 0..capacity (the classic task: the full tank, ignored)
  time: jax.Array          # primitive steps taken in this episode
  outcome: jax.Array       # taxi_rules.RUNNING, DELIVERED or OUT_OF_FUEL


@environment.record
class EnvParams:
  """What a user may change per call; the defaults are SPEC section 5's."""
  max_steps_in_episode: int = core.MAX_STEPS     # primitive steps, then truncated
  fuel_row: int = core.FUEL_STATION[0]           # F's square
  fuel_col: int = core.FUEL_STATION[1]
  capacity: int = core.FUEL_CAPACITY             # Fillup at F sets the fuel to it
  start_fuel_min: int = core.START_FUEL_MIN      # the start fuel is uniform in min..max
  start_fuel_max: int = core.START_FUEL_MAX


def taxi_step(state, action, fuel_enabled, params):
  """`taxi_core.taxi_step` on an `EnvState`: `(row, col, passenger, destination,
  fuel, reward, terminated)` after `action` (an int in 0..6, 0..5 without fuel)."""
  row, col, passenger, destination, fuel = (state.row, state.col, state.passenger,
                                            state.destination, state.fuel)
  # The moves: the border and the walls east of a square (Dietterich's map).
  new_row = jnp.where((action == core.SOUTH) & (row < core.GRID_SIZE - 1), row + 1,
                      jnp.where((action == core.NORTH) & (row > 0), row - 1, row))
  west_open = (col > 0) & ~_WALL_EAST[row, jnp.maximum(col - 1, 0)]
  new_col = jnp.where((action == core.EAST) & ~_WALL_EAST[row, col], col + 1,
                      jnp.where((action == core.WEST) & west_open, col - 1, col))
  waiting = jnp.minimum(passenger, 3)
  can_pick = ((passenger < core.IN_TAXI) & (row == _STATIONS[waiting, 0])
              & (col == _STATIONS[waiting, 1]))
  can_drop = ((passenger == core.IN_TAXI) & (row == _STATIONS[destination, 0])
              & (col == _STATIONS[destination, 1]))
  pickup, dropoff = action == core.PICKUP, action == core.DROPOFF
  new_passenger = jnp.where(pickup & can_pick, core.IN_TAXI,
                            jnp.where(dropoff & can_drop, destination, passenger))
  reward = jnp.where(dropoff & can_drop, core.DELIVERY_REWARD,
                     jnp.where((pickup & ~can_pick) | (dropoff & ~can_drop),
                               core.ILLEGAL_REWARD, core.STEP_REWARD))
  terminated = dropoff & can_drop
  new_fuel = fuel
  if fuel_enabled:
    new_fuel = fuel - 1   # every action burns a unit, wall bumps and no-ops included
    # Fillup at F: the tank full whatever it held, even 0, for no fuel and -1.
    fill = (action == core.FILLUP) & (row == params.fuel_row) & (col == params.fuel_col)
    # Otherwise an empty tank: -20 instead of the action's reward, the episode ends,
    # the taxi stranded where it is (the fuel stays 0, a valid state).
    empty = ~fill & (fuel == 0)
    still = fill | empty
    new_row = jnp.where(still, row, new_row)
    new_col = jnp.where(still, col, new_col)
    new_passenger = jnp.where(still, passenger, new_passenger)
    new_fuel = jnp.where(fill, params.capacity, jnp.where(empty, 0, new_fuel))
    reward = jnp.where(fill, core.STEP_REWARD, jnp.where(empty, core.OUT_OF_FUEL_REWARD, reward))
    terminated = jnp.where(fill, False, empty | terminated)
  return new_row, new_col, new_passenger, destination, new_fuel, reward, terminated


class Taxi(environment.Environment):
  """Taxi-fuel (`fuel=True`, 7 actions) or the classic taxi (6 actions) as a gymnax
  environment; `hpg_mj.jax.make("TaxiFuel-v0")` builds it with its parameters.
  Observation: int32 `[row, col, passenger, destination, fuel]` (no fuel without
  fuel); action an int in 0..6 (0..5), Gymnasium's Taxi numbering. `info`:
  `terminated`, `truncated`, `outcome` (`taxi_rules`' codes: 0 running, 1
  delivered, 2 out of fuel) and `discount` (0 only where terminated).
  """

  def __init__(self, fuel=True, env_id=None):
    self.fuel_enabled = bool(fuel)
    self.env_id = env_id or ("TaxiFuel" if self.fuel_enabled else "Taxi")
    self._n_obs = 5 if self.fuel_enabled else 4

  @property
  def name(self):
    return self.env_id

  @property
  def default_params(self):
    return EnvParams()

  @property
  def num_actions(self):
    return core.num_actions(self.fuel_enabled)

  def action_space(self, params=None):
    return environment.Discrete(self.num_actions)

  def observation_space(self, params=None):
    capacity = (params or self.default_params).capacity
    high = [core.GRID_SIZE - 1, core.GRID_SIZE - 1, core.IN_TAXI, 3, capacity][:self._n_obs]
    high = jnp.array(high, jnp.int32)
    return environment.Box(jnp.zeros(self._n_obs, jnp.int32), high, (self._n_obs,), jnp.int32)

  def get_obs(self, state, params=None, key=None):
    fields = [state.row, state.col, state.passenger, state.destination, state.fuel]
    return jnp.stack(fields[:self._n_obs]).astype(jnp.int32)

  def is_terminal(self, state, params):
    return (state.outcome != taxi_rules.RUNNING) | (state.time >= params.max_steps_in_episode)

  # ---- starts -------------------------------------------------------------------

  def _state(self, row, col, passenger, destination, fuel):
    values = (row, col, passenger, destination, fuel, 0, taxi_rules.RUNNING)
    return EnvState(*(jnp.asarray(v, jnp.int32) for v in values))

  def reset_env(self, key, params):
    """SPEC section 5 (`taxi_core.sample_initial_state`): the taxi on a uniform
    square, the passenger at a uniform station, the destination uniformly one of
    the other three, the fuel uniform in start_fuel_min..start_fuel_max."""
    # One draw of four integers: each call of the generator is compiled on its own.
    fuel_low, fuel_high = params.start_fuel_min, params.start_fuel_max + 1
    if not self.fuel_enabled:
      fuel_low, fuel_high = core.CLASSIC_FUEL, core.CLASSIC_FUEL + 1
    low = jnp.stack([jnp.asarray(v, jnp.int32) for v in (0, 0, 0, fuel_low)])
    high = jnp.stack([jnp.asarray(v, jnp.int32) for v in
                      (core.GRID_SIZE * core.GRID_SIZE, 4, 3, fuel_high)])
    square, station, other, fuel = jax.random.randint(key, (4,), low, high, jnp.int32)
    state = self._state(square // core.GRID_SIZE, square % core.GRID_SIZE, station,
                        (station + 1 + other) % 4, fuel)
    return self.get_obs(state), state

  def reset_to(self, taxi_state, params=None):
    """`(obs, state)` starting exactly at `taxi_state` = `[row, col, passenger,
    destination, fuel]` (without fuel: the first four), as the Gymnasium
    environment's `reset(options={"state": ...})`; its values are checked as there
    where they are known (not under jit or vmap)."""
    params = params or self.default_params
    arr = jnp.asarray(taxi_state)
    if arr.shape != (self._n_obs,) or not jnp.issubdtype(arr.dtype, jnp.integer):
      names = "row, col, passenger, destination" + (", fuel" if self.fuel_enabled else "")
      raise ValueError(f"{self.env_id}: reset_to takes a taxi state [{names}] of integers, "
                       f"shape ({self._n_obs},), got shape {arr.shape} of dtype {arr.dtype}")
    if environment.is_concrete(arr) and environment.is_concrete(params.capacity):
      core.state_from_vector(np.asarray(arr), fuel_enabled=self.fuel_enabled,
                             capacity=int(params.capacity), who=self.env_id)
    return self._start_at(arr)

  @functools.partial(jax.jit, static_argnames=("self",))
  def _start_at(self, arr):
    fuel = arr[4] if self.fuel_enabled else core.CLASSIC_FUEL
    state = self._state(arr[0], arr[1], arr[2], arr[3], fuel)
    return self.get_obs(state), state

  # ---- one primitive step -------------------------------------------------------

  def _action(self, action):
    arr = jnp.asarray(action)
    if arr.shape not in ((), (1,)) or not jnp.issubdtype(arr.dtype, jnp.integer):
      allowed = ", ".join(f"{k} {name}" for k, name in
                          enumerate(core.ACTION_NAMES[:self.num_actions]))
      raise ValueError(f"{self.env_id}: the action is one integer, shape () or (1,) ({allowed}), "
                       f"got shape {arr.shape} of dtype {arr.dtype}")
    return jnp.clip(arr.reshape(()).astype(jnp.int32), 0, self.num_actions - 1)

  def step_env(self, key, state, action, params):
    action = self._action(action)
    row, col, passenger, destination, fuel, reward, terminated = taxi_step(
        state, action, self.fuel_enabled, params)
    time = state.time + 1
    outcome = jnp.where(~terminated, taxi_rules.RUNNING,
                        jnp.where(reward == core.DELIVERY_REWARD, taxi_rules.DELIVERED,
                                  taxi_rules.OUT_OF_FUEL))
    end = EnvState(*(jnp.asarray(v, jnp.int32) for v in
                     (row, col, passenger, destination, fuel, time, outcome)))
    # SPEC section 5: 200 primitive steps, then truncated (not terminal).
    truncated = ~terminated & (time >= params.max_steps_in_episode)
    float_ = environment.float_dtype()
    info = {"terminated": terminated, "truncated": truncated, "outcome": end.outcome,
            "discount": jnp.where(terminated, 0.0, 1.0).astype(float_)}
    return self.get_obs(end), end, reward.astype(float_), terminated | truncated, info
