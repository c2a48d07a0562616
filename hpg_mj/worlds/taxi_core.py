"""Taxi-fuel: the rules of Dietterich's taxi domain with the fuel extension.

Every rule is a numba-compiled function over plain ints, so that the Gymnasium
environment, the dm_control tasks and the compiled training loops all use one
implementation of each rule (SPEC section 5). The thin Python helpers at the end
sample and check states for the step-by-step paths.

The grid is 5 x 5, row 0 at the top, column 0 on the left; the map is
Gymnasium's Taxi (Dietterich 2000, Figure 1):

    +---------+
    |R: | : :G|
    | : | : : |
    | :F: : : |      F: the fuel station (2, 1), SPEC section 5
    | | : | : |
    |Y| : |B: |
    +---------+

A state is five ints `(row, col, passenger, destination, fuel)`:

- `row`, `col`: the taxi's square, 0..4 each.
- `passenger`: 0..3, waiting at station R, G, Y, B; 4 (`IN_TAXI`), in the taxi.
- `destination`: 0..3, station R, G, Y, B.
- `fuel`: 0..capacity (12). The classic task carries the field but ignores it;
  by convention it holds a full tank there (`CLASSIC_FUEL`).

State index (for tabular learners), `encode_state` / `decode_state`:

    classic = ((row * 5 + col) * 5 + passenger) * 4 + destination     # 0..499
    fuel task: index = fuel * 500 + classic                           # 0..6499

The classic index is Gymnasium's Taxi encoding exactly; the fuel level is the
slowest index, so each fuel level is one copy of Gymnasium's 500 states.
"""
import numba
import numpy as np

# SPEC section 5: the board.
GRID_SIZE = 5
STATIONS = np.array([[0, 0], [0, 4], [4, 0], [4, 3]], dtype=np.int64)  # (row, col)
STATION_NAMES = ("R", "G", "Y", "B")
IN_TAXI = 4                   # passenger location 4: in the taxi
FUEL_STATION = (2, 1)         # F, (row, col); the paper's Figure 5 is illegible
FUEL_CAPACITY = 12
START_FUEL_MIN = 5            # start fuel is uniform in 5..12
START_FUEL_MAX = 12
CLASSIC_FUEL = FUEL_CAPACITY  # the ignored fuel field of a classic state
MAX_STEPS = 200               # primitive steps, then truncated (not terminal)

# Dietterich's walls, Gymnasium's MAP: WALL_EAST[row, col] is True when a wall
# stands on the east side of square (row, col), the grid's border included:
# columns 1|2 in rows 0-1, columns 0|1 and 2|3 in rows 3-4.
WALL_EAST = np.zeros((GRID_SIZE, GRID_SIZE), dtype=np.bool_)
WALL_EAST[:, GRID_SIZE - 1] = True
WALL_EAST[0:2, 1] = True
WALL_EAST[3:5, 0] = True
WALL_EAST[3:5, 2] = True

# Actions, numbered as in Gymnasium's Taxi; Fillup exists only with fuel.
SOUTH, NORTH, EAST, WEST, PICKUP, DROPOFF, FILLUP = range(7)
ACTION_NAMES = ("South", "North", "East", "West", "Pickup", "Dropoff", "Fillup")
NUM_ACTIONS_CLASSIC = 6
NUM_ACTIONS_FUEL = 7

# Rewards, SPEC section 5.
STEP_REWARD = -1
DELIVERY_REWARD = 20
ILLEGAL_REWARD = -10          # Pickup or Dropoff where it is not legal
OUT_OF_FUEL_REWARD = -20      # an action (other than Fillup at F) with an empty tank

NUM_CLASSIC_STATES = GRID_SIZE * GRID_SIZE * 5 * 4   # 500
NUM_FUEL_LEVELS = FUEL_CAPACITY + 1                  # 13
NUM_FUEL_STATES = NUM_CLASSIC_STATES * NUM_FUEL_LEVELS  # 6500


def num_actions(fuel_enabled: bool) -> int:
  """The taxi's actions: 7 with the fuel task's Fillup, else 6."""
  return NUM_ACTIONS_FUEL if fuel_enabled else NUM_ACTIONS_CLASSIC


