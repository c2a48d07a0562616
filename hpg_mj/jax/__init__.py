"""The ship and the taxi as pure-JAX environments, with gymnax's functional interface
(the optional extra: `pip install hpg_mj[jax]`).

```python
env, params = hpg_mj.jax.make("ShipSteering-v0")
obs, state = env.reset(key, params)
obs, state, reward, done, info = env.step(key, state, action, params)
```

Every function is jit-, vmap- and scan-able, and float64 is there with
`jax.config.update("jax_enable_x64", True)`. The ids are the Gymnasium ids of
`hpg_mj.envs` (`hpg_mj/ShipSteering-v0`, ...), every one of them, with or without
the `hpg_mj/` prefix; the task ladder's four take a `level` (`make("ShipGoal-v0",
level="hard")`). In
float64 the JAX worlds equal the analytic numba worlds step by step (SPEC sections
1-3, 5, 8 and 11; tests/jax); those, the dm_control and the Gymnasium tasks stay
the reference. See docs/jax.md.

Nothing else in hpg_mj imports JAX, and this module imports it only in `make`
and where a submodule is named (`hpg_mj.jax.ship_goal`, loaded on first use; the
environments' modules import it when loaded), so the registry below is readable
without it.
"""
import importlib

# id -> (module:class, constructor arguments): the Gymnasium ids of hpg_mj.envs.ENV_IDS.
ENV_IDS = {
    "hpg_mj/ShipSteering-v0": ("hpg_mj.jax.ship:ShipSteering", {"task": "steer"}),
    "hpg_mj/ShipSteeringDiagonal-v0": ("hpg_mj.jax.ship:ShipSteering", {"task": "diagonal"}),
    "hpg_mj/ShipSteeringStraight-v0": ("hpg_mj.jax.ship:ShipSteering", {"task": "straight"}),
    "hpg_mj/ShipPatrol-v0": ("hpg_mj.jax.ship:ShipSteering", {"task": "patrol"}),
    "hpg_mj/TaxiFuel-v0": ("hpg_mj.jax.taxi:Taxi", {"fuel": True}),
    "hpg_mj/Taxi-v0": ("hpg_mj.jax.taxi:Taxi", {"fuel": False}),
    # The task ladder's (SPEC section 11): `level` is a constructor argument, as the
    # Gymnasium environments' (`make(id, level="hard")`), the default given here.
    "hpg_mj/ShipCurrent-v0": ("hpg_mj.jax.ship_current:ShipCurrent", {"level": "easy"}),
    "hpg_mj/ShipGoal-v0": ("hpg_mj.jax.ship_goal:ShipGoal", {"level": "easy"}),
    "hpg_mj/ShipRegatta-v0": ("hpg_mj.jax.ship_regatta:ShipRegatta", {"level": "easy"}),
    "hpg_mj/ShipHarbour-v0": ("hpg_mj.jax.ship_harbour:ShipHarbour", {"level": "easy"}),
}

PREFIX = "hpg_mj/"
INSTALL = "pip install hpg_mj[jax]"


# jax.monitoring's duration events of one compile: the lowering of a traced function
# and the backend's compile (the tracing is left out: it is part of running).
COMPILE_EVENTS = ("/jax/core/compile/jaxpr_to_mlir_module_duration",
                  "/jax/core/compile/backend_compile_duration")


def listen_to_compiles(callback):
  """Tells `callback(seconds)` the seconds of each of XLA's compiles (`COMPILE_EVENTS`)
  from now on, until the function returned is called (`hpg_mj._compiling.timer`, which
  keeps `hpg-mj train`'s compile_seconds apart from its train_seconds)."""
  _require_jax()
  from jax import monitoring
  listening = [True]

  def listener(name, seconds, **_):
    if listening[0] and name in COMPILE_EVENTS:
      callback(seconds)
  monitoring.register_event_duration_secs_listener(listener)
  unregister = getattr(monitoring, "unregister_event_duration_listener", None)

  def stop():
    listening[0] = False              # where this JAX cannot unregister, silent instead
    if unregister is not None:
      unregister(listener)
  return stop


def canonical_id(env_id):
  """The registered id of `env_id`, given with or without the `hpg_mj/` prefix."""
  name = env_id if not isinstance(env_id, str) or env_id.startswith(PREFIX) else PREFIX + env_id
  if name not in ENV_IDS:
    short = sorted(i[len(PREFIX):] for i in ENV_IDS)
    raise ValueError(f"unknown hpg_mj.jax environment id {env_id!r}; valid ids: {short} "
                     f"(with or without the {PREFIX!r} prefix)")
  return name


def _scorers_name(env_id, level):
  """(id, level) of a ladder task named as `hpg_mj.benchmark` names it ("ship_current",
  "ship_current/hard"), else `(env_id, level)` as given."""
  if not isinstance(env_id, str) or not env_id.startswith("ship_"):
    return env_id, level
  from hpg_mj.worlds import ship_ladder
  task, slash, written = env_id.partition("/")
  if task not in ship_ladder.ENV_IDS:
    return env_id, level
  if slash and level is not None and level != written:
    raise ValueError(f"{env_id!r} names level {written!r} and level={level!r} another; give "
                     "the level once")
  return ship_ladder.ENV_IDS[task], written if slash else level


