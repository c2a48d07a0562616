"""The taxi-fuel task graph's pieces as compiled functions (SPEC section 5).

MAXQ's graph with the fuel subtask (Dietterich 2000; paper, section 5.1):

    Root -> {Get, Put, Refuel}
    Get -> {Navigate(t = the passenger's station), Pickup}
    Put -> {Navigate(t = the destination), Dropoff}
    Refuel -> {Navigate(t = F), Fillup}
    Navigate(t) -> {South, North, East, West},   t in {R, G, Y, B, F}

As in Dietterich's graph, the parent binds Navigate's parameter (t/source,
t/destination), so Get, Put and Refuel each choose between two children.

For each subtask this module gives its abstract state (MAXQ-style state
abstraction: the index of its row in the subtask's policy table), the children
available in a state (initiation) and its termination, and the same by subtask id
for the task-graph machine's taxi blocks (`abstract_state`, `children_of`,
`done_of`). Shared by the machine (taxi HPG), MAXQ-Q's fused loop (`maxq`) and its
step-by-step graph (`hierarchy.taxi`), so every path sees the same numbers.

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
- Root sees (row, col, passenger station, fuel) while the passenger waits and
  (row, col, destination, fuel) once it rides: 2 * 25 * 4 * 13 = 2,600 states
  (200 classic, without fuel). Fuel must matter: whether to refuel first, after
  the pickup or not at all depends on it and on the distances taxi ->
  passenger -> destination via F. Leaving the destination out while the
  passenger waits is the one approximation: the exact choice needs the full
  state (6,500), and with it the hierarchy can reach the flat optimum 6.145 from
  every start; without the destination the best mean return is 6.085 (99.0%,
  from the SPEC start distribution), while each start context is seen three
  times as often, which is what lets Root learn within 100,000 episodes.

Children and initiation (a child already terminated in a state is not
available there; primitives are always available):

- Root: Get while the passenger waits, Put while it is in the taxi (exactly one
  of the two), and Refuel unless the taxi stands at F with a full tank (the one
  state where Refuel is terminated). Refuel stays available with a full tank
  elsewhere: from a start like taxi at R, passenger at G bound for Y, fuel 12
  the only way to deliver is to top up at F on the way (R -> G -> Y takes 18
  actions), and a Root that could refuel only below capacity would lose 40 of
  the 2,400 start states (its best mean return would be 5.856 instead of 6.145).
- Get: Navigate(passenger's station) unless the taxi is there, and Pickup
  (illegal away from the passenger: -10).
- Put: Navigate(destination) unless the taxi is there, and Dropoff.
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
  dry, or the 200-step truncation (`worlds.taxi_rules.primitive_step` records which).
"""
import numba
import numpy as np

from hpg_mj.learners import rng
from hpg_mj.worlds import taxi_core as core
from hpg_mj.worlds import taxi_rules as world_rules
# The world's state layout and rules (`worlds.taxi_rules`) that the subtasks read.
from hpg_mj.worlds.taxi_rules import (COL, DESTINATION, FUEL, N_SQUARES, N_STATIONS,
    PASSENGER, ROW, W_CAPACITY, W_FUEL_COL, W_FUEL_ENABLED, W_FUEL_ROW)

# Subtask ids: one policy table and one trace each (Navigate's table is shared by
# its five targets).
ROOT, GET, PUT, REFUEL, NAVIGATE = range(5)
N_SUBTASKS = 5
SUBTASK_NAMES = ("Root", "Get", "Put", "Refuel", "Navigate")

# Children, as the column of the subtask's policy table. Get, Put and Refuel
# each have two: Navigate(t) with t bound to the passenger's station, the
# destination or F (MAXQ's parameter binding t/source, t/destination), and their
# primitive.
ROOT_GET, ROOT_PUT, ROOT_REFUEL = range(3)       # Root's child c is subtask c + 1
CARRY_NAVIGATE, CARRY_PRIMITIVE = range(2)
TARGET_F = 4                                     # Navigate's targets: R, G, Y, B, F
N_TARGETS = 5
N_CHILDREN = (3, 2, 2, 2, 4)                     # Navigate's child = the move's action index
MAX_CHILDREN = 4