def num_states(fuel_enabled: bool, capacity: int = FUEL_CAPACITY) -> int:
  """The taxi's states: 500 classic ones, times the fuel levels 0..capacity in the
  fuel task."""
  return NUM_CLASSIC_STATES * (capacity + 1) if fuel_enabled else NUM_CLASSIC_STATES


@numba.njit(cache=True)
def taxi_step(row, col, passenger, destination, fuel, action, fuel_enabled=True,
              fuel_row=FUEL_STATION[0], fuel_col=FUEL_STATION[1], capacity=FUEL_CAPACITY):
  """One primitive action (SPEC section 5).

  Returns `(row, col, passenger, destination, fuel, reward, terminated)`.
  The state must be valid (see `validate_state`); only the action is checked
  here, because a wrong action number would silently act as another rule.
  With `fuel_enabled=False` this is exactly Gymnasium's Taxi except for
  Dietterich's rule kept by the SPEC: Dropoff of the passenger anywhere but the
  destination is illegal (-10, nothing changes), where Gymnasium's Taxi leaves
  the passenger at that station for -1. The fuel field is passed through.
  """
  if action < 0 or action > FILLUP or (action == FILLUP and not fuel_enabled):
    raise ValueError("taxi_step: action must be 0..5 (classic taxi) or 0..6 (taxi-fuel)")
  if fuel_enabled:
    if action == FILLUP and row == fuel_row and col == fuel_col:
      # Fillup at F fills the tank whatever it held, even 0, and costs no fuel.
      return row, col, passenger, destination, capacity, STEP_REWARD, False
    if fuel == 0:
      # The fuel would fall below zero: -20 instead of the action's own reward,
      # and the episode ends. The action has no effect (the taxi is stranded),
      # and the fuel stays 0 so the final state is still a valid state.
      return row, col, passenger, destination, 0, OUT_OF_FUEL_REWARD, True
    fuel -= 1  # every other action costs one unit, wall bumps and no-ops included

  reward = STEP_REWARD
  terminated = False
  if action == SOUTH:
    if row < GRID_SIZE - 1:
      row += 1
  elif action == NORTH:
    if row > 0:
      row -= 1
  elif action == EAST:
    if not WALL_EAST[row, col]:
      col += 1
  elif action == WEST:
    if col > 0 and not WALL_EAST[row, col - 1]:
      col -= 1
  elif action == PICKUP:
    if passenger < IN_TAXI and row == STATIONS[passenger, 0] and col == STATIONS[passenger, 1]:
      passenger = IN_TAXI
    else:
      reward = ILLEGAL_REWARD
  elif action == DROPOFF:
    if (passenger == IN_TAXI and row == STATIONS[destination, 0]
        and col == STATIONS[destination, 1]):
      passenger = destination
      reward = DELIVERY_REWARD
      terminated = True
    else:
      # Dietterich's rule: no passenger aboard, or not at the destination.
      reward = ILLEGAL_REWARD
  # FILLUP away from F: a -1 no-op (its unit of fuel was paid above).
  return row, col, passenger, destination, fuel, reward, terminated


@numba.njit(cache=True)
def fill_legal_actions(mask, row, col, passenger, destination, fuel, fuel_enabled, fuel_row,
                       fuel_col, capacity):
  """Writes `legal_actions`' mask into `mask` (a row of a batch's masks)."""
  mask[SOUTH] = row < GRID_SIZE - 1
  mask[NORTH] = row > 0
  mask[EAST] = not WALL_EAST[row, col]
  mask[WEST] = col > 0 and not WALL_EAST[row, col - 1]
  mask[PICKUP] = (passenger < IN_TAXI and row == STATIONS[passenger, 0]
                  and col == STATIONS[passenger, 1])
  mask[DROPOFF] = (passenger == IN_TAXI and row == STATIONS[destination, 0]
                   and col == STATIONS[destination, 1])
  if fuel_enabled:
    mask[FILLUP] = row == fuel_row and col == fuel_col and fuel < capacity


