"""dm_env's own conformance tests (`dm_env.test_utils.EnvironmentTestMixin`) on every task
and level of the suite: resets, steps after LAST, specs of every time step."""
import unittest

from dm_env import test_utils

from hpg_mj import suite


def _case(domain, task):
  class Case(test_utils.EnvironmentTestMixin, unittest.TestCase):
    def make_object_under_test(self):
      return suite.load(domain, task, {"random": 0})
  Case.__name__ = Case.__qualname__ = f"Test_{domain}_{task}"
  return Case


for _domain, _task in suite.ALL_TASKS:
  globals()[f"Test_{_domain}_{_task}"] = _case(_domain, _task)
del _domain, _task
