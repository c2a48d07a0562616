"""Simulation without OpenGL (SPEC section 9).

`import mujoco` picks its OpenGL backend from `MUJOCO_GL` when first imported
(unset on Linux: GLFW), and so does `dm_control._render` when `dm_control.mujoco`
is first imported (unset: GLFW, then EGL, then OSMesa). Either can map OSMesa,
EGL, GL and Mesa's LLVM into the process, and Mesa's LLVM beside the one torch
loads through triton crashes the process (mujoco issue #644). hpg_mj therefore
imports MuJoCo and dm_control for simulation with `MUJOCO_GL=disable`, only for
the duration of that import, and renders in a separate process
(`hpg_mj._render_worker`).
"""
import contextlib
import os
import re

# The libraries that must not be mapped into a process that simulates: OSMesa,
# EGL, GL (libGL, libGLX, libGLdispatch, ...), Mesa's LLVM and its drivers, GLFW.
GL_LIBRARY = re.compile(r"^(lib(OSMesa|EGL|GL|LLVM|gallium|glfw)[\w.+-]*\.so|\w+_dri\.so)")


@contextlib.contextmanager
def simulation_imports():
  """Imports inside this block load MuJoCo and dm_control without a GL backend.

  The user's `MUJOCO_GL` (set or unset) is restored on leaving, so nothing of
  theirs changes. Modules imported before (by the user) keep what they chose.
  """
  saved = os.environ.get("MUJOCO_GL")
  os.environ["MUJOCO_GL"] = "disable"
  try:
    yield
  finally:
    if saved is None:
      del os.environ["MUJOCO_GL"]
    else:
      os.environ["MUJOCO_GL"] = saved


def mapped_gl_libraries(maps_path="/proc/self/maps"):
  """The GL libraries mapped into this process (Linux), as sorted file names."""
  found = set()
  with open(maps_path) as maps:
    for line in maps:
      name = os.path.basename(line.rstrip("\n").split(" ")[-1])
      if GL_LIBRARY.match(name):
        found.add(name)
  return sorted(found)
