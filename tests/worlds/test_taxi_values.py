"""Known answers for the exact values of taxi-fuel and the classic taxi
(hpg_mj.worlds.taxi_values): hand-computed states, the Bellman optimality
equation everywhere, and the classic values against shortest paths by BFS."""
import numpy as np
import pytest
from taxi_grid import moves_between

from hpg_mj.worlds import taxi_core as tc
from hpg_mj.worlds import taxi_values as tv

R, G, Y, B = 0, 1, 2, 3
AT = {R: (0, 0), G: (0, 4), Y: (4, 0), B: (4, 3)}
F = (2, 1)
IN_TAXI = tc.IN_TAXI


@pytest.fixture(scope="module")
def fuel():
  return tv.taxi_values(True)


@pytest.fixture(scope="module")
def classic():
  return tv.taxi_values(False)


# --- hand-computed states ------------------------------------------------------

def test_passenger_aboard_at_destination(fuel):
  # Dropoff at once: +20, whatever fuel is left above 0.
  for fuel_left in (1, 5, 12):
    assert fuel.state_value(*AT[G], IN_TAXI, G, fuel_left) == 20.0
  # An empty tank: any action but Fillup at F ends the episode with -20.
  assert fuel.state_value(*AT[G], IN_TAXI, G, 0) == -20.0


def test_refuel_at_f(fuel):
  # From F to Y is 3 moves (west, south, south); the Dropoff costs a 4th unit.
  assert fuel.state_value(*F, IN_TAXI, Y, 4) == 20 - 3       # just enough fuel
  assert fuel.state_value(*F, IN_TAXI, Y, 3) == 20 - 3 - 1   # one short: Fillup first
  assert fuel.state_value(*F, IN_TAXI, Y, 0) == 20 - 3 - 1   # Fillup works on an empty tank


def test_refuel_on_the_way(fuel):
  # Taxi at R with the passenger there, bound for G: Pickup, 8 moves, Dropoff.
  assert moves_between(AT[R], AT[G]) == 8
  assert fuel.state_value(*AT[R], R, G, 12) == 20 - 1 - 8        # 10 actions, 12 units
  assert fuel.state_value(*AT[R], R, G, 10) == 20 - 1 - 8        # exactly enough
  # With 9 units: F (2, 1) lies on a shortest way R -> G, so top up there: one more step.
  assert fuel.state_value(*AT[R], R, G, 9) == 20 - 1 - 8 - 1


def test_doomed_taxi(fuel):
  # Fuel 1 far from F and from delivery: one more action, then -20 on the next.
  assert fuel.state_value(4, 4, Y, R, 1) == -1 - 20


def test_classic_values_are_shortest_paths(classic):
  for square in range(25):
    taxi = divmod(square, 5)
    for passenger in range(4):
      for destination in range(4):
        if destination == passenger:
          continue
        expected = 20 - moves_between(taxi, AT[passenger]) - 1 - moves_between(
            AT[passenger], AT[destination])
        assert classic.state_value(*taxi, passenger, destination) == expected
      # Aboard: drive to the destination and drop off.
      assert classic.state_value(*taxi, IN_TAXI, passenger) == 20 - moves_between(
          taxi, AT[passenger])


# --- whole-table checks ---------------------------------------------------------

@pytest.mark.parametrize("task", ["fuel", "classic"])
def test_bellman_optimality_holds_everywhere(task, request):
  values = request.getfixturevalue(task)
  backup = np.max(values.reward + (~values.terminal) * values.v[values.next_state], axis=1)
  np.testing.assert_array_equal(backup, values.v)
  np.testing.assert_array_equal(values.q.max(axis=1), values.v)


def test_model_tables_match_taxi_step(fuel):
  rng = np.random.default_rng(0)
  for s in rng.integers(0, tc.NUM_FUEL_STATES, 200):
    state = tc.decode_state(s)
    for a in range(tc.NUM_ACTIONS_FUEL):
      *nxt, reward, terminal = tc.taxi_step(*state, a)
      assert fuel.next_state[s, a] == tc.encode_state(*nxt)
      assert fuel.reward[s, a] == reward
      assert fuel.terminal[s, a] == terminal


def test_truncation_does_not_bind(fuel, classic):
  # The longest optimal episode from any state; 200 steps never cut one short.
  assert fuel.steps.max() == 22
  assert classic.steps.max() == 18
  assert fuel.v.min() == -24.0    # above the -200 a truncated episode earns at most


def test_start_distribution(fuel, classic):
  starts = fuel.start_states()
  assert starts.shape == (25 * 4 * 3 * 8,)
  assert len(set(starts.tolist())) == starts.shape[0]
  for s in starts[::97]:
    row, col, passenger, destination, fuel_left = tc.decode_state(s)
    assert passenger < IN_TAXI and destination != passenger and 5 <= fuel_left <= 12
  assert classic.start_states().shape == (25 * 4 * 3,)
  with pytest.raises(ValueError, match="start_fuel"):
    fuel.start_states((3, 13))


# --- optimal mean returns -------------------------------------------------------

def test_classic_optimal_mean_return_by_bfs():
  total = 0
  for square in range(25):
    for passenger in range(4):
      for destination in range(4):
        if destination != passenger:
          total += 19 - moves_between(divmod(square, 5), AT[passenger]) - moves_between(
              AT[passenger], AT[destination])
  assert tv.optimal_mean_return(fuel=False) == pytest.approx(total / 300, abs=1e-12)
  assert tv.optimal_mean_return(fuel=False) == pytest.approx(7.93, abs=1e-12)


def test_fuel_optimal_mean_return(fuel):
  assert tv.optimal_mean_return(fuel=True) == pytest.approx(14747 / 2400, abs=1e-12)
  # Fuel costs the optimal driver on average 1.785 per episode against the classic task.
  assert tv.optimal_mean_return(True) < tv.optimal_mean_return(False)


def test_performance_threshold():
  assert tv.performance_threshold(6.0) == pytest.approx(5.7)
  assert tv.performance_threshold(-19.0) == pytest.approx(-20.0)
  assert tv.performance_threshold(0.0) == 0.0
  with pytest.raises(ValueError, match="fraction"):
    tv.performance_threshold(1.0, 1.5)


def test_steps_to_reach_counts_to_the_first_trailing_window_at_the_threshold():
  # Returns 0 for 3 episodes of 10 steps, then 6 (the threshold of 6.0 is 5.7): a
  # window of 2 first reaches a mean of 5.7 nowhere before both episodes are 6s.
  returns, steps = [0.0, 0.0, 0.0, 6.0, 6.0, 6.0], [10, 10, 10, 5, 5, 5]
  assert tv.steps_to_reach(returns, steps, 6.0, window=2) == 40.0
  assert tv.steps_to_reach(returns, steps, 6.0, window=1) == 35.0
  assert np.isnan(tv.steps_to_reach(returns[:4], steps[:4], 6.0, window=2))     # never
  assert np.isnan(tv.steps_to_reach(returns, steps, 6.0, window=7))             # too short


def test_bad_arguments():
  with pytest.raises(ValueError, match="capacity"):
    tv.TaxiValues(True, capacity=0)
  with pytest.raises(ValueError, match="fuel_station"):
    tv.TaxiValues(True, fuel_station=(5, 0))
