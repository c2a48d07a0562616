"""Compile time apart from training time, for `hpg-mj train` and the runs' metrics
(`compile_seconds`; `train_seconds` is the wall time less it): numba's compiling
(its outermost compilations; loading from its cache is not one) and, where JAX is
in use, XLA's (`hpg_mj.jax.listen_to_compiles`: lowering and the backend's compile;
the tracing stays in the training time)."""
import contextlib
import sys


def uses_jax(agent):
  """Whether `agent` learns in JAX (its `tags` say "jax": the JAX agents)."""
  return "jax" in getattr(agent, "tags", ())


@contextlib.contextmanager
def timer(callback, jax=False):
  """A context in which `callback(seconds)` is told each compile's seconds: numba's,
  and XLA's where JAX is in use: `jax` (an agent that learns in JAX is about to), or
  JAX imported before the context opened. Nothing here imports JAX otherwise."""
  from numba.core import event
  stop = None
  if jax or "jax" in sys.modules:
    from hpg_mj import jax as hpg_jax
    stop = hpg_jax.listen_to_compiles(callback)
  try:
    with event.install_timer("numba:compile", callback):
      yield
  finally:
    if stop is not None:
      stop()
