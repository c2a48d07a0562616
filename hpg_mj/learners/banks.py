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
import numba
from llvmlite import ir
from numba.core import cgutils
from numba.core import imputils
from numba.core import types
from numba.core.datamodel import default_manager
from numba.core.datamodel import models
from numba.core.extending import NativeValue
from numba.core.extending import box
from numba.core.extending import infer_getattr
from numba.core.extending import intrinsic
from numba.core.extending import lower_getattr_generic
from numba.core.extending import unbox
from numba.core.typing.templates import AttributeTemplate
from numba.experimental import structref
from numba.experimental.jitclass.base import imp_dtor

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


@intrinsic
def _new_banks(typingctx, banks):
  """A struct of each namedtuple of `banks`, of its fields (each referenced once
  more), made in one compiled function whatever their number; None stays None."""
  if not (isinstance(banks, types.BaseTuple) and
          all(isinstance(b, (types.BaseNamedTuple, types.NoneType)) for b in banks)):
    return None
  struct_types = [b if isinstance(b, types.NoneType) else _struct_type(b) for b in banks]

  def codegen(context, builder, signature, args):
    out = []
    for k, (bank, struct_type) in enumerate(zip(banks, struct_types)):
      if isinstance(bank, types.NoneType):
        out.append(context.get_dummy_value())
        continue
      model = context.data_model_manager[struct_type.get_data_type()]
      alloc_type = model.get_value_type()
      meminfo = context.nrt.meminfo_alloc_dtor(
          builder, context.get_constant(types.uintp, context.get_abi_sizeof(alloc_type)),
          imp_dtor(context, builder.module, struct_type))
      data = builder.bitcast(context.nrt.meminfo_data(builder, meminfo),
                             alloc_type.as_pointer())
      payload = cgutils.create_struct_proxy(struct_type.get_data_type())(context, builder,
                                                                         ref=data)
      values = builder.extract_value(args[0], k)
      for i, (name, field_type) in enumerate(zip(bank.fields, bank.types)):
        value = builder.extract_value(values, i)
        context.nrt.incref(builder, field_type, value)
        setattr(payload, name, value)
      struct = cgutils.create_struct_proxy(struct_type)(context, builder)
      struct.meminfo = meminfo
      out.append(struct._getvalue())
    return context.make_tuple(builder, signature.return_type, out)
  return types.Tuple(struct_types)(banks), codegen


def _make(banks):
  return _new_banks(banks)


# numba's cache keeps one index per function, with every signature compiled, pickled:
# a namedtuple class of another package's (a test's, a user's) in it made every later
# process that could not import that package fail to load the index. hpg_mj's own
# banks are cached; anyone else's compile in their process.
# Without the C-callable wrapper numba adds to every function (only a first-class
# function needs one): over ~45 arrays it was a third of _make's first compile.
_as_structs = numba.njit(cache=True, no_cfunc_wrapper=True)(_make)
_as_foreign_structs = numba.njit(no_cfunc_wrapper=True)(_make)


def as_structs(*banks):
  """The struct of each namedtuple of arrays of `banks` (their arrays, not copies);
  a None among them stays None."""
  ours = all(b is None or type(b).__module__.startswith("hpg_mj.") for b in banks)
  return (_as_structs if ours else _as_foreign_structs)(banks)


def field_type(bank_type, name):
  """The numba type of field `name` of a bank, given as a namedtuple or a struct."""
  if isinstance(bank_type, BankType):
    return bank_type.field_dict[name]
  return dict(zip(bank_type.fields, bank_type.types))[name]
