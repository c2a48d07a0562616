"""hpg_mj._validation: the one-call range check refuses and clips as the two checks do."""
import numpy as np
import pytest

from hpg_mj import _validation


def _two_checks(action, strict):
  value = _validation.finite_scalar_action(action, "task", "r")
  return _validation.clip_or_refuse(value, -15.0, 15.0, strict=strict, task="task", name="r")


def _outcome(check, action, strict):
  try:
    return check(action, strict)
  except ValueError as error:
    return ("ValueError", str(error))


@pytest.mark.parametrize("strict", [False, True])
@pytest.mark.parametrize("action", [
    np.array([3.5]), np.array([-15.0]), np.array([15.0]), np.array([40.0]), np.array([-40.0]),
    np.array([np.nan]), np.array([np.inf]), np.array([-np.inf]), np.array([3.5], np.float32),
    np.array([np.nan], np.float32), np.array([7]), np.array(2.0), np.array([[2.0]]),
    np.array([1.0, 2.0]), np.array([], np.float64), np.array(["a"]), np.array([True]),
    np.array([3.5]).astype(">f8"), np.array([1.0, 3.5])[1:], [3.5], 3.5, float("nan"), 20, None,
])
def test_bounded_scalar_action_is_the_two_checks(action, strict):
  def one_call(action, strict):
    return _validation.bounded_scalar_action(action, -15.0, 15.0, strict=strict, task="task",
                                             name="r")
  got, expected = _outcome(one_call, action, strict), _outcome(_two_checks, action, strict)
  assert got == expected
  if not isinstance(expected, tuple):
    assert type(got) is float
