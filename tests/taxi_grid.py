"""Test helper: shortest paths on the taxi's walled grid by breadth-first search,
independent of the value iteration and the task graph they check."""
import collections
import functools

from hpg_mj.worlds import taxi_core as tc


@functools.lru_cache(maxsize=None)
def moves_from(start):
  """Shortest number of moves from square `start` to every square."""
  dist = {start: 0}
  queue = collections.deque([start])
  while queue:
    square = queue.popleft()
    for action in (tc.SOUTH, tc.NORTH, tc.EAST, tc.WEST):
      nxt = tuple(int(v) for v in tc.taxi_step(*square, 0, 1, 12, action, False)[:2])
      if nxt not in dist:
        dist[nxt] = dist[square] + 1
        queue.append(nxt)
  return dist


def moves_between(start, goal):
  """Shortest number of moves from `start` to `goal` (the grid's moves are symmetric)."""
  return moves_from(start)[goal]
