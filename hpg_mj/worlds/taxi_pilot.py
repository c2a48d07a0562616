"""A scripted taxi driver: shortest paths on the walled grid, refuelling when the
tank would not last the trip. For demonstrations and videos, not learned."""
import collections

import numpy as np

from hpg_mj.worlds import taxi_core as core

_MOVES = (core.SOUTH, core.NORTH, core.EAST, core.WEST)


def _neighbours(row, col):
  for action in _MOVES:
    r, c, *_ = core.taxi_step(row, col, 0, 1, core.FUEL_CAPACITY, action, False)
    if (r, c) != (row, col):
      yield action, (r, c)


def distances_to(target):
  """Shortest number of moves from every square to `target`, and the first move."""
  dist = {tuple(target): 0}
  first = {}
  queue = collections.deque([tuple(target)])
  while queue:
    square = queue.popleft()
    for row in range(core.GRID_SIZE):
      for col in range(core.GRID_SIZE):
        if (row, col) in dist:
          continue
        for action, nxt in _neighbours(row, col):
          if nxt == square:
            dist[(row, col)] = dist[square] + 1
            first[(row, col)] = action
            queue.append((row, col))
            break
  return dist, first


class TaxiPilot:
  """Policy over the Gymnasium observation [row, col, passenger, destination(, fuel)]."""

  def __init__(self, fuel=True, fuel_station=core.FUEL_STATION):
    self.fuel = fuel
    self.fuel_station = tuple(fuel_station)
    self._routes = {}

  def reset(self):
    """A new episode: nothing to reset."""
    pass

  def _route(self, target):
    target = tuple(int(v) for v in target)
    if target not in self._routes:
      self._routes[target] = distances_to(target)
    return self._routes[target]

  def _go(self, square, target):
    dist, first = self._route(target)
    return dist[square], first.get(square)

  def __call__(self, obs):
    row, col, passenger, destination = (int(v) for v in obs[:4])
    square = (row, col)
    pickup = tuple(core.STATIONS[passenger]) if passenger < core.IN_TAXI else None
    drop = tuple(core.STATIONS[destination])
    target = pickup if pickup is not None else drop
    if self.fuel:
      # Enough fuel for the next leg (and its Pickup or Dropoff), and, unless that
      # leg ends the episode, to reach F afterwards; otherwise refuel first.
      fuel = int(obs[4])
      need = self._go(square, target)[0] + 1
      if pickup is not None:
        need += self._go(target, self.fuel_station)[0]
      if need > fuel and fuel < core.FUEL_CAPACITY:
        steps, move = self._go(square, self.fuel_station)
        if steps == 0:
          return np.int64(core.FILLUP)
        return np.int64(move)
    steps, move = self._go(square, target)
    if steps == 0:
      return np.int64(core.PICKUP if pickup is not None else core.DROPOFF)
    return np.int64(move)
