"""hpg_mj: hierarchical policy gradient benchmarks on MuJoCo.

Importing the package registers the Gymnasium environments
(`hpg_mj/ShipSteering-v0`, ... see `hpg_mj.envs`). The dm_control suite is
`hpg_mj.suite`.

Importing hpg_mj changes no environment variable and loads no OpenGL library:
simulation never needs one, and rendering happens in a worker process
(`hpg_mj._render_worker`, SPEC section 9).

"SPEC section N" in comments and docstrings is section N of the project's
specification, docs/SPEC.md in the repository.
"""
__version__ = "0.1.0"

from hpg_mj import envs as _envs  # registers the Gymnasium ids

_envs.register_all()