def n_abstract_states(fuel_enabled: bool = True, capacity: int = core.FUEL_CAPACITY):
  """Rows of each subtask's policy table, by subtask id."""
  levels = capacity + 1 if fuel_enabled else 1
  return (2 * N_SQUARES * N_STATIONS * levels, N_SQUARES * N_STATIONS,
          N_SQUARES * N_STATIONS, N_SQUARES, N_TARGETS * N_SQUARES)


# --- abstract states -----------------------------------------------------------

@numba.njit(cache=True, inline="always")
def root_state(state, world):
  """Root sees (row, col, passenger station, fuel) while the passenger waits and
  (row, col, destination, fuel) once it is aboard (see the module docstring)."""
  levels = world[W_CAPACITY] + 1 if world[W_FUEL_ENABLED] != 0 else 1
  fuel = state[FUEL] if world[W_FUEL_ENABLED] != 0 else 0
  square = state[ROW] * core.GRID_SIZE + state[COL]
  if state[PASSENGER] != core.IN_TAXI:
    return (square * N_STATIONS + state[PASSENGER]) * levels + fuel
  return ((N_SQUARES + square) * N_STATIONS + state[DESTINATION]) * levels + fuel


@numba.njit(cache=True, inline="always")
def get_state(state):
  """Get sees (row, col, passenger station 0..3)."""
  return (state[ROW] * core.GRID_SIZE + state[COL]) * N_STATIONS + state[PASSENGER]


@numba.njit(cache=True, inline="always")
def put_state(state):
  """Put sees (row, col, destination)."""
  return (state[ROW] * core.GRID_SIZE + state[COL]) * N_STATIONS + state[DESTINATION]


@numba.njit(cache=True, inline="always")
def refuel_state(state):
  """Refuel sees (row, col)."""
  return state[ROW] * core.GRID_SIZE + state[COL]


@numba.njit(cache=True, inline="always")
def navigate_state(target, state):
  """Navigate(t) sees (t, row, col)."""
  return target * N_SQUARES + state[ROW] * core.GRID_SIZE + state[COL]


@numba.njit(cache=True, inline="always")
def carry_state(subtask, state):
  """The abstract state of Get, Put or Refuel (the three children of Root)."""
  if subtask == GET:
    return get_state(state)
  if subtask == PUT:
    return put_state(state)
  return refuel_state(state)


# --- where things are ----------------------------------------------------------

@numba.njit(cache=True, inline="always")
def at_target(target, state, world):
  """Is the taxi at station t (0..3) or at F (`TARGET_F`)?"""
  if target == TARGET_F:
    return state[ROW] == world[W_FUEL_ROW] and state[COL] == world[W_FUEL_COL]
  return state[ROW] == core.STATIONS[target, 0] and state[COL] == core.STATIONS[target, 1]


@numba.njit(cache=True, inline="always")
def tank_full_at_f(state, world):
  """Whether the taxi is at F with a full tank (Refuel's end)."""
  return at_target(TARGET_F, state, world) and state[FUEL] == world[W_CAPACITY]


# --- initiation: the children available in a state --------------------------------

@numba.njit(cache=True, inline="always")
def root_children(state, world, mask):
  """Get while the passenger waits, Put while it rides, Refuel (fuel task only)
  unless the taxi is at F with a full tank."""
  mask[ROOT_GET] = state[PASSENGER] != core.IN_TAXI
  mask[ROOT_PUT] = state[PASSENGER] == core.IN_TAXI
  mask[ROOT_REFUEL] = world[W_FUEL_ENABLED] != 0 and not tank_full_at_f(state, world)


