"""SPEC section 9: no OpenGL library in the user's process, rendering or not.

Each check runs in a fresh interpreter, because what a process has mapped
(`/proc/self/maps`) and imported cannot be undone inside pytest's own.
"""
import json
import os
import subprocess
import sys
import textwrap

import pytest

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="reads /proc/self/maps")

_REPORT = """
import json, os, sys
from hpg_mj import _headless
print("REPORT " + json.dumps({
    "gl": _headless.mapped_gl_libraries(),
    "modules": sorted(m for m in ("mujoco", "dm_control") if m in sys.modules),
    "environ_changed": sorted(k for k in set(os.environ) | set(BEFORE)
                              if os.environ.get(k) != BEFORE.get(k)),
    **RESULT}))
"""


def _run(body, mujoco_gl=None, extra_env=None):
  """Runs `body` in a fresh interpreter; returns the dict it reports."""
  env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
  if mujoco_gl is not None:
    env["MUJOCO_GL"] = mujoco_gl
  env.update(extra_env or {})
  # Gymnasium sets PYGAME_HIDE_SUPPORT_PROMPT when imported; hpg_mj must set nothing more.
  script = ("import os, gymnasium\nBEFORE = dict(os.environ)\nRESULT = {}\n"
            + textwrap.dedent(body) + _REPORT)
  # -P: the checkout (the working directory) stays off sys.path; the installed hpg_mj runs.
  done = subprocess.run([sys.executable, "-P", "-c", script], env=env, capture_output=True,
                        text=True, timeout=600)
  assert done.returncode == 0, done.stderr[-3000:]
  line = [l for l in done.stdout.splitlines() if l.startswith("REPORT ")][-1]
  return json.loads(line[len("REPORT "):])


_SIMULATE_EVERYTHING = """
import gymnasium, numpy as np
import hpg_mj
from hpg_mj import suite
for env_id in hpg_mj.envs.ENV_IDS:
  backends = ["analytic", "mujoco"] if "Ship" in env_id else [None]
  for backend in backends:
    env = gymnasium.make(env_id, **({} if backend is None else {"backend": backend}))
    env.reset(seed=0)
    for _ in range(5):
      env.step(env.action_space.sample())
    env.close()
for domain, task in suite.ALL_TASKS:
  env = suite.load(domain, task, {"random": 0})
  env.reset()
  spec = env.action_spec()
  for _ in range(5):
    env.step(np.zeros(spec.shape) if domain == "ship" else 0)
from hpg_mj import cli
for name in ("ship_hybrid", "taxi_fuel_hpg"):
  out = os.path.join(TMP, name)
  assert cli.main(["train", name, "--episodes", "2", "--backend", "mujoco", "--out", out,
                   "--quiet", "--json"]) == 0
  assert cli.main(["evaluate", out, "--episodes", "2", "--backend", "mujoco", "--json"]) == 0
"""


@pytest.mark.parametrize("mujoco_gl", [None, "osmesa"])
def test_simulating_training_and_evaluating_map_no_gl(tmp_path, mujoco_gl):
  # Every Gymnasium id (both ship backends), every dm_control task, training and
  # evaluating on MuJoCo: no GL library, and the user's MUJOCO_GL (even one that
  # names OSMesa) is left as it was.
  report = _run(f"TMP = {str(tmp_path)!r}\n" + _SIMULATE_EVERYTHING, mujoco_gl=mujoco_gl)
  assert report["gl"] == []
  assert report["modules"] == ["dm_control", "mujoco"]     # they were used, without GL
  assert report["environ_changed"] == []


def test_the_analytic_ship_imports_neither_mujoco_nor_dm_control(tmp_path):
  report = _run("""
    import gymnasium, numpy as np
    import hpg_mj
    for env_id in ("hpg_mj/ShipSteering-v0", "hpg_mj/ShipSteeringDiagonal-v0",
                   "hpg_mj/ShipSteeringStraight-v0", "hpg_mj/TaxiFuel-v0", "hpg_mj/Taxi-v0"):
      env = gymnasium.make(env_id, **({"backend": "analytic"} if "Ship" in env_id else {}))
      env.reset(seed=0)
      for _ in range(5):
        env.step(env.action_space.sample())
    from hpg_mj import cli
    assert cli.main(["train", "ship_hybrid", "--episodes", "2", "--out", TMP, "--quiet"]) == 0
  """.replace("TMP", repr(str(tmp_path))))
  assert report["modules"] == []
  assert report["gl"] == []