@numba.njit(cache=True)
def legal_actions(row, col, passenger, destination, fuel, fuel_enabled=True,
                  fuel_row=FUEL_STATION[0], fuel_col=FUEL_STATION[1], capacity=FUEL_CAPACITY):
  """An int8 mask of the actions that do something on the board.

  1 for a move that is not blocked by a wall or the border, a legal Pickup, a
  legal Dropoff and, with fuel, a Fillup at F when the tank is not full; 0 for
  the -1 no-ops and the -10 illegal actions. Like Gymnasium's `action_mask` it
  says nothing about fuel running out: every action is still allowed.
  """
  mask = np.zeros(NUM_ACTIONS_FUEL if fuel_enabled else NUM_ACTIONS_CLASSIC, dtype=np.int8)
  fill_legal_actions(mask, row, col, passenger, destination, fuel, fuel_enabled, fuel_row,
                     fuel_col, capacity)
  return mask


@numba.njit(cache=True)
def encode_state(row, col, passenger, destination, fuel, fuel_enabled=True):
  """The state's index: Gymnasium's Taxi index, plus `fuel * 500` with fuel."""
  index = ((row * GRID_SIZE + col) * 5 + passenger) * 4 + destination
  if fuel_enabled:
    index += NUM_CLASSIC_STATES * fuel
  return index


@numba.njit(cache=True)
def decode_state(index, fuel_enabled=True):
  """Inverse of `encode_state`; a classic index decodes with `CLASSIC_FUEL`."""
  fuel = CLASSIC_FUEL
  if fuel_enabled:
    fuel = index // NUM_CLASSIC_STATES
    index = index % NUM_CLASSIC_STATES
  destination = index % 4
  index //= 4
  passenger = index % 5
  index //= 5
  col = index % GRID_SIZE
  row = index // GRID_SIZE
  return row, col, passenger, destination, fuel


@numba.njit(cache=True)
def state_from_draws(square, station, other, fuel):
  """A start state from uniform draws (SPEC section 5).

  `square` in 0..24 is the taxi's square (row-major), `station` in 0..3 the
  passenger's station, `other` in 0..2 picks the destination among the other
  three stations, `fuel` the start fuel.
  """
  destination = (station + 1 + other) % 4
  return square // GRID_SIZE, square % GRID_SIZE, station, destination, fuel


@numba.njit(cache=True)
def sample_initial_state_numba(fuel_enabled=True, fuel_min=START_FUEL_MIN,
                               fuel_max=START_FUEL_MAX):
  """`sample_initial_state` for compiled loops, drawing from numba's generator
  (seed it with `np.random.seed` inside a compiled function)."""
  square = np.random.randint(0, GRID_SIZE * GRID_SIZE)
  station = np.random.randint(0, 4)
  other = np.random.randint(0, 3)
  fuel = CLASSIC_FUEL
  if fuel_enabled:
    fuel = np.random.randint(fuel_min, fuel_max + 1)
  return state_from_draws(square, station, other, fuel)


def _draw(rng, low: int, high: int) -> int:
  """A uniform int in low..high (inclusive) from a Generator or a RandomState."""
  if isinstance(rng, np.random.Generator):
    return int(rng.integers(low, high + 1))
  if isinstance(rng, np.random.RandomState):
    return int(rng.randint(low, high + 1))
  raise TypeError(f"taxi: rng must be a numpy Generator or RandomState, got {type(rng).__name__}")


def sample_initial_state(rng, fuel_enabled: bool = True, fuel_min: int = START_FUEL_MIN,
                         fuel_max: int = START_FUEL_MAX):
  """A start state (SPEC section 5): the taxi on a uniformly random square, the
  passenger at a random station, the destination one of the other three
  stations, the fuel uniform in `fuel_min..fuel_max` (classic: `CLASSIC_FUEL`,
  and no fuel is drawn). `rng` is a `np.random.Generator` or `RandomState`.

  Returns `(row, col, passenger, destination, fuel)` as Python ints.
  """
  square = _draw(rng, 0, GRID_SIZE * GRID_SIZE - 1)
  station = _draw(rng, 0, 3)
  other = _draw(rng, 0, 2)
  fuel = _draw(rng, fuel_min, fuel_max) if fuel_enabled else CLASSIC_FUEL
  return tuple(int(v) for v in state_from_draws(square, station, other, fuel))


