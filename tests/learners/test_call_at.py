"""A compiled function called through the address of its code (`learners.jit.call_at`)."""
import collections

import numba
import numpy as np
import pytest
from numba.core import errors

from hpg_mj.learners import banks
from hpg_mj.learners import jit

Pair = collections.namedtuple("Pair", ("ints", "floats"))


@numba.njit(error_model="numpy", _nrt=False)
def _scale(p, i, factor, values):
  """Writes through a struct and an array; returns a tuple; raises on a bad index."""
  if i >= p.ints.shape[0]:
    raise IndexError("no such row")
  p.ints[i] += 1
  for k in range(values.shape[0]):
    values[k] *= factor
  return p.ints[i] * factor, values.sum()


@numba.njit(error_model="numpy", _nrt=False)
def _through(address, p, i, values):
  return jit.call_at(_scale, address, (p, i, 2.0, values))    # i: a literal where constant


@numba.njit(error_model="numpy", _nrt=False)
def _through_int(address, p, i, values):
  return jit.call_at(_scale, address, (p, i, 2, values))


@numba.njit(error_model="numpy", _nrt=False)
def _direct(p, i, values):
  return _scale(p, i, 2.0, values)


def _pair():
  return Pair(np.zeros(3, dtype=np.int64), np.zeros(3))


def test_a_call_through_the_address_is_the_call():
  (p,) = banks.as_structs(_pair())
  values = np.arange(4.0)
  address = jit.address_of(_scale, (p, np.int64(0), 2.0, values))
  assert address != 0
  assert _through(address, p, 1, values) == (2.0, 12.0)
  assert _direct(p, 1, values) == (4.0, 24.0)
  assert _through(address, p, 1, values) == (6.0, 48.0)
  assert values.tolist() == [0.0, 8.0, 16.0, 24.0]


def test_an_exception_in_the_callee_reaches_the_caller():
  (p,) = banks.as_structs(_pair())
  values = np.ones(2)
  address = jit.address_of(_scale, (p, np.int64(0), 2.0, values))
  with pytest.raises(IndexError, match="no such row"):
    _through(address, p, 7, values)


def test_an_address_never_set_raises_rather_than_crashes():
  (p,) = banks.as_structs(_pair())
  with pytest.raises(RuntimeError, match="_scale: called through an address never set"):
    _through(0, p, 0, np.ones(2))


def test_an_array_other_than_a_writable_c_one_is_refused_when_compiled():
  (p,) = banks.as_structs(_pair())
  values = np.ones(4)
  address = jit.address_of(_scale, (p, np.int64(0), 2.0, values))
  with pytest.raises(errors.TypingError, match="writable C-contiguous"):
    _through(address, p, 0, values[::2])
  values.flags.writeable = False
  with pytest.raises(errors.TypingError, match="writable C-contiguous"):
    _through(address, p, 0, values)


def test_a_caller_whose_types_address_of_did_not_compile_is_refused():
  """An int where address_of was given a float: other code, refused as it compiles."""
  (p,) = banks.as_structs(_pair())
  values = np.ones(2)
  address = jit.address_of(_scale, (p, np.int64(0), 2.0, values))
  with pytest.raises(errors.TypingError, match="_scale has no code for"):
    _through_int(address, p, 0, values)
