"""Rendering in a worker process, so that OpenGL never enters the user's process.

SPEC section 9: OSMesa, EGL and Mesa's LLVM in the process that also holds
torch crash it (mujoco issue #644). Every picture hpg_mj draws (Gymnasium's
`render_mode="rgb_array"`, the dm_control tasks' `physics.render`, `hpg-mj
render`, Figure 12's videos) is drawn here instead: a `RenderWorker` starts
`python -m hpg_mj._render_worker` on the first frame, sends it what the scene
needs (the ship's state and wake, or the MuJoCo state arrays) and receives the
frame. The worker sets its own `MUJOCO_GL`, trying EGL, then OSMesa (or only
the backend the user's `MUJOCO_GL` names); the user's process maps no GL
library before, during or after rendering, and a crash of the renderer is an
exception in the user's process, not its end.

The worker is a fresh interpreter (`subprocess`), not a `multiprocessing`
spawn: spawn re-imports the user's `__main__` in the child, which re-runs a
script without a main guard and imports whatever it imports (torch).
"""
import os
import pathlib
import socket
import subprocess
import sys
import tempfile
import weakref
from multiprocessing import connection

# Tried in this order unless MUJOCO_GL names one of them (SPEC section 9).
BACKENDS = ("egl", "osmesa")
USER_BACKENDS = ("egl", "osmesa", "glfw")

# Seconds to wait for the worker to start (python, mujoco, a GL context) and for a frame.
START_TIMEOUT_S = 120.0
FRAME_TIMEOUT_S = 120.0

INSTALL_HINT = ("install OSMesa for software rendering (Debian/Ubuntu: `apt-get install "
                "libosmesa6`; conda: `conda install -c conda-forge mesalib`), or on a machine "
                "with an NVIDIA GPU its driver's EGL (`libegl1` and the driver); or pick one "
                "with MUJOCO_GL=egl|osmesa. Simulation and training need neither.")


class RenderingUnavailable(RuntimeError):
  """No OpenGL backend works for the worker; says what to install.

  `failures` holds one "backend: why" string per backend tried.
  """

  def __init__(self, message, failures=()):
    super().__init__(message)
    self.failures = list(failures)


class RenderWorkerError(RuntimeError):
  """The worker failed or died while drawing; the user's process is unaffected."""


def candidate_backends(environ=None):
  """The backends the worker tries, in order: MUJOCO_GL's if it names one, else EGL, OSMesa."""
  chosen = (os.environ if environ is None else environ).get("MUJOCO_GL", "").strip().lower()
  if chosen in USER_BACKENDS:
    return (chosen,)
  return BACKENDS


def _worker_environment(backend):
  env = dict(os.environ)
  env["MUJOCO_GL"] = backend
  env["PYOPENGL_PLATFORM"] = backend
  # The worker imports the same hpg_mj as this process, installed or not.
  package_parent = str(pathlib.Path(__file__).resolve().parents[2])
  env["PYTHONPATH"] = os.pathsep.join(p for p in (package_parent, env.get("PYTHONPATH")) if p)
  return env


def _shutdown(process, conn, log):
  try:
    conn.send(("close", None))
  except (OSError, ValueError):
    pass
  try:
    process.wait(timeout=5)
  except subprocess.TimeoutExpired:
    process.kill()
    process.wait()
  conn.close()
  log.close()


