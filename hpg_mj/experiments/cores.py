"""How many processes a command starts: never more than the runs it has to do, nor,
without a Ray cluster's address, more than the cores this process may run on, so
that a mistyped `--workers 100000` cannot start thousands of Python processes."""
import os


def available():
  """The cores this process may run on: its CPU affinity where the system keeps one
  (a container or `taskset` may allow fewer than the machine has), else all."""
  try:
    return len(os.sched_getaffinity(0))
  except (AttributeError, OSError):
    return os.cpu_count() or 1


def pool_size(requested, runs, address=None, here=None):
  """The processes to start for `runs` runs (None: not known ahead).

  `requested`: the user's `--workers` (None: one per core). Without `address`
  (a Ray cluster's, whose own CPUs bound it) the cores here (`here`, default
  `available()`) bound it too. At least 1."""
  if requested is not None and (isinstance(requested, bool) or not isinstance(requested, int)
                                or requested < 1):
    raise ValueError(f"workers must be a positive number of processes, got {requested!r}")
  here = available() if here is None else here
  wanted = requested if requested is not None else (runs if address and runs else here)
  if address is None:
    wanted = min(wanted, here)
  if runs is not None:
    wanted = min(wanted, runs)
  return max(1, wanted)
