"""Learning rules, each written once as numba functions over plain arrays.

The step-by-step path (any dm_control or Gymnasium environment, driven from
Python) and the fused compiled loops (the analytic environments) call these
same functions, so the two cannot drift apart.
"""
from hpg_mj import _collector  # noqa: F401  (pauses the collector while numba compiles)
