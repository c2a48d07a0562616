"""The taxi-fuel task graph's pieces as compiled functions (SPEC section 5).

MAXQ's graph with the fuel subtask (Dietterich 2000; paper, section 5.1):

    Root -> {Get, Put, Refuel}
    Get -> {Navigate(R), Navigate(G), Navigate(Y), Navigate(B), Pickup}
    Put -> {Navigate(R), Navigate(G), Navigate(Y), Navigate(B), Dropoff}
    Refuel -> {Navigate(F), Fillup}
    Navigate(t) -> {South, North, East, West},   t in {R, G, Y, B, F}

For each subtask this module gives its abstract state (MAXQ-style state
abstraction: the index of its row in the subtask's policy table), the children
available in a state (initiation) and its termination. Shared by the fused
compiled loop (`taxi_compiled`) and any step-by-step executor, so both see the
same numbers.

A world state is an int64[5] array `(row, col, passenger, destination, fuel)`
(`taxi_core`'s layout); `world` is the int64 array of `world_config`.

Abstractions (each subtask sees only what its choice depends on):

- Navigate(t) sees (t, row, col): 5 * 25 = 125 states, one table shared by the
  five targets. Passenger, destination and fuel do not change the shortest way.
- Get sees (row, col, passenger station): 25 * 4 = 100 states. Get only runs
  while the passenger waits (0..3); the destination and fuel do not change where
  to go (Get cannot refuel; running dry ends the episode whatever it chooses).
- Put sees (row, col, destination): 100 states, the same argument.
- Refuel sees (row, col): 25 states. The way to F and the Fillup there do not
  depend on how much fuel is left.
- Root sees the full state (`taxi_core.encode_state`: 6,500 with fuel, 500
  classic). Whether to refuel first, or only after the pickup, or not at all,
  depends on the fuel *and* on the three distances taxi -> passenger ->
  destination and via F, so no variable can be dropped. Only reached states
  are ever visited (start states, and the few states in which Get or Refuel
  return), so the table is large but sparsely used.

Children and initiation (a child already terminated in a state is not
available there; primitives are always available):

- Root: Get while the passenger waits, Put while it is in the taxi (exactly one
  of the two), and Refuel unless the taxi stands at F with a full tank (the one
  state where Refuel is terminated). Refuel stays available with a full tank
  elsewhere: from a start like taxi at R, passenger at G, fuel 12 the only way
  to deliver is to top up at F on the way (R -> G -> Y takes 18 actions), and a
  Root that could refuel only below capacity would lose 40 of the 2,400 start
  states (its best mean return would be 5.856, not the optimal 6.145). With it,
  the hierarchy's best policy reaches the optimum from every start.
- Get: Navigate(t) for the four stations except the one the taxi is at, and
  Pickup (which may be illegal: -10).
- Put: the same with Dropoff.
- Refuel: Navigate(F) unless the taxi is at F, and Fillup (a -1 no-op away from F).
- Navigate(t): the four moves (a move into a wall is a -1 no-op).

Termination (MAXQ's):

- Navigate(t): the taxi is at t.
- Get: the passenger is in the taxi.
- Put: the passenger has been delivered (it stands at its destination).
- Refuel: the taxi is at F with a full tank. No move can bring the taxi to F
  with a full tank (moves burn fuel), so this is "after a Fillup at F".
- Root: the episode ends.
- Every subtask also returns when the episode ends: delivery, the tank running
  dry, or the 200-step truncation (`primitive_step` records which).
"""
import numba
import numpy as np

from hpg_mj.worlds import taxi_core as core

# Subtask ids: one policy table and one trace each (Navigate's table is shared by
# its five targets).
ROOT, GET, PUT, REFUEL, NAVIGATE = range(5)
N_SUBTASKS = 5
SUBTASK_NAMES = ("Root", "Get", "Put", "Refuel", "Navigate")

# Children, as the column of the subtask's policy table.
ROOT_GET, ROOT_PUT, ROOT_REFUEL = range(3)       # Root's child c is subtask c + 1
N_STATIONS = 4
TARGET_F = 4                                     # Navigate's targets: R, G, Y, B, F
N_TARGETS = 5
CARRY_PRIMITIVE = N_STATIONS                     # Get/Put: children 0..3 Navigate(t), 4 Pickup/Dropoff
REFUEL_NAVIGATE, REFUEL_FILLUP = range(2)
N_CHILDREN = (3, N_STATIONS + 1, N_STATIONS + 1, 2, 4)  # Navigate's child = the move's action index
MAX_CHILDREN = 5
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
    raise ValueError(f"taxi_rules: rules must be a taxi_core.TaxiRules, got {type(rules).__name__}")
  return np.array([rules.fuel_enabled, rules.fuel_station[0], rules.fuel_station[1],
                   rules.capacity, rules.max_steps, rules.start_fuel[0], rules.start_fuel[1]],
                  dtype=np.int64)


def n_abstract_states(fuel_enabled: bool = True, capacity: int = core.FUEL_CAPACITY):
  """Rows of each subtask's policy table, by subtask id."""
  return (core.num_states(fuel_enabled, capacity), N_SQUARES * N_STATIONS,
          N_SQUARES * N_STATIONS, N_SQUARES, N_TARGETS * N_SQUARES)


# --- abstract states -----------------------------------------------------------

@numba.njit(cache=True)
def root_state(state, world):
  """Root sees the full state (see the module docstring)."""
  return core.encode_state(state[ROW], state[COL], state[PASSENGER], state[DESTINATION],
                           state[FUEL], world[W_FUEL_ENABLED] != 0)


