"""`hpg-mj doctor` reports what it found, and says what to do about each problem."""
import os
import subprocess
import sys

import pytest

from test_gl_isolation import _HIDE_GL

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="reads /proc/self/maps")


def _doctor(extra_env=None):
  env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
  env.update(extra_env or {})
  done = subprocess.run([sys.executable, "-P", "-m", "hpg_mj.cli", "doctor"], env=env,
                        capture_output=True, text=True, timeout=300)
  return done.returncode, done.stdout


def test_doctor_finds_a_renderer_and_no_gl_in_the_simulating_process():
  rc, out = _doctor()
  assert rc == 0, out
  assert "mujoco 3.17.0" in out and "dm-control 1.0.50" in out and "gymnasium 1.4.0" in out
  assert "GL in this process after simulating on MuJoCo: none" in out
  found = [line for line in out.splitlines() if "renderer found:" in line]
  assert len(found) == 1 and found[0].split("renderer found: ")[1].split()[0] in ("egl", "osmesa")
  assert "numba cache: writable" in out
  assert out.rstrip().endswith("no problems found")


def test_doctor_without_egl_and_osmesa_says_what_to_install(tmp_path):
  (tmp_path / "sitecustomize.py").write_text(_HIDE_GL)
  rc, out = _doctor({"PYTHONPATH": str(tmp_path)})
  assert rc == 1
  assert "renderer found: none" in out
  assert "renderer egl: " in out and "renderer osmesa: " in out
  assert "problem: no render backend works" in out
  assert "to do: install OSMesa" in out and "apt-get install libosmesa6" in out
  assert "GL in this process after simulating on MuJoCo: none" in out   # simulation unaffected
