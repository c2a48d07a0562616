"""hpg_mj: hierarchical policy gradient benchmarks on MuJoCo.

Importing the package registers the Gymnasium environments
(`hpg_mj/ShipSteering-v0`, ... see `hpg_mj.envs`). The dm_control suite is
`hpg_mj.suite`.

"SPEC section N" in comments and docstrings is section N of the project's
specification, docs/SPEC.md in the repository.
"""
import os as _os

# Headless rendering: MuJoCo picks its OpenGL backend when first imported.
# Without a display, use EGL where an NVIDIA device is present, OSMesa otherwise.
if "MUJOCO_GL" not in _os.environ and not _os.environ.get("DISPLAY"):
  _os.environ["MUJOCO_GL"] = "egl" if _os.path.exists("/dev/nvidia0") else "osmesa"
  _os.environ.setdefault("PYOPENGL_PLATFORM", _os.environ["MUJOCO_GL"])

__version__ = "0.1.0"

from hpg_mj import envs as _envs  # noqa: E402  (registers the Gymnasium ids)

_envs.register_all()
