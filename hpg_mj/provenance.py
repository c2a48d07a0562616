"""What produced a result: recorded in every saved agent (`agent.json`), every
finished run (`metrics.json`) and every REPORT.md, so that a number can be traced
to the code and the libraries that made it, and a saved agent loaded by another
version says so.

The git commit is the one the installed wheel was built from (setup.py writes it
into `hpg_mj/_build.json`, with "-dirty" when the checkout had uncommitted
changes), or the checkout's own when hpg_mj is imported from a source tree;
"unknown" otherwise. Versions are read from the installed distributions'
metadata, so that recording them imports neither mujoco nor dm_control (SPEC
section 9).
"""
import functools
import hashlib
import json
import os
import pathlib
import platform
import subprocess
import warnings
from importlib import metadata

# The libraries whose versions can change a number; distribution name -> key.
LIBRARIES = {"numpy": "numpy", "numba": "numba", "mujoco": "mujoco",
             "dm-control": "dm_control", "gymnasium": "gymnasium"}
# The keys that say which code made a result (the rest say where and from what).
VERSION_KEYS = ("hpg_mj", "git_commit", "python") + tuple(LIBRARIES.values())


class VersionWarning(UserWarning):
  """A saved agent made by another version of hpg_mj or of a library."""


def git_commit(folder):
  """The commit checked out at `folder` ("-dirty" with uncommitted changes), or None."""
  try:
    head = subprocess.run(["git", "-C", str(folder), "rev-parse", "HEAD"], capture_output=True,
                          text=True, timeout=10)
    if head.returncode != 0:
      return None
    status = subprocess.run(["git", "-C", str(folder), "status", "--porcelain",
                             "--untracked-files=no"], capture_output=True, text=True, timeout=10)
  except (OSError, subprocess.SubprocessError):
    return None
  dirty = status.returncode == 0 and status.stdout.strip() != ""
  return head.stdout.strip() + ("-dirty" if dirty else "")


@functools.lru_cache(maxsize=1)
def _commit():
  here = pathlib.Path(__file__).resolve().parent
  try:
    return json.loads((here / "_build.json").read_text())["git_commit"]
  except (OSError, ValueError, KeyError):
    pass
  if (here.parent / "pyproject.toml").is_file():     # imported from a checkout
    return git_commit(here.parent) or "unknown"
  return "unknown"


def _version(distribution):
  try:
    return metadata.version(distribution)
  except metadata.PackageNotFoundError:
    return "not installed"


def versions():
  """hpg_mj's version and commit, Python's and the libraries' versions."""
  from hpg_mj import __version__
  found = {"hpg_mj": __version__, "git_commit": _commit(),
           "python": platform.python_version()}
  found.update({key: _version(dist) for dist, key in LIBRARIES.items()})
  return found


def sha256_text(text):
  """The SHA-256 of `text` (UTF-8), in hex."""
  return hashlib.sha256(text.encode()).hexdigest()


def collect(task_text=None, seed=None):
  """The provenance of a result made now from a task file's text and a seed."""
  record = versions()
  record.update({"task_file_sha256": None if task_text is None else sha256_text(task_text),
                 "seed": seed, "cores": os.cpu_count()})
  return record


def differences(recorded):
  """How `recorded` (a provenance dict, or None) differs from this installation, in
  words ("numba 0.60.0, here 0.68.1"); empty when it is the same."""
  if not isinstance(recorded, dict):
    return ["it records no versions (saved before hpg_mj recorded them)"]
  here = versions()
  return [_difference(key, recorded.get(key, "unrecorded"), here[key]) for key in VERSION_KEYS
          if recorded.get(key) != here[key]]


def _difference(key, then, now):
  """One difference in words; two commits that differ only in the checkout's
  uncommitted changes ("-dirty") say so."""
  if key == "git_commit" and isinstance(then, str) and isinstance(now, str) and \
      then.removesuffix("-dirty") == now.removesuffix("-dirty"):
    changes = "with" if now.endswith("-dirty") else "without"
    return (f"git_commit {then}, here the same commit {changes} uncommitted changes to "
            "the checkout's files")
  return f"{key} {then}, here {now}"


def warn_if_different(recorded, what):
  """A VersionWarning when `what` (e.g. a saved agent's folder) was made by
  another version; its numbers may not be reproduced here."""
  found = differences(recorded)
  if found:
    warnings.warn(f"{what} was made by another version: {'; '.join(found)}",
                  VersionWarning, stacklevel=3)


def markdown(record):
  """One line of REPORT.md."""
  libs = ", ".join(f"{key} {record.get(key)}" for key in VERSION_KEYS[2:])
  return (f"hpg_mj {record.get('hpg_mj')} (commit {record.get('git_commit')}), {libs}; "
          f"{record.get('cores')} cores")
