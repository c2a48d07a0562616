"""Compiling the rules a fused loop calls before the loop itself.

numba compiles a function's callees while it types the function, one inside the
other, so the innermost rules of a deep loop compile with the Python stack
hundreds of frames deep. On Python 3.11 and 3.12 that is slow for an unrelated
reason (CPython gh-142183, fixed in later 3.13 and 3.14 releases): each time a
call crosses the boundary of the interpreter's 16 KB frame-stack chunks, the chunk
is mapped and unmapped again, and numba's compiler does so hundreds of thousands of
times. Compiled one by one from the bottom up, each function compiles near the top
of the stack, and the loop then finds its callees compiled (MAXQ-Q's first compile:
0.2 s of system time rather than 1.6 from the command line).

`call_at` calls a compiled function through the address of its code. numba links a
callee's code into each caller's and compiles it there again: LLVM optimizes the
caller with all its callees, and emits their machine code, once per caller. In a
chain of callers (the machine: `run_ship` > `step` > `_descend` > `_call` > ...) the
innermost code was compiled six times over, two fifths of a first train's LLVM time.
Through its address, a function's code is compiled once, in its own library; the
caller cannot inline it, so it is for calls whose work outweighs a call (a subtask's
call, a control step of the ship).
"""
import numba
from numba.core import cgutils
from numba.core import errors
from numba.core import types
from numba.core.compiler_lock import global_compiler_lock
from numba.extending import intrinsic

from hpg_mj import _stack


def compile_first(loop, rules):
  """Before `loop`'s first call in this process, compiles (or loads from numba's
  cache) each `(dispatcher, example arguments)` of `rules()` in order, for the types
  of the example arguments: list the callees before their callers. The examples'
  types must be those the loop calls them with, or the loop compiles them again for
  its own (as it would have anyway)."""
  if loop.signatures:
    return
  for dispatcher, example in rules():
    _stack.roomy(dispatcher.compile, tuple(numba.typeof(value) for value in example))


def _canonical(typ):
  """The type a function called through `call_at` is compiled for: an int64, a
  float64 or a bool for any integer, float or bool (literal or not); writable C
  arrays, structs and None as they are; any other array is refused. The caller and
  `address_of` must agree on the code's types without seeing each other."""
  typ = types.unliteral(typ)
  if isinstance(typ, types.Boolean):
    return types.boolean
  if isinstance(typ, types.Integer):
    return types.int64
  if isinstance(typ, types.Float):
    return types.float64
  if isinstance(typ, types.Array) and (typ.layout != "C" or not typ.mutable or not typ.aligned):
    raise errors.TypingError(f"call_at takes writable C-contiguous arrays; got {typ}")
  return typ


def canonical_signature(example):
  """The types `address_of` compiles a function for, given example arguments."""
  return tuple(_canonical(numba.typeof(value)) for value in example)


def address_of(dispatcher, example):
  """The address of `dispatcher`'s code for the (canonical) types of the values
  `example`, compiled or loaded from numba's cache now, for `call_at`. Valid in this
  process only, while the dispatcher lives."""
  signature = canonical_signature(example)
  dispatcher.compile(signature)
  compiled = dispatcher.overloads[signature]
  return compiled.library.get_pointer_to_function(compiled.fndesc.mangled_name)


def load_cached(dispatcher, signature):
  """Whether `dispatcher` has code for `signature` in this process, loading it from
  numba's cache if it is there (what `Dispatcher.compile` does before it compiles);
  never compiles. False where this numba's dispatcher lacks what it reads."""
  if signature in dispatcher.overloads:
    return True
  try:
    with global_compiler_lock:
      compiled = dispatcher._cache.load_overload(signature, dispatcher.targetctx)
      if compiled is None:
        return False
      dispatcher.targetctx.insert_user_function(compiled.entry_point, compiled.fndesc,
                                                [compiled.library])
      dispatcher.add_overload(compiled)
  except AttributeError:
    return False
  return True


@intrinsic
def call_at(typingctx, function, address, args):
  """function(*args) through `address`, the address of function's code for these
  arguments' canonical types (`address_of`, called before the caller compiles: a
  caller whose types have no such code is refused as it compiles, rather than call
  code for other types). An address of 0 (never set) raises, not a crash."""
  if not isinstance(function, types.Dispatcher) or not isinstance(args, types.BaseTuple):
    return None
  name = function.dispatcher.py_func.__name__
  canonical = tuple(_canonical(t) for t in args.types)
  if canonical not in function.dispatcher.overloads:
    raise errors.TypingError(f"call_at: {name} has no code for {canonical}: call address_of "
                             "first, with arguments of the types the caller passes")
  signature = typingctx.resolve_function_type(function, canonical, {})

  def codegen(context, builder, sig, values):
    arguments = [context.cast(builder, builder.extract_value(values[2], i), have, want)
                 for i, (have, want) in enumerate(zip(args.types, signature.args))]
    with cgutils.if_unlikely(builder, cgutils.is_null(builder, values[1])):
      context.call_conv.return_user_exc(
          builder, RuntimeError, (f"{name}: called through an address never set",))
    callee = builder.inttoptr(
        values[1], context.call_conv.get_function_type(signature.return_type,
                                                       signature.args).as_pointer())
    status, out = context.call_conv.call_function(builder, callee, signature.return_type,
                                                  signature.args, arguments)
    with cgutils.if_unlikely(builder, status.is_error):
      context.call_conv.return_status_propagate(builder, status)
    return out
  return signature.return_type(function, address, args), codegen