@numba.njit(cache=True, inline="always")
def carry_target(subtask, state):
  """The target t that Get (the passenger's station), Put (the destination) or
  Refuel (F) binds Navigate(t) to."""
  if subtask == GET:
    return state[PASSENGER]
  if subtask == PUT:
    return state[DESTINATION]
  return TARGET_F


@numba.njit(cache=True, inline="always")
def carry_children(subtask, state, world, mask):
  """Navigate(t) unless the taxi is at t already; the primitive always."""
  mask[CARRY_NAVIGATE] = not at_target(carry_target(subtask, state), state, world)
  mask[CARRY_PRIMITIVE] = True


@numba.njit(cache=True, inline="always")
def navigate_children(mask):
  """All four moves."""
  for a in range(4):
    mask[a] = True


# --- the children's meaning ------------------------------------------------------

@numba.njit(cache=True, inline="always")
def carry_primitive(subtask):
  """The primitive child of Get (Pickup), Put (Dropoff) or Refuel (Fillup)."""
  if subtask == GET:
    return core.PICKUP
  if subtask == PUT:
    return core.DROPOFF
  return core.FILLUP


# --- termination ---------------------------------------------------------------

@numba.njit(cache=True, inline="always")
def navigate_done(target, state, world):
  """Whether the taxi is at `target` (Navigate(t)'s end)."""
  return at_target(target, state, world)


@numba.njit(cache=True, inline="always")
def carry_done(subtask, state, world):
  """Get: the passenger is aboard. Put: delivered. Refuel: at F with a full tank."""
  if subtask == GET:
    return state[PASSENGER] == core.IN_TAXI
  if subtask == PUT:
    return state[PASSENGER] == state[DESTINATION]
  return tank_full_at_f(state, world)


# --- by subtask id (the task-graph machine's taxi blocks) ---------------------------

@numba.njit(cache=True, inline="always")
def abstract_state(subtask, target, state, world):
  """The abstract state of subtask `subtask` (Navigate's: of its target)."""
  if subtask == ROOT:
    return root_state(state, world)
  if subtask == NAVIGATE:
    return navigate_state(target, state)
  return carry_state(subtask, state)


@numba.njit(cache=True, inline="always")
def children_of(subtask, state, world, mask):
  """The children available to subtask `subtask` in `state`, into `mask`."""
  if subtask == ROOT:
    root_children(state, world, mask)
  elif subtask == NAVIGATE:
    navigate_children(mask)
  else:
    carry_children(subtask, state, world, mask)


@numba.njit(cache=True, inline="always")
def done_of(subtask, target, state, world):
  """Has subtask `subtask` (Navigate: to `target`) terminated? Root never does."""
  if subtask == ROOT:
    return False
  if subtask == NAVIGATE:
    return navigate_done(target, state, world)
  return carry_done(subtask, state, world)


@numba.njit(cache=True)
def sample_start(rng_state, world, state):
  """A start state (SPEC section 5), drawn in the order square, passenger
  station, destination among the other three, fuel (fuel task only).

  The draws go into `state` first, from one call site of `rng.randint` in a loop:
  four inlined copies of it made this function's first compile 0.4 s longer."""
  fuel_min = world[world_rules.W_START_FUEL_MIN]
  sizes = (np.int64(world_rules.N_SQUARES), np.int64(world_rules.N_STATIONS),
           np.int64(world_rules.N_STATIONS - 1), world[world_rules.W_START_FUEL_MAX] - fuel_min + 1)
  n_draws = 4 if world[world_rules.W_FUEL_ENABLED] != 0 else 3
  for k in range(n_draws):
    state[k] = rng.randint(rng_state, sizes[k])
  fuel = fuel_min + state[3] if n_draws == 4 else core.CLASSIC_FUEL
  row, col, passenger, destination, fuel = core.state_from_draws(state[0], state[1], state[2],
                                                                 fuel)
  state[world_rules.ROW] = row
  state[world_rules.COL] = col
  state[world_rules.PASSENGER] = passenger
  state[world_rules.DESTINATION] = destination
  state[world_rules.FUEL] = fuel
