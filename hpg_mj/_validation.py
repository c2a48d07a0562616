"""Checks shared by every environment: actions and states are refused early,
with the task, the value and what is allowed."""
import math

import numpy as np


def finite_scalar_action(action, task: str, name: str = "action") -> float:
  """Returns `action` as a float after checking it is one finite number.

  Accepts a Python number or an array of shape (), (1,) or (1, 1)... holding one
  element. NaN and infinity are always errors; the range is checked by the caller.
  """
  if type(action) is np.ndarray and action.shape == (1,) and action.dtype.kind == "f":
    value = float(action[0])   # the common case, without asarray and reshape (~1 us)
    if not math.isfinite(value):
      raise ValueError(f"{task}: {name} must be finite, got {value!r}")
    return value
  arr = np.asarray(action)
  if arr.dtype.kind not in "biuf":
    raise ValueError(f"{task}: {name} must be a number, got {action!r} of dtype {arr.dtype}")
  if arr.size != 1 or arr.ndim > 1:
    raise ValueError(f"{task}: {name} must have shape (1,), got shape {arr.shape} ({action!r})")
  value = float(arr.reshape(()))
  if not math.isfinite(value):
    raise ValueError(f"{task}: {name} must be finite, got {value!r}")
  return value


def clip_or_refuse(value: float, low: float, high: float, *, strict: bool, task: str,
                   name: str) -> float:
  """Clips `value` to [low, high]; in strict mode a value outside is an error."""
  if low <= value <= high:
    return value
  if strict:
    raise ValueError(f"{task}: {name} {value!r} is outside the allowed range [{low}, {high}] "
                     "(strict=True; without strict it is clipped)")
  return min(max(value, low), high)


_FLOAT64 = np.dtype(np.float64)


def bounded_scalar_action(action, low: float, high: float, *, strict: bool, task: str,
                          name: str = "action") -> float:
  """`finite_scalar_action` then `clip_or_refuse`, with their refusals and messages:
  `action` as a float, clipped to [low, high] (refused outside it if `strict`)."""
  kind = type(action)
  if kind is float or (kind is np.ndarray and action.dtype is _FLOAT64 and action.shape == (1,)):
    value = action if kind is float else action.item()
    if low <= value <= high:   # the common cases; False for NaN, so finite too
      return value
  return clip_or_refuse(finite_scalar_action(action, task, name), low, high, strict=strict,
                        task=task, name=name)


def discrete_action(action, n: int, task: str, names=None) -> int:
  """Returns `action` as an int in 0..n-1, or raises naming what is allowed."""
  arr = np.asarray(action)
  if arr.size != 1 or arr.ndim > 1:
    raise ValueError(f"{task}: action must be a single integer, got shape {arr.shape} ({action!r})")
  if arr.dtype.kind == "f":
    value = float(arr.reshape(()))
    if not math.isfinite(value):
      raise ValueError(f"{task}: action must be finite, got {value!r}")
    if value != int(value):
      raise ValueError(f"{task}: action must be an integer in 0..{n - 1}, got {value!r}")
  elif arr.dtype.kind not in "biu":
    raise ValueError(f"{task}: action must be an integer, got {action!r} of dtype {arr.dtype}")
  index = int(arr.reshape(()))
  if not 0 <= index < n:
    allowed = f"0..{n - 1}" if names is None else ", ".join(f"{i} {s}" for i, s in enumerate(names))
    raise ValueError(f"{task}: action {index} is not one of {allowed}")
  return index
