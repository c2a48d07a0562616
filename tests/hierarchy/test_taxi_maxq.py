"""MAXQ-Q (work in progress): on the classic taxi it reaches the optimal mean return."""
import numpy as np

from hpg_mj.baselines import taxi_maxq as mq
from hpg_mj.hierarchy import taxi_rules as rules
from hpg_mj.learners import rng
from hpg_mj.worlds import taxi_core, taxi_values


def _tables(fuel):
  sizes = mq.table_sizes(fuel)
  n_states = taxi_core.num_states(fuel)
  make = lambda: tuple(np.zeros(sizes[i] * rules.N_CHILDREN[i]) for i in range(5))  # noqa: E731
  return np.zeros(n_states * mq.N_PRIMITIVES), make(), make()


def test_maxq_q_reaches_the_classic_optimum():
  world = rules.world_config(taxi_core.TaxiRules(fuel_enabled=False))
  vp, ct, c = _tables(False)
  record = np.zeros((30000, mq.N_RECORD))
  mq.train(30000, 0, True, True, rng.make_state(0), world, vp, ct, c, 0.5, 0.1, 0.0, 15000,
           np.zeros(5), record)
  optimal = taxi_values.optimal_mean_return(False)
  assert record[-1000:, mq.RETURN].mean() >= 0.98 * optimal
  # Without pseudo-rewards the two completion functions are the same.
  for a, b in zip(ct, c):
    np.testing.assert_array_equal(a, b)
  # A greedy run from the learned tables delivers every passenger.
  greedy = np.zeros((500, mq.N_RECORD))
  mq.train(500, 30000, False, False, rng.make_state(1), world, vp, ct, c, 0.5, 0.1, 0.0, 15000,
           np.zeros(5), greedy)
  assert np.all(greedy[:, mq.OUTCOME] == rules.DELIVERED)
