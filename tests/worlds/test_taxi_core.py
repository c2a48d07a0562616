"""Known answers for every taxi-fuel rule (SPEC section 5), and the classic taxi
against Gymnasium's Taxi transition table."""
import numpy as np
import pytest
from gymnasium.envs.toy_text.taxi import MAP
from gymnasium.envs.toy_text.taxi import TaxiEnv as GymnasiumTaxi

from hpg_mj.worlds import taxi_core as tc
from hpg_mj.worlds.taxi_core import DROPOFF, EAST, FILLUP, NORTH, PICKUP, SOUTH, WEST

R, G, Y, B = 0, 1, 2, 3
AT = {R: (0, 0), G: (0, 4), Y: (4, 0), B: (4, 3)}
F = (2, 1)


def step(state, action, fuel_enabled=True, **kwargs):
  """taxi_step on a 5-tuple state: (next_state, reward, terminated)."""
  out = tc.taxi_step(*state, action, fuel_enabled, **kwargs)
  return tuple(int(v) for v in out[:5]), int(out[5]), bool(out[6])


# --- the board ---------------------------------------------------------------

def test_walls_are_gymnasium_taxi_map():
  for row in range(5):
    for col in range(5):
      # In MAP, the character east of square (row, col) is at column 2 * col + 2.
      wall = MAP[1 + row][2 * col + 2] != ":"
      assert tc.WALL_EAST[row, col] == wall, (row, col)


def test_stations_and_actions_are_gymnasium_taxi():
  env = GymnasiumTaxi()
  assert [tuple(s) for s in tc.STATIONS] == env.locs
  assert tc.ACTION_NAMES[:6] == ("South", "North", "East", "West", "Pickup", "Dropoff")
  assert (SOUTH, NORTH, EAST, WEST, PICKUP, DROPOFF, FILLUP) == tuple(range(7))


# --- moves -------------------------------------------------------------------

OPEN_MOVES = [  # (row, col), action, (row, col) after
    ((1, 1), SOUTH, (2, 1)),
    ((2, 2), NORTH, (1, 2)),
    ((2, 2), EAST, (2, 3)),
    ((2, 2), WEST, (2, 1)),
    ((2, 1), EAST, (2, 2)),  # row 2 has no interior wall
    ((3, 1), EAST, (3, 2)),
    ((0, 2), EAST, (0, 3)),
]

BUMPS = [  # (row, col), action: a -1 no-op
    ((4, 2), SOUTH), ((0, 3), NORTH),                       # the border, rows
    ((2, 4), EAST), ((2, 0), WEST),                         # the border, columns
    ((0, 1), EAST), ((1, 1), EAST), ((0, 2), WEST), ((1, 2), WEST),  # wall 1|2, rows 0-1
    ((3, 0), EAST), ((4, 0), EAST), ((3, 1), WEST), ((4, 1), WEST),  # wall 0|1, rows 3-4
    ((3, 2), EAST), ((4, 2), EAST), ((3, 3), WEST), ((4, 3), WEST),  # wall 2|3, rows 3-4
]


@pytest.mark.parametrize("start,action,end", OPEN_MOVES)
def test_move(start, action, end):
  assert step((*start, B, R, 7), action) == ((*end, B, R, 6), -1, False)


@pytest.mark.parametrize("start,action", BUMPS)
def test_wall_bump_is_a_no_op_that_costs_fuel(start, action):
  assert step((*start, B, R, 7), action) == ((*start, B, R, 6), -1, False)


def test_every_interior_wall_blocks_both_ways_and_nothing_else():
  blocked = {(r, c) for r in range(5) for c in range(4) if tc.WALL_EAST[r, c]}
  assert blocked == {(0, 1), (1, 1), (3, 0), (4, 0), (3, 2), (4, 2)}
  for r in range(5):
    for c in range(4):
      east = step((r, c, R, G, 5), EAST)[0][:2]
      west = step((r, c + 1, R, G, 5), WEST)[0][:2]
      if (r, c) in blocked:
        assert east == (r, c) and west == (r, c + 1)
      else:
        assert east == (r, c + 1) and west == (r, c)


# --- Pickup and Dropoff ------------------------------------------------------

@pytest.mark.parametrize("station", [R, G, Y, B])
def test_legal_pickup_at_each_station(station):
  destination = (station + 1) % 4
  assert step((*AT[station], station, destination, 9), PICKUP) == (
      (*AT[station], tc.IN_TAXI, destination, 8), -1, False)


