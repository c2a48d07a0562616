"""A namedtuple of arrays as one struct that compiled code takes by reference.

numba passes a namedtuple by value: every function, and every inlined call, that
takes one carries all its arrays as one aggregate (seven numbers and pointers an
array), and numba's typing and lowering, then LLVM, pay for each copy. A machine
whose banks hold ~45 arrays compiled four to five times slower than the same code
over a namedtuple of five (a scratch benchmark of twelve inlined calls: 5.5 s
against 1.0 s). `as_structs(*banks)` makes a struct of each bank's fields (the
same arrays, not copies) that compiled code takes as one pointer; `bank.field` reads
the field through it. The banks keep their namedtuples for Python.

The fields are read without reference counting (the machine compiles without it)
and as invariant loads: a struct's fields are set once, when it is made, and never
assigned again (its arrays' contents change; the arrays do not), so LLVM may keep a
field it has read in a register across the arrays' writes, as it does a
namedtuple's. Compiled code cannot assign a field. The struct holds a reference to
each of its arrays, released when the struct is.
"""
import ctypes

import numba
import numpy as np
from llvmlite import ir
from numba.core import cgutils
from numba.core import imputils
from numba.core import types
from numba.core.datamodel import default_manager
from numba.core.datamodel import models
from numba.core.extending import NativeValue
from numba.core.extending import box
from numba.core.extending import infer_getattr
from numba.core.extending import lower_getattr_generic
from numba.core.extending import unbox
from numba.core.registry import cpu_target
from numba.core.runtime import _nrt_python
from numba.core.runtime import nrt
from numba.core.typing.templates import AttributeTemplate
from numba.experimental import function_type
from numba.experimental import structref

# NRT_MemInfo's fields (numba's nrt.h): refct, dtor, dtor_info, data, ...
_MEMINFO_DATA = 3


class BankType(types.StructRef):
  """The numba type of a bank's struct: its fields' names and types."""

  def preprocess_fields(self, fields):
    """The fields' types without literal values (a field holds any value of its type)."""
    return tuple((name, types.unliteral(t)) for name, t in fields)


default_manager.register(BankType, models.StructRefModel)


class Bank(structref.StructRefProxy):
  """A bank's struct in Python: only passed to compiled functions."""


@box(BankType)
def _box(typ, value, c):
  """A Bank around the struct's MemInfo (`structref.define_boxing`'s)."""
  meminfo = cgutils.create_struct_proxy(typ)(c.context, c.builder, value=value).meminfo
  boxed = c.box(types.MemInfoPointer(types.voidptr), meminfo)
  make = c.pyapi.unserialize(c.pyapi.serialize_object(Bank._numba_box_))
  typ_obj = c.pyapi.unserialize(c.pyapi.serialize_object(typ))
  out = c.pyapi.call_function_objargs(make, [typ_obj, boxed])
  for obj in (make, typ_obj, boxed):
    c.pyapi.decref(obj)
  return out


@unbox(BankType)
def _unbox(typ, obj, c):
  """The struct of a Bank. Taking its MemInfo from Python takes a reference, which a
  function compiled with numba's runtime gives back after the call; one compiled
  without it (as the machine's are) would not, and the struct would never be freed:
  for those, the reference is given back here."""
  meminfo_obj = c.pyapi.object_getattr_string(obj, "_meminfo")
  meminfo = c.pyapi.nrt_meminfo_from_pyobject(meminfo_obj)
  c.pyapi.decref(meminfo_obj)
  struct = cgutils.create_struct_proxy(typ)(c.context, c.builder)
  struct.meminfo = meminfo

  if c.context.enable_nrt:
    return NativeValue(struct._getvalue(), is_error=cgutils.is_null(c.builder, meminfo))

  def cleanup():
    release = cgutils.get_or_insert_function(
        c.builder.module, ir.FunctionType(ir.VoidType(), [cgutils.voidptr_t]),
        "NRT_MemInfo_release")
    c.builder.call(release, [meminfo])
  return NativeValue(struct._getvalue(), is_error=cgutils.is_null(c.builder, meminfo),
                     cleanup=cleanup)


@infer_getattr
class _BankAttributes(AttributeTemplate):
  key = BankType

  def generic_resolve(self, typ, attr):
    return typ.field_dict.get(attr)


def _invariant(builder, load):
  load.set_metadata("invariant.load", builder.module.add_metadata([]))
  return load


