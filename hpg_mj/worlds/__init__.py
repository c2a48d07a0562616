"""The worlds: each task's physics and rules, and its dm_control task. A world is a
compiled core of plain-array rules (`ship_core`, `taxi_core`, ...), which every
backend and agent steps, and a module beside it with its dm_control `Physics` and
`Task` (`ship`, `taxi`, ...); the MuJoCo model is in assets/."""
from hpg_mj import _collector  # noqa: F401  (pauses the collector while numba compiles)