def test_illegal_pickup():
  # Away from the passenger's station (on another station, and off any station).
  assert step((*AT[G], R, B, 9), PICKUP) == ((*AT[G], R, B, 8), -10, False)
  assert step((2, 2, R, B, 9), PICKUP) == ((2, 2, R, B, 8), -10, False)
  # The passenger is already in the taxi.
  assert step((*AT[R], tc.IN_TAXI, B, 9), PICKUP) == ((*AT[R], tc.IN_TAXI, B, 8), -10, False)


@pytest.mark.parametrize("destination", [R, G, Y, B])
def test_legal_dropoff_delivers_and_terminates(destination):
  assert step((*AT[destination], tc.IN_TAXI, destination, 3), DROPOFF) == (
      (*AT[destination], destination, destination, 2), 20, True)


def test_dropoff_at_a_wrong_station_is_illegal():
  # Dietterich's rule (SPEC section 5), also in the classic task: nothing changes.
  for fuel_enabled in (True, False):
    expected_fuel = 8 if fuel_enabled else 9
    assert step((*AT[Y], tc.IN_TAXI, G, 9), DROPOFF, fuel_enabled) == (
        (*AT[Y], tc.IN_TAXI, G, expected_fuel), -10, False)


def test_dropoff_off_any_station_and_without_passenger_is_illegal():
  assert step((2, 2, tc.IN_TAXI, G, 9), DROPOFF) == ((2, 2, tc.IN_TAXI, G, 8), -10, False)
  # At the destination, but the passenger still waits elsewhere.
  assert step((*AT[G], R, G, 9), DROPOFF) == ((*AT[G], R, G, 8), -10, False)
  # On the passenger's own station, without picking them up.
  assert step((*AT[R], R, G, 9), DROPOFF) == ((*AT[R], R, G, 8), -10, False)


# --- fuel --------------------------------------------------------------------

@pytest.mark.parametrize("fuel", [0, 1, 5, 11, 12])
def test_fillup_at_f_fills_the_tank(fuel):
  for passenger in (R, tc.IN_TAXI):
    assert step((*F, passenger, B, fuel), FILLUP) == ((*F, passenger, B, 12), -1, False)


def test_fillup_away_from_f_is_a_no_op_that_costs_fuel():
  assert step((2, 2, R, B, 7), FILLUP) == ((2, 2, R, B, 6), -1, False)
  assert step((*AT[R], R, B, 1), FILLUP) == ((*AT[R], R, B, 0), -1, False)


@pytest.mark.parametrize("action", range(7))
def test_any_action_with_an_empty_tank_ends_the_episode(action):
  # Away from F even Fillup runs dry: -20 instead of the action's reward, terminal,
  # nothing moves and the fuel stays 0.
  state = (*AT[B], tc.IN_TAXI, B, 0)   # at the destination, Dropoff would deliver
  assert step(state, action) == (state, -20, True)


def test_moves_at_f_with_an_empty_tank_also_run_dry():
  for action in (SOUTH, NORTH, EAST, WEST, PICKUP, DROPOFF):
    assert step((*F, R, B, 0), action) == ((*F, R, B, 0), -20, True)


def test_last_unit_of_fuel_still_acts():
  assert step((*AT[B], tc.IN_TAXI, B, 1), DROPOFF) == ((*AT[B], B, B, 0), 20, True)
  assert step((2, 2, R, B, 1), NORTH) == ((1, 2, R, B, 0), -1, False)


def test_configurable_fuel_station_and_capacity():
  kwargs = dict(fuel_row=4, fuel_col=4, capacity=20)
  assert step((4, 4, R, B, 0), FILLUP, **kwargs) == ((4, 4, R, B, 20), -1, False)
  assert step((*F, R, B, 3), FILLUP, **kwargs) == ((*F, R, B, 2), -1, False)


def test_classic_ignores_fuel():
  assert step((2, 2, R, B, 0), NORTH, False) == ((1, 2, R, B, 0), -1, False)
  assert step((*AT[B], tc.IN_TAXI, B, 0), DROPOFF, False) == ((*AT[B], B, B, 0), 20, True)


@pytest.mark.parametrize("action,fuel_enabled", [(6, False), (7, True), (-1, True), (-1, False)])
def test_taxi_step_refuses_actions_outside_the_task(action, fuel_enabled):
  with pytest.raises(ValueError, match="0..5 .classic taxi. or 0..6"):
    tc.taxi_step(2, 2, R, B, 5, action, fuel_enabled)


