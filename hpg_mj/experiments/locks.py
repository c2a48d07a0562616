"""Run folders are locked while a process writes them, so that two commands on one
output folder (two `hpg-mj run` started at once, a Ray job resubmitted onto a
shared folder) never write or resume the same run together.

The lock is `fcntl.flock` on `<folder>/run.lock`, held for as long as the run
is being trained or finished. The kernel releases it when its holder dies, by
any signal, SIGKILL included: a lock left by a killed process never blocks the
next command. The file holds who holds it (pid, host, command, since when), to
be named in the message of the command that finds it held. It is never deleted:
deleting a lock file while another process waits on it would let a third one
lock a new file of the same name beside them. On a cluster the folder must be
on a POSIX file system that supports flock across machines (NFS v4, Lustre,
CephFS, GPFS do; Linux maps flock to NFS byte-range locks).
"""
import contextlib
import fcntl
import json
import os
import pathlib
import socket
import sys
import time

LOCK_FILE = "run.lock"


class RunLocked(ValueError):
  """The run is held by another process and the caller would not wait for it."""


def command_line():
  """This process's command, for the lock file (`hpg-mj run fig6 --out runs`)."""
  argv = list(sys.argv)
  if argv and argv[0].endswith(("cli.py", "__main__.py", "hpg-mj")):
    argv[0] = "hpg-mj"
  return " ".join(argv)


def describe_holder(path):
  """Who holds the lock at `path`, in words (from what it wrote there)."""
  try:
    holder = json.loads(path.read_text() or "{}")
  except (OSError, ValueError):
    holder = {}
  if not holder:
    return "another process (it has not written its name yet)"
  return (f"pid {holder.get('pid')} on {holder.get('host')} since {holder.get('since')} "
          f"({holder.get('command')!r})")


def holder_if_locked(folder):
  """Who holds `folder`'s lock, in words, or None when it is free (a probe: it
  takes a shared lock for an instant, never the exclusive one)."""
  path = pathlib.Path(folder) / LOCK_FILE
  if not path.is_file():
    return None
  fd = os.open(path, os.O_RDONLY)
  try:
    try:
      fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
      return describe_holder(path)
    fcntl.flock(fd, fcntl.LOCK_UN)
    return None
  finally:
    os.close(fd)


# A refusing caller retries this long: a probe (`holder_if_locked`) holds a shared
# lock for microseconds, and must not make a real run refuse.
_PROBE_GRACE_S = 2.0


@contextlib.contextmanager
def hold(folder, wait=True, command=None, on_wait=None, what="run"):
  """Holds `folder`'s lock for the `with` block.

  Held elsewhere: with `wait`, calls `on_wait(message)` (default: prints it on
  stderr) and blocks until it is free; without, raises RunLocked with a message
  that names the folder and its holder.
  """
  folder = pathlib.Path(folder)
  folder.mkdir(parents=True, exist_ok=True)
  path = folder / LOCK_FILE
  fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
  try:
    deadline = time.monotonic() + _PROBE_GRACE_S
    while True:
      try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        break
      except BlockingIOError:
        if time.monotonic() < deadline:
          time.sleep(0.05)
          continue
      message = f"{what} {folder} is held by {describe_holder(path)}"
      if not wait:
        raise RunLocked(f"{message}; it was left alone (wait for that command to finish, or "
                        f"run again without --no-wait to wait for it)")
      (on_wait or (lambda m: print(m, file=sys.stderr, flush=True)))(
          f"{message}; waiting for it")
      fcntl.flock(fd, fcntl.LOCK_EX)
      break
    holder = {"pid": os.getpid(), "host": socket.gethostname(),
              "command": command or command_line(),
              "since": time.strftime("%Y-%m-%d %H:%M:%S")}
    os.ftruncate(fd, 0)
    os.pwrite(fd, (json.dumps(holder) + "\n").encode(), 0)
    yield
  finally:
    os.close(fd)            # releases the lock (the kernel does the same on any death)