def __getattr__(name):
  """`hpg_mj.jax.ship_goal` (and every other submodule) after a plain `import
  hpg_mj.jax`, imported on first use (PEP 562), so that the module stays light."""
  import pkgutil
  if name in {m.name for m in pkgutil.iter_modules(__path__)}:
    _require_jax()
    return importlib.import_module(f"{__name__}.{name}")
  raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _require_jax():
  try:
    import jax  # noqa: F401
    import jax.numpy  # noqa: F401
  except ImportError as error:
    raise ImportError(f"hpg_mj.jax needs JAX, which is not installed: {INSTALL}") from error


def make(env_id, level=None, **params):
  """`(env, params)` for an hpg_mj id, as `gymnax.make`: the environment and its
  default `EnvParams`, with `params` (field names of its `EnvParams`, for example
  `max_steps_in_episode=1000` or `out_of_bounds_reward=-300.0`) replacing defaults.
  `level` ("easy", "medium" or "hard") picks a task ladder's level (SPEC section
  11; None: "easy"), as the Gymnasium environments' argument. A ladder task may also
  be named as `hpg_mj.benchmark` names it: `make("ship_current/hard")`.

  Raises ValueError naming the id, level or parameter and what is allowed,
  ImportError naming the extra to install where JAX is missing.
  """
  env_id, level = _scorers_name(env_id, level)
  name = canonical_id(env_id)
  _require_jax()
  path, kwargs = ENV_IDS[name]
  if level is not None:
    if "level" not in kwargs:
      raise ValueError(f"{name} has no levels (level={level!r}); the ids with levels: "
                       f"{sorted(i[len(PREFIX):] for i, e in ENV_IDS.items() if 'level' in e[1])}")
    kwargs = {**kwargs, "level": level}
  module, cls = path.split(":")
  env = getattr(importlib.import_module(module), cls)(env_id=name, **kwargs)
  defaults = env.default_params
  allowed = list(type(defaults).__dataclass_fields__)
  unknown = sorted(set(params) - set(allowed))
  if unknown:
    raise ValueError(f"{name}: unknown parameter(s) {unknown}; allowed: {allowed}")
  chosen = defaults.replace(**params)
  _check_values(name, defaults, chosen, params)
  return env, chosen


# What `make` allows of a parameter beyond its kind (a whole number for the int fields, a
# finite number for the float fields, an array of the default's shape for the obstacles).
_ABOVE_ZERO = (lambda v: v > 0, "above 0")
_RANGES = {
    "max_steps_in_episode": (lambda v: v >= 1, "at least 1"),
    "speed": _ABOVE_ZERO, "time_constant": _ABOVE_ZERO, "sampling_interval": _ABOVE_ZERO,
    "half_width": _ABOVE_ZERO, "spacing": _ABOVE_ZERO,
    "min_cos": (lambda v: -1 <= v <= 1, "in [-1, 1]"),
    "gates": (lambda v: 1 <= v <= _max_gates(), "in 1..{max_gates}"),
    "fuel_row": (lambda v: 0 <= v < _grid_size(), "in 0..{last_cell}"),
    "fuel_col": (lambda v: 0 <= v < _grid_size(), "in 0..{last_cell}"),
    "capacity": (lambda v: v >= 1, "at least 1"),
    "start_fuel_min": (lambda v: v >= 0, "at least 0"),
    "start_fuel_max": (lambda v: v >= 0, "at least 0"),
}
# Pairs whose first may not exceed the second.
_ORDERED = (("gate_low", "gate_high"), ("smallest_turn_deg", "largest_turn_deg"),
            ("start_fuel_min", "start_fuel_max"), ("start_fuel_max", "capacity"))


def _grid_size():
  from hpg_mj.worlds import taxi_core
  return taxi_core.GRID_SIZE


def _max_gates():
  from hpg_mj.worlds import ship_regatta_core
  return ship_regatta_core.MAX_GATES


def _check_values(name, defaults, chosen, given):
  """Refuses, in one line naming the parameter and what is allowed, a value `make` was
  given that the environment cannot take (a traced value is left to the caller)."""
  import numpy as np
  for key, value in given.items():
    default = getattr(defaults, key)
    try:
      if isinstance(value, (str, bytes)):
        raise TypeError(value)
      array = np.asarray(value, dtype=float)
    except Exception:          # a tracer, or no number at all
      if type(value).__module__.startswith("jax"):
        continue
      raise ValueError(f"{name}: {key} must be a number, got {value!r}") from None
    if np.shape(default) != ():
      if array.shape != np.shape(default) or not np.all(np.isfinite(array)) or np.any(
          array[:, -1] < 0):
        raise ValueError(f"{name}: {key} must be {np.shape(default)[0]} rows of "
                         f"{np.shape(default)[1]} finite numbers (rows of zeros for none, "
                         f"the last column at least 0), got shape {array.shape}")
      continue
    whole = isinstance(default, int)
    if array.shape != () or isinstance(value, bool) or not np.isfinite(array) or (
        whole and array != np.round(array)):
      kind = "a whole number" if whole else "a finite number"
      raise ValueError(f"{name}: {key} must be {kind}, got {value!r}")
    rule = _RANGES.get(key)
    if rule is not None and not rule[0](float(array)):
      allowed = rule[1].format(max_gates=_max_gates(), last_cell=_grid_size() - 1)
      raise ValueError(f"{name}: {key} must be {allowed}, got {value!r}")
  for low, high in _ORDERED:
    if not (low in given or high in given) or not hasattr(chosen, low):
      continue
    try:
      out_of_order = float(getattr(chosen, low)) > float(getattr(chosen, high))
    except Exception:          # a traced value: not known here
      continue
    if out_of_order:
      raise ValueError(f"{name}: {low} ({getattr(chosen, low)!r}) may not exceed {high} "
                       f"({getattr(chosen, high)!r})")
