"""Exact optimal values of the taxi-fuel MDP and of the classic taxi (SPEC section 5).

Value iteration over the full state table of `taxi_core` (6,500 states with fuel,
500 without), undiscounted and episodic:

    V(s) = max_a  r(s, a) + [not terminal(s, a)] * V(s'(s, a))      (Bellman optimality)

The taxi is deterministic and every reward is an integer, so the iterates are
integers held exactly in float64 and the loop stops when an iterate repeats,
which is the fixed point V* itself.

Why it converges, and to V*: this is a stochastic shortest path problem. Every
state can end its episode (deliver, or run the tank dry: with fuel 0 any action
but Fillup at F ends it), and every step that does not end the episode pays at
least 1 (-1, or -10 for an illegal Pickup/Dropoff), so a policy that never ends
has return minus infinity. Then the Bellman operator has the one fixed point V*,
and value iteration from V = 0 reaches it exactly after as many sweeps as the
longest optimal path (V_k is the best k-step return with 0 after k steps; an
unfinished k-step sequence earns at most -k).

The 200-step truncation (`taxi_core.MAX_STEPS`) does not bind: `optimal_steps`
gives the longest an optimal policy (any tie-break) takes from each state to the
end of its episode: at most 22 primitive steps from any of the 6,500 states with
the SPEC's defaults (18 in the classic task), well within 200. A truncated
episode earns at most -200 (200 steps of -1 or worse, no delivery), below every
V*(s) (the minimum is -24), so truncation can neither help nor hurt an optimal
policy: V* of the truncated task from a fresh start is the V* computed here.

With the SPEC's defaults the optimal mean return from the start distribution is
14,747 / 2,400 = 6.14458 with fuel and 7.93 in the classic task.

Unreachable states (a passenger waiting at its own destination: 100 per fuel
level) are valued by the same rules (Pickup there is legal, and so is the
Dropoff after it); no start distribution weights them.
"""
import functools

import numba
import numpy as np

from hpg_mj.worlds import taxi_core as core

_MAX_SWEEPS = 100_000   # a guard only: convergence takes a few dozen sweeps


@numba.njit(cache=True)
def transition_tables(fuel_enabled, fuel_row, fuel_col, capacity):
  """The deterministic model as arrays over (state index, action).

  Returns `(next_state, reward, terminal)`: int64, float64 and bool arrays of
  shape (num_states, num_actions), each entry from `taxi_core.taxi_step`.
  """
  n_actions = core.NUM_ACTIONS_FUEL if fuel_enabled else core.NUM_ACTIONS_CLASSIC
  n_states = core.NUM_CLASSIC_STATES * (capacity + 1) if fuel_enabled else core.NUM_CLASSIC_STATES
  next_state = np.empty((n_states, n_actions), dtype=np.int64)
  reward = np.empty((n_states, n_actions))
  terminal = np.empty((n_states, n_actions), dtype=np.bool_)
  for s in range(n_states):
    row, col, passenger, destination, fuel = core.decode_state(s, fuel_enabled)
    for a in range(n_actions):
      r2, c2, p2, d2, f2, rew, term = core.taxi_step(row, col, passenger, destination, fuel, a,
                                                     fuel_enabled, fuel_row, fuel_col, capacity)
      next_state[s, a] = core.encode_state(r2, c2, p2, d2, f2, fuel_enabled)
      reward[s, a] = rew
      terminal[s, a] = term
  return next_state, reward, terminal


class TaxiValues:
  """V*, Q* and the optimal path lengths of one taxi task.

  Attributes (arrays indexed by `taxi_core.encode_state`):
    v: float64[num_states], V*(s).
    q: float64[num_states, num_actions], Q*(s, a) = r + [not terminal] V*(s').
    steps: int64[num_states], the most primitive steps any optimal policy takes
      from s to the end of the episode (`optimal_steps`).
    next_state, reward, terminal: the model (`transition_tables`).
    sweeps: value-iteration sweeps until the iterate repeated.
  """

  def __init__(self, fuel_enabled: bool = True, fuel_station=core.FUEL_STATION,
               capacity: int = core.FUEL_CAPACITY):
    # TaxiRules checks the arguments and raises with the value and what is allowed.
    rules = core.TaxiRules(fuel_enabled, fuel_station=fuel_station, capacity=capacity,
                           who="taxi_values")
    self.fuel_enabled = rules.fuel_enabled
    self.fuel_station = rules.fuel_station
    self.capacity = rules.capacity
    self.next_state, self.reward, self.terminal = transition_tables(
        self.fuel_enabled, self.fuel_station[0], self.fuel_station[1], self.capacity)
    self.v, self.sweeps = value_iteration(self.next_state, self.reward, self.terminal)
    self.q = q_values(self.v, self.next_state, self.reward, self.terminal)
    self.steps = optimal_steps(self.q, self.v, self.next_state, self.terminal)

  def state_value(self, row, col, passenger, destination, fuel=core.CLASSIC_FUEL) -> float:
    """V* of one state (fuel ignored in the classic task)."""
    return float(self.v[core.encode_state(row, col, passenger, destination, fuel,
                                          self.fuel_enabled)])

  def start_states(self, start_fuel=(core.START_FUEL_MIN, core.START_FUEL_MAX)):
    """The indices of the SPEC start distribution's states, each equally likely:
    taxi on any of 25 squares, passenger at any of 4 stations, destination any of
    the other 3, fuel uniform in `start_fuel` (one classic fuel level without)."""
    low, high = start_fuel
    if not (0 <= low <= high <= self.capacity):
      raise ValueError(f"taxi_values: start_fuel must be (low, high) with 0 <= low <= high <= "
                       f"{self.capacity}, got {start_fuel!r}")
    fuels = range(low, high + 1) if self.fuel_enabled else (core.CLASSIC_FUEL,)
    out = []
    for fuel in fuels:
      for square in range(core.GRID_SIZE * core.GRID_SIZE):
        for station in range(4):
          for other in range(3):
            state = core.state_from_draws(square, station, other, fuel)
            out.append(core.encode_state(*state, self.fuel_enabled))
    return np.array(out, dtype=np.int64)

  def mean_start_value(self, start_fuel=(core.START_FUEL_MIN, core.START_FUEL_MAX)) -> float:
    """The expected return of an optimal policy from the start distribution."""
    return float(self.v[self.start_states(start_fuel)].mean())


