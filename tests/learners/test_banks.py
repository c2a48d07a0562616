"""A namedtuple of arrays as a struct passed by reference (`learners.banks`)."""
import collections
import gc
import os
import subprocess
import sys
import weakref

import numba
import numpy as np
import pytest
from numba.core import types

from hpg_mj.learners import banks

Pair = collections.namedtuple("Pair", ("ints", "floats", "extra"))


@numba.njit(error_model="numpy", _nrt=False)
def _bump(p, i):
  """Writes through the struct's fields and reads them back after the write."""
  p.ints[i] += 1
  p.floats[i, 0] = p.ints[i] * 0.5
  total = 0.0
  for k in range(p.floats.shape[0]):
    total += p.floats[k, 0]
  return total


def test_a_struct_holds_the_bank_arrays_themselves_not_copies():
  bank = Pair(np.zeros(3, dtype=np.int64), np.zeros((3, 2)), None)
  (ref,) = banks.as_structs(bank)
  assert _bump(ref, 1) == 0.5
  assert _bump(ref, 1) == 1.0
  assert bank.ints.tolist() == [0, 2, 0] and bank.floats[1, 0] == 1.0
  bank.floats[2, 0] = 10.0                  # a write from Python is seen by compiled code
  assert _bump(ref, 0) == 11.5
  other = Pair(np.zeros(2, dtype=np.int64), np.ones((2, 1)), None)
  first, second = banks.as_structs(bank, other)   # several at once, each its own arrays
  assert _bump(second, 1) == 1.5 and _bump(first, 0) == 12.0
  assert other.ints.tolist() == [0, 1] and bank.ints.tolist() == [2, 2, 0]
  assert banks.as_structs(bank, None)[1] is None      # a machine's absent bank stays None


def test_a_struct_keeps_its_arrays_alive_and_lets_them_go_with_it():
  ints, floats = np.zeros(3, dtype=np.int64), np.zeros((3, 2))
  (ref,) = banks.as_structs(Pair(ints, floats, None))
  alive = weakref.ref(ints)
  del ints, floats
  gc.collect()
  assert alive() is not None               # only the struct refers to it now
  assert _bump(ref, 2) == 0.5
  del ref
  gc.collect()
  assert alive() is None                   # released with the struct


@numba.njit
def _read(p, i):
  """The same through a function compiled with numba's reference counting."""
  return p.floats[i, 0]


def test_calls_neither_keep_nor_drop_a_reference_to_the_struct():
  ints = np.zeros(3, dtype=np.int64)
  (ref,) = banks.as_structs(Pair(ints, np.zeros((3, 2)), None))
  alive = weakref.ref(ints)
  for _ in range(5):
    _bump(ref, 0)
    _read(ref, 0)
  assert ref._meminfo.refcount == 1
  del ints, ref
  gc.collect()
  assert alive() is None


def test_field_types_read_alike_from_a_namedtuple_and_its_struct():
  bank = Pair(np.zeros(3, dtype=np.int64), np.zeros((3, 2)), None)
  for typ in (numba.typeof(bank), numba.typeof(banks.as_structs(bank)[0])):
    assert banks.field_type(typ, "ints") == types.int64[::1]
    assert isinstance(banks.field_type(typ, "extra"), types.NoneType)


def test_a_foreign_namedtuple_leaves_the_shared_cache_alone(tmp_path):
  """numba pickles every signature of a cached function into one index: a namedtuple
  class of another module's in `as_structs`'s made each later process that could not
  import that module fail to load it (a taxi agent's machine, in the experiment
  runner's workers). Structs are now made without compiling (`banks._words`), so no
  bank's type reaches the cache; this holds it so."""
  env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
  (tmp_path / "user").mkdir()
  (tmp_path / "user" / "mine.py").write_text(
      "import collections\nMine = collections.namedtuple('Mine', ('a',))\n")
  foreign = ("import numpy as np, mine\nfrom hpg_mj.learners import banks\n"
             "banks.as_structs(mine.Mine(np.zeros(2)))\n")
  ours = "from hpg_mj.agents import taxi_flat_q\ntaxi_flat_q.TaxiFlatQ()\n"   # its banks
  for code, where in ((ours, tmp_path), (foreign, tmp_path / "user"), (ours, tmp_path)):
    done = subprocess.run([sys.executable, "-c", code], env=env, cwd=where,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]


Inner = collections.namedtuple("Inner", ("a", "b"))
Outer = collections.namedtuple("Outer", ("n", "x", "inner", "ref", "none"))


@numba.njit(_nrt=False)
def _read_all(o):
  """Every kind of field a struct holds, read back: numbers, a namedtuple of arrays,
  another struct, None."""
  return o.n + o.x + o.inner.a[1] + o.inner.b[0, 1] + o.ref.floats[2, 1] + (o.none is None)


def test_every_kind_of_field_reads_back_from_the_struct():
  """The struct is written word by word in numba's layout (`banks._words`): a 64-bit
  integer and float, a namedtuple of arrays, another bank's struct and None read back
  as they were; a field that has no 8-byte layout is refused, by its type."""
  (pair,) = banks.as_structs(Pair(np.zeros(3, dtype=np.int64), np.arange(6.0).reshape(3, 2),
                                  None))
  inner = Inner(np.array([0.0, 0.25]), np.array([[0.0, 0.125]]))
  (outer,) = banks.as_structs(Outer(np.int64(3), 0.5, inner, pair, None))
  assert _read_all(outer) == 3 + 0.5 + 0.25 + 0.125 + 5.0 + 1
  alive = weakref.ref(inner.a)
  del inner, pair
  gc.collect()
  assert alive() is not None and _read_all(outer) == 9.875    # held by the struct
  with pytest.raises(TypeError, match="field of type bool cannot go in a struct"):
    banks.as_structs(Pair(np.zeros(1), np.zeros((1, 1)), True))