class RenderWorker:
  """A scene drawn in a worker process, started on the first `render` call.

  `scene` is "ship" (the ship at a state with its wake, `drawing.ShipDrawing`)
  or "physics" (a MuJoCo model at given state arrays, `drawing.PhysicsDrawing`);
  `options` are that scene's constructor arguments.
  """

  def __init__(self, scene, **options):
    self.scene = scene
    self.options = options
    self.backend = None     # "egl" or "osmesa" once started
    self.info = {}          # what the worker reported: backend, GL renderer, versions
    self._process = None
    self._conn = None
    self._finalizer = None

  @property
  def pid(self):
    """The worker's process id, or None before it started."""
    return None if self._process is None else self._process.pid

  def start(self, backends=None):
    """Starts the worker if it is not running; returns the backend it uses.

    `backends`: the ones to try, in order (default `candidate_backends()`).
    """
    if self._process is not None:
      return self.backend
    failures = []
    for backend in backends or candidate_backends():
      started = self._try_start(backend)
      if isinstance(started, str):
        failures.append(f"{backend}: {started}")
        continue
      self._process, self._conn, log, self.info = started
      self.backend = backend
      self._finalizer = weakref.finalize(self, _shutdown, self._process, self._conn, log)
      return backend
    raise RenderingUnavailable("hpg_mj cannot render: no OpenGL backend works here ("
                               + "; ".join(failures) + "). To render, " + INSTALL_HINT,
                               failures)

  def _try_start(self, backend):
    """(process, connection, log, info) on success, else the reason as a string."""
    ours, theirs = socket.socketpair()
    log = tempfile.TemporaryFile()
    try:   # -P: not the working directory's hpg_mj, the one PYTHONPATH names
      process = subprocess.Popen(
          [sys.executable, "-P", "-m", "hpg_mj._render_worker", str(theirs.fileno())],
          pass_fds=[theirs.fileno()], env=_worker_environment(backend),
          stdin=subprocess.DEVNULL, stdout=log, stderr=log)
    except OSError as err:
      ours.close()
      log.close()
      return f"could not start {sys.executable}: {err}"
    finally:
      theirs.close()
    conn = connection.Connection(ours.detach())
    try:
      conn.send(("open", (self.scene, self.options)))
      if not conn.poll(START_TIMEOUT_S):
        raise TimeoutError(f"no answer in {START_TIMEOUT_S:.0f} s")
      kind, payload = conn.recv()
    except (OSError, EOFError, TimeoutError) as err:
      kind, payload = "error", f"the worker stopped ({err})"
    if kind == "ready":
      return process, conn, log, payload
    conn.close()
    if process.poll() is None:
      process.kill()
    died = process.wait() != 1   # 1: the worker reported why it cannot render
    reason = f"{payload}{_log_tail(log) if died else ''}"
    log.close()
    return reason

  def render(self, **request):
    """Draws one frame; returns it as a (height, width, 3) uint8 array."""
    self.start()
    try:
      self._conn.send(("render", request))
      if not self._conn.poll(FRAME_TIMEOUT_S):
        raise TimeoutError(f"no frame in {FRAME_TIMEOUT_S:.0f} s")
      kind, payload = self._conn.recv()
    except (OSError, EOFError, TimeoutError) as err:
      backend = self.backend
      try:
        code = self._process.wait(timeout=5)   # how it ended, for the message
      except subprocess.TimeoutExpired:
        code = "none yet: still running"
      self.close()
      raise RenderWorkerError(f"the {backend} render worker failed ({err}; exit code "
                              f"{code}); this process is unaffected and the next render "
                              "starts a new worker") from None
    if kind == "error":
      raise ValueError(payload)   # a bad request (an unknown camera, a wrong shape)
    return payload

  def close(self):
    """Stops the worker (a later `render` starts a new one)."""
    if self._finalizer is not None:
      self._finalizer()
    self._process = self._conn = self._finalizer = None
    self.backend = None


# What `render_physics` sends: the state a picture shows, and the model fields
# hpg_mj's worlds change at run time (the taxi's gauge and fuel pad, the ship's
# orthographic extents, the goal task's gate and its width).
PHYSICS_DATA_FIELDS = ("qpos", "qvel", "act", "mocap_pos", "mocap_quat")
PHYSICS_MODEL_FIELDS = ("geom_rgba", "geom_pos", "geom_quat", "geom_sameframe", "geom_size",
                        "geom_rbound", "cam_fovy")


