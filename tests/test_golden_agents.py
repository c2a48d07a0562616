"""Every shipped task file gives, bit for bit, the records and final state stored
in tests/golden/agents/ (on the compiled path, step by step through Gymnasium and,
for the taxi, through the dm_control board): code that moves or is rewritten must
not change a number. tests/golden/agents_golden.py says how they were made."""
import pathlib
import sys

import numpy as np
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent / "golden"))
import agents_golden  # noqa: E402


@pytest.mark.parametrize("name", sorted(agents_golden.SCHEDULES))
def test_agent_matches_its_golden_record(name):
  want = dict(np.load(agents_golden.HERE / f"{name}.npz"))
  got = agents_golden.produce(name)
  assert sorted(got) == sorted(want)
  for key, value in want.items():
    np.testing.assert_array_equal(got[key], value, err_msg=f"{name}: {key}")
  assert want["compiled.steps"].sum() > 10_000        # a real amount of learning