_RENDER_EVERYTHING = """
import gymnasium, numpy as np
import hpg_mj
from hpg_mj import suite
frames, workers = [], []
for env_id, kwargs in (("hpg_mj/ShipSteering-v0", {"backend": "analytic"}),
                       ("hpg_mj/ShipSteeringDiagonal-v0", {"backend": "mujoco"}),
                       ("hpg_mj/TaxiFuel-v0", {})):
  env = gymnasium.make(env_id, render_mode="rgb_array", width=96, height=80, **kwargs)
  env.reset(seed=0)
  env.step(env.action_space.sample())
  frames.append(env.render())
  inner = env.unwrapped
  worker = inner._renderer._worker if hasattr(inner, "_renderer") else (
      inner._physics.__dict__["_hpg_render_worker"])
  with open(f"/proc/{worker.pid}/maps") as maps:
    workers.append({"backend": worker.backend, "pid": worker.pid,
                    "gl": [l for l in maps if "libEGL" in l or "libOSMesa" in l] != []})
  env.close()
physics = suite.load("ship", "steer", {"random": 0}).physics
frames.append(physics.render(64, 48, camera_id="top"))
physics.free()
RESULT = {"workers": workers, "own_pid": os.getpid(),
          "frames": [[list(f.shape), str(f.dtype), float(f.std())] for f in frames]}
"""


@pytest.mark.parametrize("mujoco_gl", [None, "osmesa"])
def test_rendering_draws_in_a_worker_and_maps_no_gl_here(mujoco_gl):
  report = _run(_RENDER_EVERYTHING, mujoco_gl=mujoco_gl)
  assert report["gl"] == []                 # torch may be imported after this
  assert report["environ_changed"] == []
  assert report["modules"] == ["dm_control", "mujoco"]
  expected = ["egl", "osmesa"] if mujoco_gl is None else [mujoco_gl]
  for worker in report["workers"]:
    assert worker["pid"] != report["own_pid"]
    assert worker["backend"] in expected
    assert worker["gl"]                     # the GL library is in the worker instead
  shapes = [(shape, dtype) for shape, dtype, _ in report["frames"]]
  assert shapes == [([80, 96, 3], "uint8")] * 3 + [([64, 48, 3], "uint8")]   # height, width
  assert all(std > 5.0 for _, _, std in report["frames"])   # drawn, not blank


def test_a_crashing_renderer_is_an_error_not_the_end_of_the_process():
  report = _run("""
    import signal, gymnasium
    import hpg_mj
    from hpg_mj import _render_worker as worker
    env = gymnasium.make("hpg_mj/Taxi-v0", render_mode="rgb_array", width=32, height=32)
    env.reset(seed=0)
    env.render()
    first = env.unwrapped._physics.__dict__["_hpg_render_worker"]
    pid = first.pid
    os.kill(pid, signal.SIGSEGV)
    try:
      env.render()
      RESULT["error"] = None
    except worker.RenderWorkerError as err:
      RESULT["error"] = str(err)
    RESULT["again"] = list(env.render().shape)       # a new worker
    RESULT["new_pid"] = first.pid != pid
  """)
  error = report["error"]
  assert error is not None and "render worker failed" in error and "exit code -11" in error
  assert "this process is unaffected" in error and "None render worker" not in error
  assert report["again"] == [32, 32, 3] and report["new_pid"]
  assert report["gl"] == []


_HIDE_GL = """
import ctypes
_open = ctypes.CDLL.__init__
def _hidden(self, name, *args, **kwargs):
  if name is not None and ("EGL" in str(name) or "OSMesa" in str(name)):
    raise OSError(f"{name}: cannot open shared object file (hidden by the test)")
  _open(self, name, *args, **kwargs)
ctypes.CDLL.__init__ = _hidden
"""


def test_without_egl_and_osmesa_only_rendering_fails_and_names_the_package(tmp_path):
  # A sitecustomize hides libEGL and libOSMesa from every interpreter started
  # here, the render worker's included: a machine without them.
  (tmp_path / "sitecustomize.py").write_text(_HIDE_GL)
  report = _run("""
    import gymnasium, numpy as np
    import hpg_mj
    from hpg_mj import _render_worker as worker
    env = gymnasium.make("hpg_mj/ShipSteering-v0", render_mode="rgb_array", width=32, height=32)
    env.reset(seed=0)
    for _ in range(3):
      env.step(np.array([5.0]))                        # simulation works
    try:
      env.render()
      RESULT["error"] = None
    except worker.RenderingUnavailable as err:
      RESULT["error"] = str(err)
    RESULT["after"] = env.step(np.array([5.0]))[0].tolist()   # and still works
  """, extra_env={"PYTHONPATH": str(tmp_path)})
  error = report["error"]
  assert error is not None and "egl:" in error and "osmesa:" in error
  assert "apt-get install libosmesa6" in error
  assert len(report["after"]) == 4
  assert report["gl"] == []