@lower_getattr_generic(BankType)
def _field(context, builder, typ, value, attr):
  """bank.attr: the data pointer of the struct's MemInfo (read directly, as
  NRT_MemInfo_data does, so that no runtime is needed), then the field."""
  meminfo = cgutils.create_struct_proxy(typ)(context, builder, value=value).meminfo
  slots = builder.bitcast(meminfo, cgutils.voidptr_t.as_pointer())
  data = _invariant(builder, builder.load(builder.gep(slots, [cgutils.int32_t(_MEMINFO_DATA)])))
  model = context.data_model_manager[typ.get_data_type()]
  data = builder.bitcast(data, model.get_value_type().as_pointer())
  at = builder.gep(data, [cgutils.int32_t(0), cgutils.int32_t(model.get_field_position(attr))])
  field_type = typ.field_dict[attr]
  raw = _invariant(builder, builder.load(at))
  value = context.data_model_manager[field_type].from_data(builder, raw)
  # a new reference where the function counts them (it releases what it read), none
  # where it does not
  return imputils.impl_ret_borrowed(context, builder, field_type, value)


def _struct_type(bank):
  return BankType(list(zip(bank.fields, bank.types)))


# The struct of a bank is written from Python, word by word, in the layout of numba's
# data model for it (`_words`), not compiled: a compiled maker unboxed every array of
# the banks in its C wrapper, ~15 ms of LLVM work an array, 0.8-1.3 s of every
# machine's first compile. Every field the banks hold is laid out in 8-byte words
# (an array's meminfo, parent, size, item size, data, shape and strides; a number; a
# struct's meminfo; a first-class function's three addresses; None's null pointer),
# so the payload is their words in order, and its size is checked against numba's.
# An array's meminfo is left null (numba counts no references on a null meminfo, as
# for its constant arrays): the arrays, the payload and the structs it points to are
# held by the struct's own meminfo (`rtsys.meminfo_new`: it holds a reference to a
# Python object, released with it), so they live exactly as long as the struct.

_meminfo_of = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.py_object)(
    _nrt_python.c_helpers["meminfo_from_pyobject"])
_release = ctypes.CFUNCTYPE(None, ctypes.c_void_p)(_nrt_python.c_helpers["MemInfo_release"])


def _words(value, typ, out, keep):
  """The 8-byte words of `value`, of numba type `typ`, as numba lays them out."""
  if isinstance(typ, types.Array):
    out += [0, id(value), value.size, value.itemsize, value.__array_interface__["data"][0],
            *value.shape, *value.strides]
    keep.append(value)
  elif isinstance(typ, types.NoneType):
    out.append(0)
  elif isinstance(typ, types.Integer) and typ.bitwidth == 64:
    out.append(int(value))
  elif isinstance(typ, types.Float) and typ.bitwidth == 64:
    out.append(int(np.float64(value).view(np.int64)))
  elif isinstance(typ, BankType):
    pointer = _meminfo_of(value._meminfo)          # a reference taken, and given back:
    _release(pointer)                              # the struct is kept in `keep`
    out.append(pointer)
    keep.append(value)
  elif isinstance(typ, types.FunctionType):
    signature = typ.signature
    out += [function_type._get_wrapper_address(value, signature), id(value),
            function_type._get_jit_address(value, signature)]
    keep.append(value)
  elif isinstance(typ, types.BaseTuple):
    for v, t in zip(value, typ):
      _words(v, t, out, keep)
  else:
    raise TypeError(f"banks.as_structs: a bank's field of type {typ} cannot go in a struct; "
                    "fields are arrays, 64-bit numbers, None, structs, first-class "
                    "functions, or tuples of these")


def _struct(bank):
  """The struct (a Bank) of the namedtuple `bank`."""
  typ = numba.typeof(bank)
  struct_type = _struct_type(typ)
  words, keep = [], [bank]
  for value, field_type in zip(bank, typ.types):
    _words(value, field_type, words, keep)
  payload = np.array(words, dtype=np.int64)
  context = cpu_target.target_context
  size = context.get_abi_sizeof(default_manager[struct_type.get_data_type()].get_value_type())
  if payload.nbytes != size:
    raise TypeError(f"banks.as_structs: {type(bank).__name__}'s fields take {payload.nbytes} "
                    f"bytes in 8-byte words, numba's struct of them {size}")
  keep.append(payload)
  nrt.rtsys.initialize(context)          # numba's runtime, which its first compile starts
  return Bank._numba_box_(struct_type, nrt.rtsys.meminfo_new(payload.ctypes.data, tuple(keep)))


def as_structs(*banks):
  """The struct of each namedtuple of arrays of `banks` (their arrays, not copies);
  a None among them stays None."""
  return tuple(None if b is None else _struct(b) for b in banks)


def field_type(bank_type, name):
  """The numba type of field `name` of a bank, given as a namedtuple or a struct."""
  if isinstance(bank_type, BankType):
    return bank_type.field_dict[name]
  return dict(zip(bank_type.fields, bank_type.types))[name]