# --- Gymnasium's Taxi --------------------------------------------------------

def test_classic_agrees_with_gymnasium_taxi_table():
  """All 500 states x 6 actions of Gymnasium's Taxi (v3 and v4 share it) `P`, except the 12 Dropoffs where
  Gymnasium leaves the passenger at a station that is not their destination
  (-1); the SPEC keeps Dietterich's rule there (-10, nothing changes)."""
  table = GymnasiumTaxi().P
  differences = []
  for index in range(500):
    state = tc.decode_state(index, False)
    for action in range(6):
      ((_, gym_next, gym_reward, gym_done),) = table[index][action]
      nxt, reward, done = step(state, action, False)
      ours = (tc.encode_state(*nxt, False), reward, done)
      if ours != (gym_next, gym_reward, gym_done):
        differences.append((state, action, ours, (gym_next, gym_reward, gym_done)))
  expected = []
  for station in range(4):
    for destination in range(4):
      if destination != station:
        s = (*AT[station], tc.IN_TAXI, destination, tc.CLASSIC_FUEL)
        gym_next = tc.encode_state(*AT[station], station, destination, 0, False)
        expected.append((s, DROPOFF, (tc.encode_state(*s, False), -10, False),
                         (gym_next, -1, False)))
  assert sorted(differences) == sorted(expected)
  assert len(differences) == 12


# --- state index -------------------------------------------------------------

def test_encode_is_gymnasium_index_and_decode_inverts_it():
  env = GymnasiumTaxi()
  for index in range(500):
    row, col, passenger, destination, fuel = tc.decode_state(index, False)
    assert fuel == tc.CLASSIC_FUEL
    assert env.encode(row, col, passenger, destination) == index
    assert tc.encode_state(row, col, passenger, destination, 0, False) == index
  assert list(env.decode(137)) == list(tc.decode_state(137, False)[:4])


def test_fuel_index_is_fuel_times_500_plus_classic():
  seen = set()
  for index in range(tc.NUM_FUEL_STATES):
    state = tc.decode_state(index, True)
    assert tc.encode_state(*state, True) == index
    assert index == state[4] * 500 + tc.encode_state(*state, False)
    seen.add(state)
  assert len(seen) == 6500 == tc.num_states(True)
  assert tc.encode_state(4, 4, 4, 3, 12, True) == 6499
  assert tc.encode_state(0, 0, 0, 0, 0, True) == 0


# --- start states ------------------------------------------------------------

def test_initial_state_distribution():
  rng = np.random.default_rng(0)
  starts = [tc.sample_initial_state(rng) for _ in range(20000)]
  cells = {(s[0], s[1]) for s in starts}
  layouts = {(s[2], s[3]) for s in starts}
  fuels = np.array([s[4] for s in starts])
  assert cells == {(r, c) for r in range(5) for c in range(5)}
  assert layouts == {(p, d) for p in range(4) for d in range(4) if p != d}
  assert set(fuels) == set(range(5, 13))
  assert all(s[2] != s[3] and s[2] < 4 for s in starts)
  # Each of the 12 (passenger, destination) pairs about 1/12 of the time.
  counts = np.unique([s[2] * 4 + s[3] for s in starts], return_counts=True)[1]
  assert counts.min() > 20000 / 12 * 0.85 and counts.max() < 20000 / 12 * 1.15


def test_initial_state_classic_and_seeds():
  for make_rng in (np.random.default_rng, np.random.RandomState):
    a = [tc.sample_initial_state(make_rng(5), False) for _ in range(3)]
    assert a[0] == a[1] == a[2] and a[0][4] == tc.CLASSIC_FUEL
    first = [tc.sample_initial_state(make_rng(11)) for _ in range(2)]
    assert first[0] == first[1]
  rng = np.random.RandomState(1)
  assert len({tc.sample_initial_state(rng) for _ in range(50)}) > 40
  with pytest.raises(TypeError, match="Generator or RandomState"):
    tc.sample_initial_state(3)


def test_state_from_draws_covers_the_other_three_stations():
  for station in range(4):
    destinations = {tc.state_from_draws(7, station, other, 9)[3] for other in range(3)}
    assert destinations == set(range(4)) - {station}
  assert tc.state_from_draws(7, 0, 0, 9) == (1, 2, 0, 1, 9)