def value_iteration(next_state, reward, terminal, max_sweeps: int = _MAX_SWEEPS):
  """V* by synchronous sweeps from V = 0 until an iterate repeats exactly.

  Returns `(v, sweeps)`. Raises RuntimeError if `max_sweeps` pass first (which
  the taxi, a stochastic shortest path problem, never does).
  """
  live = ~terminal
  v = np.zeros(next_state.shape[0])
  for sweep in range(1, max_sweeps + 1):
    new = np.max(reward + live * v[next_state], axis=1)
    if np.array_equal(new, v):
      return v, sweep
    v = new
  raise RuntimeError(f"taxi_values: value iteration did not converge in max_sweeps={max_sweeps}")


def q_values(v, next_state, reward, terminal):
  """Q*(s, a) = r(s, a) + [not terminal] V*(s')."""
  return reward + (~terminal) * v[next_state]


def optimal_steps(q, v, next_state, terminal):
  """The longest episode, in primitive steps, of any optimal policy from each state.

  L(s) = max over optimal a of 1 + [not terminal] L(s'). Optimal actions form no
  cycle (a cycle would earn 0 in total, but every non-final step pays at least
  1), so the iteration settles within as many sweeps as there are states.
  """
  optimal = q == v[:, None]
  live = ~terminal
  steps = np.zeros(v.shape[0], dtype=np.int64)
  for _ in range(v.shape[0] + 1):
    candidate = np.where(optimal, 1 + live * steps[next_state], -1)
    new = candidate.max(axis=1)
    if np.array_equal(new, steps):
      return steps
    steps = new
  raise RuntimeError("taxi_values: optimal actions form a cycle")  # unreachable, see above


@functools.lru_cache(maxsize=8)
def taxi_values(fuel: bool = True, fuel_station=core.FUEL_STATION,
                capacity: int = core.FUEL_CAPACITY) -> TaxiValues:
  """The (cached) `TaxiValues` of a task; `fuel_station` as a (row, col) tuple."""
  return TaxiValues(fuel, tuple(fuel_station), capacity)


def performance_threshold(optimal: float, fraction: float = 0.95) -> float:
  """The return that counts as `fraction` of `optimal`: fraction * optimal when
  optimal > 0, optimal / fraction when it is negative (closer to 0 is better),
  so reaching it always means doing at least that well."""
  if not 0.0 < fraction <= 1.0:
    raise ValueError(f"performance_threshold: fraction must be in (0, 1], got {fraction!r}")
  if optimal >= 0.0:
    return fraction * optimal
  return optimal / fraction


def steps_to_reach(returns, steps, optimal: float, fraction: float = 0.95,
                   window: int = 1000) -> float:
  """The primitive steps trained until the trailing `window`-episode mean return first
  reaches `fraction` of `optimal` (`performance_threshold`): the paper's Figure 6
  measure, counted to that window's last episode; NaN when it never does. `returns`
  and `steps` are a record's per-episode columns."""
  threshold = performance_threshold(optimal, fraction)
  returns = np.asarray(returns, dtype=np.float64)
  if len(returns) < window:
    return float("nan")
  trailing = np.convolve(returns, np.ones(window) / window, mode="valid")
  hit = np.nonzero(trailing >= threshold)[0]
  return float(np.cumsum(steps)[hit[0] + window - 1]) if len(hit) else float("nan")


def optimal_mean_return(fuel: bool = True, fuel_station=core.FUEL_STATION,
                        capacity: int = core.FUEL_CAPACITY,
                        start_fuel=(core.START_FUEL_MIN, core.START_FUEL_MAX)) -> float:
  """The exact expected return per episode of an optimal (flat) policy under the
  SPEC start distribution (taxi uniform on 25 squares, passenger uniform on 4
  stations, destination uniform on the other 3, fuel uniform in 5..12)."""
  return taxi_values(fuel, tuple(fuel_station), capacity).mean_start_value(tuple(start_fuel))
