"""`hpg-mj doctor`: what this machine offers hpg_mj, and what to do about each problem.

It reports the versions that matter, the OpenGL libraries this process maps
after simulating on MuJoCo (none, SPEC section 9), the render worker's
backends (each tried in its own worker), and whether numba can keep its
compiled functions between runs.
"""
import ctypes.util
import importlib.metadata
import os
import platform
import sys
import time

# The pinned pair (pyproject.toml): dm-control 1.0.50 breaks with mujoco 4.
PINNED = {"mujoco": "3.17.0", "dm-control": "1.0.50", "gymnasium": "1.4.0"}
VERSIONS = ("hpg_mj", "mujoco", "dm-control", "gymnasium", "numpy", "numba", "llvmlite",
            "PyOpenGL", "torch", "stable-baselines3")


def _version(distribution):
  try:
    return importlib.metadata.version(distribution)
  except importlib.metadata.PackageNotFoundError:
    return None


def check_versions():
  """(lines, problems): installed versions, and a problem for each pin not met."""
  lines, problems = [f"python {platform.python_version()} ({sys.executable})"], []
  for name in VERSIONS:
    version = _version(name)
    lines.append(f"{name} {version or 'not installed'}")
    pinned = PINNED.get(name)
    if pinned and version != pinned:
      problems.append((f"{name} is {version or 'not installed'}, hpg_mj needs {pinned}",
                       f"pip install '{name}=={pinned}' (mujoco 3.17.0 with dm-control "
                       "1.0.50: mujoco 4 breaks dm-control)"))
  return lines, problems


def check_process_gl():
  """(lines, problems): GL libraries mapped here after stepping the MuJoCo ship."""
  from hpg_mj import _headless
  if not os.path.exists("/proc/self/maps"):
    return ["GL in this process: not checked (no /proc/self/maps on this system)"], []
  import numpy as np

  from hpg_mj import suite
  env = suite.load("ship", "steer", {"random": 0})
  env.reset()
  env.step(np.array([5.0]))
  mapped = _headless.mapped_gl_libraries()
  if not mapped:
    return ["GL in this process after simulating on MuJoCo: none (safe to use torch)"], []
  return ([f"GL in this process after simulating on MuJoCo: {', '.join(mapped)}"],
          [(f"this process maps {', '.join(mapped)}: something imported mujoco or dm_control "
            "with a GL backend before hpg_mj did (Mesa's LLVM beside torch's crashes it, "
            "mujoco issue #644)",
            "import hpg_mj before anything that imports mujoco or dm_control, or set "
            "MUJOCO_GL=disable in the training process; hpg_mj renders in a worker anyway")])


def check_renderers():
  """(lines, problems): each render backend, tried in a worker of its own."""
  from hpg_mj import _render_worker as worker
  lines = []
  user = os.environ.get("MUJOCO_GL")
  order = worker.candidate_backends()
  lines.append(f"MUJOCO_GL {user!r}: the render worker tries {', '.join(order)}"
               if user is not None else
               f"MUJOCO_GL unset: the render worker tries {', '.join(order)}, in that order")
  for name, library in (("EGL", "EGL"), ("OSMesa", "OSMesa")):
    found = ctypes.util.find_library(library)   # looks up, does not load
    lines.append(f"lib{library}: {found or 'not found'}")
  working = []
  for backend in order:
    probe = worker.RenderWorker("physics", model_name="taxi.xml")
    start = time.perf_counter()
    try:
      probe.start(backends=(backend,))
      probe.render(height=48, width=48, camera_id="top")
    except worker.RenderingUnavailable as err:
      lines.append(f"renderer {err.failures[0]}")
      continue
    except (worker.RenderWorkerError, ValueError) as err:
      lines.append(f"renderer {backend}: started, but drawing failed: {err}")
      continue
    finally:
      seconds = time.perf_counter() - start
      probe.close()
    info = probe.info
    working.append(backend)
    lines.append(f"renderer {backend}: works, {info.get('gl_renderer')}, OpenGL "
                 f"{info.get('gl_version')} (worker up and first frame in {seconds:.1f} s)")
  if working:
    lines.append(f"renderer found: {working[0]} (used by render_mode='rgb_array', "
                 "physics.render, hpg-mj render and Figure 12's videos)")
    return lines, []
  return lines + ["renderer found: none"], [
      ("no render backend works: rendering (render_mode='rgb_array', hpg-mj render, videos) "
       "fails; simulation and training are unaffected", worker.INSTALL_HINT)]


def check_numba_cache():
  """(lines, problems): where numba keeps hpg_mj's compiled functions, and if it can write."""
  import tempfile

  from hpg_mj.worlds import ship_core
  try:
    from numba.core.caching import FunctionCache   # numba's own choice of folder
    path = FunctionCache(ship_core.euler_control.py_func).cache_path
    tempfile.TemporaryFile(dir=path).close()
  except (OSError, RuntimeError) as err:           # RuntimeError: no writable folder at all
    return ([f"numba cache: not writable ({err})"],
            [("numba cannot cache compiled functions: every new process compiles them "
              "again (seconds to a minute)",
              "set NUMBA_CACHE_DIR to a writable folder, for example "
              "NUMBA_CACHE_DIR=~/.cache/numba")])
  except (ImportError, AttributeError) as err:   # a numba whose internals moved
    return [f"numba cache: not checked ({type(err).__name__}: {err})"], []
  entries = len([f for f in os.listdir(path) if f.endswith(".nbi")]) if os.path.isdir(path) else 0
  return [f"numba cache: writable, {path} ({entries} compiled functions there)"], []


CHECKS = (("versions", check_versions), ("simulation", check_process_gl),
          ("rendering", check_renderers), ("compilation", check_numba_cache))


def run(out=print):
  """Prints the report; returns the number of problems found."""
  problems = []
  for title, check in CHECKS:
    out(f"{title}:")
    lines, found = check()
    for line in lines:
      out(f"  {line}")
    problems += found
  if not problems:
    out("no problems found")
  for problem, fix in problems:
    out(f"problem: {problem}\n  to do: {fix}")
  return len(problems)