_FIELDS = ("row", "col", "passenger", "destination", "fuel")


def _as_int(value, name: str, allowed: str, who: str) -> int:
  arr = np.asarray(value)
  if arr.ndim != 0 or arr.dtype.kind not in "iu":
    raise ValueError(f"{who}: state {name} must be an integer in {allowed}, got {value!r}")
  return int(arr)


def validate_state(row, col, passenger, destination, fuel=None, *, fuel_enabled: bool = True,
                   capacity: int = FUEL_CAPACITY, allow_passenger_at_destination: bool = False,
                   who: str = "taxi"):
  """Returns the state as a tuple of five Python ints, or raises ValueError.

  The error names the field, its value and the allowed range. A passenger
  waiting at its own destination (passenger == destination < 4) never occurs in
  an episode (the start puts the destination at another station, and delivery
  ends the episode) and is refused unless `allow_passenger_at_destination`
  (Gymnasium's Taxi lists those 100 states in its table). A passenger in the
  taxi may have any destination. In the classic task `fuel` is ignored and
  may be None; it is returned as `CLASSIC_FUEL`.
  """
  row = _as_int(row, "row", f"0..{GRID_SIZE - 1} (row 0 at the top)", who)
  col = _as_int(col, "col", f"0..{GRID_SIZE - 1} (column 0 on the left)", who)
  if not 0 <= row < GRID_SIZE:
    raise ValueError(f"{who}: state row={row} is off the grid; allowed 0..{GRID_SIZE - 1}")
  if not 0 <= col < GRID_SIZE:
    raise ValueError(f"{who}: state col={col} is off the grid; allowed 0..{GRID_SIZE - 1}")
  passenger_allowed = "0..4 (0 R, 1 G, 2 Y, 3 B at a station, 4 in the taxi)"
  passenger = _as_int(passenger, "passenger", passenger_allowed, who)
  if not 0 <= passenger <= IN_TAXI:
    raise ValueError(f"{who}: state passenger={passenger} is not allowed; allowed {passenger_allowed}")
  destination_allowed = "0..3 (0 R, 1 G, 2 Y, 3 B)"
  destination = _as_int(destination, "destination", destination_allowed, who)
  if not 0 <= destination <= 3:
    raise ValueError(f"{who}: state destination={destination} is not allowed; "
                     f"allowed {destination_allowed}")
  if passenger == destination and not allow_passenger_at_destination:
    raise ValueError(
        f"{who}: state passenger={passenger} waits at its own destination "
        f"{destination} ({STATION_NAMES[destination]}), which no episode reaches; allowed: "
        "a destination other than the waiting passenger's station, or passenger=4 (in the "
        "taxi) with any destination")
  if fuel_enabled:
    if fuel is None:
      raise ValueError(f"{who}: the fuel task needs a fuel level in 0..{capacity}, got None")
    fuel = _as_int(fuel, "fuel", f"0..{capacity}", who)
    if not 0 <= fuel <= capacity:
      raise ValueError(f"{who}: state fuel={fuel} is outside the tank; allowed 0..{capacity}")
  else:
    fuel = CLASSIC_FUEL
  return row, col, passenger, destination, fuel


def state_from_vector(state, *, fuel_enabled: bool = True, capacity: int = FUEL_CAPACITY,
                      allow_passenger_at_destination: bool = False, who: str = "taxi"):
  """Checks a user's `[row, col, passenger, destination(, fuel)]` and returns the
  five-int state tuple (see `validate_state`)."""
  names = _FIELDS if fuel_enabled else _FIELDS[:4]
  arr = np.asarray(state)
  if arr.shape != (len(names),):
    raise ValueError(f"{who}: a state is [{', '.join(names)}] (shape ({len(names)},)), "
                     f"got {state!r} of shape {arr.shape}")
  values = list(arr) + ([] if fuel_enabled else [None])
  return validate_state(*values, fuel_enabled=fuel_enabled, capacity=capacity,
                        allow_passenger_at_destination=allow_passenger_at_destination, who=who)