@numba.njit(cache=True)
def get_state(state):
  """Get sees (row, col, passenger station 0..3)."""
  return (state[ROW] * core.GRID_SIZE + state[COL]) * N_STATIONS + state[PASSENGER]


@numba.njit(cache=True)
def put_state(state):
  """Put sees (row, col, destination)."""
  return (state[ROW] * core.GRID_SIZE + state[COL]) * N_STATIONS + state[DESTINATION]


@numba.njit(cache=True)
def refuel_state(state):
  """Refuel sees (row, col)."""
  return state[ROW] * core.GRID_SIZE + state[COL]


@numba.njit(cache=True)
def navigate_state(target, state):
  """Navigate(t) sees (t, row, col)."""
  return target * N_SQUARES + state[ROW] * core.GRID_SIZE + state[COL]


@numba.njit(cache=True)
def carry_state(subtask, state):
  """The abstract state of Get, Put or Refuel (the three children of Root)."""
  if subtask == GET:
    return get_state(state)
  if subtask == PUT:
    return put_state(state)
  return refuel_state(state)


# --- where things are ----------------------------------------------------------

@numba.njit(cache=True)
def at_target(target, state, world):
  """Is the taxi at station t (0..3) or at F (`TARGET_F`)?"""
  if target == TARGET_F:
    return state[ROW] == world[W_FUEL_ROW] and state[COL] == world[W_FUEL_COL]
  return state[ROW] == core.STATIONS[target, 0] and state[COL] == core.STATIONS[target, 1]


@numba.njit(cache=True)
def tank_full_at_f(state, world):
  return at_target(TARGET_F, state, world) and state[FUEL] == world[W_CAPACITY]


# --- initiation: the children available in a state --------------------------------

@numba.njit(cache=True)
def root_children(state, world, mask):
  """Get while the passenger waits, Put while it rides, Refuel (fuel task only)
  unless the taxi is at F with a full tank."""
  mask[ROOT_GET] = state[PASSENGER] != core.IN_TAXI
  mask[ROOT_PUT] = state[PASSENGER] == core.IN_TAXI
  mask[ROOT_REFUEL] = world[W_FUEL_ENABLED] != 0 and not tank_full_at_f(state, world)


@numba.njit(cache=True)
def carry_children(subtask, state, world, mask):
  """Get / Put: Navigate(t) unless at t, and Pickup / Dropoff. Refuel:
  Navigate(F) unless at F, and Fillup."""
  if subtask == REFUEL:
    mask[REFUEL_NAVIGATE] = not at_target(TARGET_F, state, world)
    mask[REFUEL_FILLUP] = True
    return
  for t in range(N_STATIONS):
    mask[t] = not at_target(t, state, world)
  mask[CARRY_PRIMITIVE] = True


@numba.njit(cache=True)
def navigate_children(mask):
  """All four moves."""
  for a in range(4):
    mask[a] = True


# --- the children's meaning ------------------------------------------------------

@numba.njit(cache=True)
def carry_child_target(subtask, child):
  """The Navigate target of a child of Get, Put or Refuel, or -1 for its primitive."""
  if subtask == REFUEL:
    return TARGET_F if child == REFUEL_NAVIGATE else -1
  return child if child < N_STATIONS else -1


@numba.njit(cache=True)
def carry_primitive(subtask):
  """The primitive child of Get (Pickup), Put (Dropoff) or Refuel (Fillup)."""
  if subtask == GET:
    return core.PICKUP
  if subtask == PUT:
    return core.DROPOFF
  return core.FILLUP


# --- termination ---------------------------------------------------------------

@numba.njit(cache=True)
def navigate_done(target, state, world):
  return at_target(target, state, world)


@numba.njit(cache=True)
def carry_done(subtask, state, world):
  """Get: the passenger is aboard. Put: delivered. Refuel: at F with a full tank."""
  if subtask == GET:
    return state[PASSENGER] == core.IN_TAXI
  if subtask == PUT:
    return state[PASSENGER] == state[DESTINATION]
  return tank_full_at_f(state, world)


@numba.njit(cache=True)
def episode_over(episode):
  return episode[E_OUTCOME] != RUNNING


# --- the world ------------------------------------------------------------------

@numba.njit(cache=True)
def primitive_step(state, episode, action, world):
  """Executes a primitive action (Algorithm 1, line 4) and returns its reward.

  Updates `state` and `episode` (steps, illegal count, outcome: DELIVERED, OUT_OF_FUEL,
  or TRUNCATED after `world[W_MAX_STEPS]` steps - not terminal, SPEC section 5).
  """
  row, col, passenger, destination, fuel, reward, terminated = core.taxi_step(
      state[ROW], state[COL], state[PASSENGER], state[DESTINATION], state[FUEL], action,
      world[W_FUEL_ENABLED] != 0, world[W_FUEL_ROW], world[W_FUEL_COL], world[W_CAPACITY])
  state[ROW] = row
  state[COL] = col
  state[PASSENGER] = passenger
  state[DESTINATION] = destination
  state[FUEL] = fuel
  episode[E_STEPS] += 1
  if reward == core.ILLEGAL_REWARD:
    episode[E_ILLEGAL] += 1
  if terminated:
    episode[E_OUTCOME] = DELIVERED if reward == core.DELIVERY_REWARD else OUT_OF_FUEL
  elif episode[E_STEPS] >= world[W_MAX_STEPS]:
    episode[E_OUTCOME] = TRUNCATED
  return float(reward)