def render_physics(physics, model_name, height=240, width=320, camera_id=-1, overlays=(),
                   depth=False, segmentation=False, scene_option=None,
                   render_flag_overrides=None, scene_callback=None):
  """dm_control's `Physics.render` for hpg_mj's worlds, drawn in a worker.

  An RGB frame of `physics` (built from `assets/<model_name>`) at its current
  state; the worker lives as long as `physics` (see `close_physics_worker`).
  Depth, segmentation, overlays, scene options and callbacks are not offered.
  """
  unsupported = [name for name, value in (
      ("overlays", overlays), ("depth", depth), ("segmentation", segmentation),
      ("scene_option", scene_option), ("render_flag_overrides", render_flag_overrides),
      ("scene_callback", scene_callback)) if value]
  if unsupported:
    raise ValueError(f"{model_name}: render() draws RGB frames in a worker process; "
                     f"{', '.join(unsupported)} {'is' if len(unsupported) == 1 else 'are'} "
                     "not supported (allowed: height, width, camera_id; the others left "
                     "at their defaults)")
  render_worker = physics.__dict__.get("_hpg_render_worker")
  if render_worker is None:
    render_worker = physics.__dict__["_hpg_render_worker"] = RenderWorker(
        "physics", model_name=model_name)
  model, data = physics.model.ptr, physics.data.ptr
  return render_worker.render(
      height=int(height), width=int(width), camera_id=camera_id,
      model_fields={name: getattr(model, name).copy() for name in PHYSICS_MODEL_FIELDS},
      data_fields={name: getattr(data, name).copy() for name in PHYSICS_DATA_FIELDS})


def close_physics_worker(physics):
  """Stops the render worker of `physics`, if it has one."""
  render_worker = physics.__dict__.pop("_hpg_render_worker", None)
  if render_worker is not None:
    render_worker.close()


def _log_tail(log, lines=6):
  log.seek(0)
  text = log.read().decode(errors="replace").strip().splitlines()[-lines:]
  return ("; worker output: " + " | ".join(text)) if text else ""


# --- the worker process -------------------------------------------------------

_LIBRARIES = {"egl": "libEGL", "osmesa": "libOSMesa", "glfw": "GLFW or a display"}

def _open_scene(scene, options):
  from hpg_mj.render import drawing
  if scene == "ship":
    return drawing.ShipDrawing(**options)
  if scene == "physics":
    return drawing.PhysicsDrawing(**options)
  raise ValueError(f"unknown scene {scene!r}; valid scenes: 'ship', 'physics'")


def _gl_strings():
  """The GL renderer and version of the current context (for `hpg-mj doctor`)."""
  try:
    from OpenGL import GL
    return {"gl_renderer": GL.glGetString(GL.GL_RENDERER).decode(),
            "gl_version": GL.glGetString(GL.GL_VERSION).decode()}
  except Exception:   # only a description; the frame is what counts
    return {"gl_renderer": "unknown", "gl_version": "unknown"}


def _serve(fd):
  conn = connection.Connection(fd)
  _, (scene_name, options) = conn.recv()
  try:
    # MuJoCo first, under the MUJOCO_GL this worker was started with, so that
    # mujoco.Renderer makes its contexts with that backend. Without the library,
    # PyOpenGL fails here (AttributeError: 'NoneType' object has no attribute ...).
    import mujoco
    scene = _open_scene(scene_name, options)
    scene.render_first()
  except Exception as err:   # reported to the parent, which tries the next backend
    library = _LIBRARIES.get(os.environ["MUJOCO_GL"], "its library")
    conn.send(("error", f"{type(err).__name__}: {err} ({library} is missing or does not work)"))
    return 1
  conn.send(("ready", {"backend": os.environ["MUJOCO_GL"], "mujoco": mujoco.__version__,
                       **_gl_strings()}))
  while True:
    try:
      kind, request = conn.recv()
    except EOFError:   # the parent went away
      return 0
    if kind == "close":
      scene.close()
      return 0
    try:
      frame = scene.render(**request)
    except (ValueError, TypeError) as err:
      conn.send(("error", str(err)))
      continue
    conn.send(("frame", frame))


if __name__ == "__main__":
  sys.exit(_serve(int(sys.argv[1])))