def _int_in(value, low: int, high: int, name: str, who: str) -> int:
  arr = np.asarray(value)
  if arr.ndim != 0 or arr.dtype.kind not in "iu" or not low <= int(arr) <= high:
    raise ValueError(f"{who}: {name} must be an integer in {low}..{high}, got {value!r}")
  return int(arr)


class TaxiRules:
  """One taxi task's configuration and its rules, shared by every backend.

  The defaults are SPEC section 5's; each can be changed. The Gymnasium
  environment and the dm_control task both step through `step`, which calls the
  compiled `taxi_step`, so the rules live in one place.
  """

  def __init__(self, fuel_enabled: bool = True, *, fuel_station=FUEL_STATION,
               capacity: int = FUEL_CAPACITY, start_fuel=(START_FUEL_MIN, START_FUEL_MAX),
               max_steps: int = MAX_STEPS, who: str = "taxi"):
    """Args:
      fuel_enabled: taxi-fuel (7 actions) or Gymnasium's classic taxi (6 actions).
      fuel_station: (row, col) of F; SPEC default (2, 1).
      capacity: the tank, 12; Fillup at F sets the fuel to it.
      start_fuel: (low, high), the start fuel is uniform in low..high; (5, 12).
      max_steps: primitive steps before the episode is truncated; 200.
      who: the task's name in error messages.
    Raises:
      ValueError: naming the argument, its value and what is allowed.
    """
    self.fuel_enabled = bool(fuel_enabled)
    self.who = who
    if np.shape(fuel_station) != (2,):
      raise ValueError(f"{who}: fuel_station must be (row, col), got {fuel_station!r}")
    self.fuel_station = (_int_in(fuel_station[0], 0, GRID_SIZE - 1, "fuel_station row", who),
                         _int_in(fuel_station[1], 0, GRID_SIZE - 1, "fuel_station col", who))
    self.capacity = _int_in(capacity, 1, 10**6, "capacity", who)
    if np.shape(start_fuel) != (2,):
      raise ValueError(f"{who}: start_fuel must be (low, high), got {start_fuel!r}")
    low = _int_in(start_fuel[0], 0, self.capacity, "start_fuel low", who)
    high = _int_in(start_fuel[1], low, self.capacity, "start_fuel high", who)
    self.start_fuel = (low, high)
    self.max_steps = _int_in(max_steps, 1, 2**62, "max_steps", who)
    self.num_actions = num_actions(self.fuel_enabled)
    self.action_names = ACTION_NAMES[:self.num_actions]
    self.num_states = num_states(self.fuel_enabled, self.capacity)

  def sample_start(self, rng):
    """A random start state (SPEC section 5) drawn from `rng`."""
    return sample_initial_state(rng, self.fuel_enabled, *self.start_fuel)

  def check_state(self, state, *, strict: bool = True):
    """A user's `[row, col, passenger, destination(, fuel)]` as a state tuple.

    With `strict`, a passenger waiting at its own destination is refused.
    """
    return state_from_vector(state, fuel_enabled=self.fuel_enabled, capacity=self.capacity,
                             allow_passenger_at_destination=not strict, who=self.who)

  def step(self, state, action: int):
    """`(next_state, reward, terminated)` for a valid state and action index."""
    row, col, passenger, destination, fuel, reward, terminated = taxi_step(
        state[0], state[1], state[2], state[3], state[4], action, self.fuel_enabled,
        self.fuel_station[0], self.fuel_station[1], self.capacity)
    return (row, col, passenger, destination, fuel), float(reward), bool(terminated)

  def legal_actions(self, state):
    """The int8 mask of `legal_actions` for `state`."""
    return legal_actions(state[0], state[1], state[2], state[3], state[4], self.fuel_enabled,
                         self.fuel_station[0], self.fuel_station[1], self.capacity)

  def encode(self, state) -> int:
    """The index of `state` (row, col, passenger, destination, fuel)."""
    return int(encode_state(state[0], state[1], state[2], state[3], state[4], self.fuel_enabled))