def test_numba_sampler_is_in_range():
  for _ in range(500):
    row, col, passenger, destination, fuel = tc.sample_initial_state_numba(True)
    assert 0 <= row < 5 and 0 <= col < 5 and 0 <= passenger < 4
    assert destination != passenger and 5 <= fuel <= 12


# --- action mask -------------------------------------------------------------

def test_legal_actions_are_the_actions_that_do_something():
  for index in range(0, tc.NUM_FUEL_STATES, 7):
    state = tc.decode_state(index, True)
    if state[4] == 0:
      continue
    mask = tc.legal_actions(*state)
    for action in range(7):
      nxt, reward, _ = step(state, action)
      acts = (nxt[:4] != state[:4]) or (action == FILLUP and nxt[4] > state[4])
      assert bool(mask[action]) == (acts and reward != -10), (state, action)
  assert tc.legal_actions(2, 1, R, B, 12)[FILLUP] == 0   # a full tank
  assert tc.legal_actions(2, 1, R, B, 12, False).shape == (6,)


# --- checking states ---------------------------------------------------------

@pytest.mark.parametrize("state,message", [
    ((5, 0, R, B, 5), "row=5 is off the grid; allowed 0..4"),
    ((0, -1, R, B, 5), "col=-1 is off the grid; allowed 0..4"),
    ((0, 0, 5, B, 5), "passenger=5 is not allowed; allowed 0..4"),
    ((0, 0, R, 4, 5), "destination=4 is not allowed; allowed 0..3"),
    ((0, 0, G, G, 5), "passenger=1 waits at its own destination 1 .G."),
    ((0, 0, R, B, 13), "fuel=13 is outside the tank; allowed 0..12"),
    ((0, 0, R, B, -1), "fuel=-1 is outside the tank; allowed 0..12"),
    ((0.5, 0, R, B, 5), "row must be an integer in 0..4"),
    ((0, 0, R, B, None), "needs a fuel level in 0..12"),
])
def test_validate_state_names_field_value_and_range(state, message):
  with pytest.raises(ValueError, match=message):
    tc.validate_state(*state)


def test_validate_state_accepts_what_episodes_contain():
  assert tc.validate_state(1, 2, tc.IN_TAXI, R, 0) == (1, 2, 4, 0, 0)
  assert tc.validate_state(np.int64(1), 2, G, R, 12) == (1, 2, 1, 0, 12)
  assert tc.validate_state(0, 0, G, G, 5, allow_passenger_at_destination=True) == (0, 0, 1, 1, 5)
  assert tc.validate_state(0, 0, R, B, fuel_enabled=False) == (0, 0, 0, 3, tc.CLASSIC_FUEL)
  assert tc.validate_state(0, 0, R, B, 20, capacity=20) == (0, 0, 0, 3, 20)


def test_state_from_vector_checks_length():
  assert tc.state_from_vector([0, 1, 2, 3, 4]) == (0, 1, 2, 3, 4)
  with pytest.raises(ValueError, match=r"\[row, col, passenger, destination, fuel\]"):
    tc.state_from_vector([0, 1, 2, 3])
  with pytest.raises(ValueError, match=r"\[row, col, passenger, destination\] .shape .4,"):
    tc.state_from_vector([0, 1, 2, 3, 4], fuel_enabled=False)


@pytest.mark.parametrize("kwargs,message", [
    (dict(fuel_station=(5, 0)), "fuel_station row must be an integer in 0..4"),
    (dict(fuel_station=3), r"fuel_station must be \(row, col\)"),
    (dict(capacity=0), "capacity must be an integer in 1.."),
    (dict(start_fuel=(5, 13)), "start_fuel high must be an integer in 5..12"),
    (dict(max_steps=0), "max_steps must be an integer in 1.."),
])
def test_rules_refuse_bad_configuration(kwargs, message):
  with pytest.raises(ValueError, match=message):
    tc.TaxiRules(True, **kwargs)


def test_rules_step_uses_configuration():
  rules = tc.TaxiRules(True, fuel_station=(0, 0), capacity=4, start_fuel=(4, 4))
  assert rules.step((0, 0, G, B, 1), FILLUP) == ((0, 0, G, B, 4), -1.0, False)
  assert rules.sample_start(np.random.default_rng(0))[4] == 4
  assert rules.num_states == 500 * 5 and rules.num_actions == 7
