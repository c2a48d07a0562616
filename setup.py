"""Writes the commit the wheel is built from into it (hpg_mj/_build.json), so that
an installed hpg_mj records the code of every result (`hpg_mj.provenance`).
Everything else is in pyproject.toml."""
import json
import pathlib
import subprocess

from setuptools import setup
from setuptools.command.build_py import build_py


def _git_commit(folder):
  try:
    head = subprocess.run(["git", "-C", str(folder), "rev-parse", "HEAD"], capture_output=True,
                          text=True, timeout=10)
    status = subprocess.run(["git", "-C", str(folder), "status", "--porcelain",
                             "--untracked-files=no"], capture_output=True, text=True, timeout=10)
  except (OSError, subprocess.SubprocessError):
    return "unknown"
  if head.returncode != 0:
    return "unknown"
  return head.stdout.strip() + ("-dirty" if status.stdout.strip() else "")


class BuildPyWithCommit(build_py):
  def run(self):
    super().run()
    target = pathlib.Path(self.build_lib) / "hpg_mj" / "_build.json"
    target.write_text(json.dumps({"git_commit": _git_commit(pathlib.Path(__file__).parent)}) + "\n")


setup(cmdclass={"build_py": BuildPyWithCommit})
