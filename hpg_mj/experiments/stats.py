"""Statistics over runs (SPEC section 7): the mean with a 95% bootstrap confidence
interval (scipy.stats.bootstrap, percentile method), the interquartile mean, and
whether two learners' intervals separate, which is what a report needs before it
calls an ordering the paper's.
"""
import numpy as np

CONFIDENCE = 0.95
RESAMPLES = 2000
SEED = 0          # the bootstrap's own generator: a report is the same when redrawn


def _values(values):
  x = np.asarray(values, dtype=np.float64).reshape(-1)
  return x[~np.isnan(x)]


def mean_ci(values, confidence=CONFIDENCE, resamples=RESAMPLES, seed=SEED):
  """(mean, low, high) of the runs' values (NaNs left out): the percentile
  bootstrap interval of the mean. One value gives a zero-width interval; none
  gives NaNs."""
  import scipy.stats
  if not 0.0 < confidence < 1.0:
    raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")
  if isinstance(resamples, bool) or not isinstance(resamples, int) or resamples < 1:
    raise ValueError(f"resamples must be a positive integer, got {resamples!r}")
  x = _values(values)
  if len(x) == 0:
    return float("nan"), float("nan"), float("nan")
  mean = float(x.mean())
  if len(x) == 1 or np.all(x == x[0]):
    return mean, mean, mean
  result = scipy.stats.bootstrap((x,), np.mean, n_resamples=resamples, vectorized=True,
                                 confidence_level=confidence, method="percentile",
                                 rng=np.random.default_rng(seed))
  return mean, float(result.confidence_interval.low), float(result.confidence_interval.high)


def iqm(values):
  """The interquartile mean: the mean of the middle 50% of the runs' values."""
  import scipy.stats
  x = _values(values)
  return float(scipy.stats.trim_mean(x, 0.25)) if len(x) else float("nan")


def summary(values):
  """{"mean", "low", "high", "iqm", "n"} of the runs' values."""
  mean, low, high = mean_ci(values)
  return {"mean": mean, "low": low, "high": high, "iqm": iqm(values),
          "n": int(len(_values(values)))}


def band(data):
  """Per column of `data` (runs x points): mean, low, high of `mean_ci`."""
  data = np.asarray(data, dtype=np.float64)
  out = np.array([mean_ci(data[:, k]) for k in range(data.shape[1])]).reshape(-1, 3)
  return out[:, 0], out[:, 1], out[:, 2]


def separated(a, b):
  """Whether two `summary`s' intervals do not overlap."""
  if any(np.isnan(s[k]) for s in (a, b) for k in ("low", "high")):
    return False
  return a["high"] < b["low"] or b["high"] < a["low"]


def format_summary(s, digits=None, iqm=True):
  """'mean [low, high], IQM iqm' (or '-' when there is no value; without the IQM
  with `iqm=False`); `digits` after the point (default: 3 below 10, 2 below 100,
  else 1)."""
  if s is None or np.isnan(s["mean"]):
    return "-"
  if digits is None:
    size = abs(s["mean"])
    digits = 3 if size < 10 else 2 if size < 100 else 1
  f = f"{{:.{digits}f}}"
  text = f"{f.format(s['mean'])} [{f.format(s['low'])}, {f.format(s['high'])}]"
  return text + (f", IQM {f.format(s['iqm'])}" if iqm else "")
