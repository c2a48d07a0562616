"""What a user's files and options may name on disk, checked before anything is
written.

Names read from a file that become a folder or file name under `--out` (an
experiment's name, a figure's name, a task file's name in an experiment) are one
path component of a small alphabet, so that a file from elsewhere writes only
inside the output folder. Output paths are checked before any work: a file where
a folder is wanted, a folder where a file is, a place that cannot be written
(`hpg_mj.storage.check_out` adds what an agent's folder may hold).
"""
import pathlib
import re
import tempfile

NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}\Z")
NAME_ALLOWED = ("one folder or file name of 1-100 letters, digits, '_', '-' and '.', not "
                "starting with '.' or '-'")


def check_name(value, where, error=ValueError):
  """`value` if it is safe as one path component under --out; `where` names the
  file and key in the error (e.g. "fig.toml: [experiment] name"), `error` its class."""
  if not isinstance(value, str) or not NAME.match(value):
    raise error(f"{where} = {value!r} becomes a path under --out; allowed: "
                        f"{NAME_ALLOWED}")
  return value


def read_text(path, what, error=ValueError):
  """The UTF-8 text of a user's file (`what`: "task file", "experiment file"), or
  `error` naming the file."""
  path = pathlib.Path(path)
  try:
    data = path.read_bytes()
  except OSError as err:
    raise error(f"{path}: cannot read the {what}: {err.strerror or err}") from None
  try:
    return data.decode("utf-8")
  except UnicodeDecodeError as err:
    raise error(f"{path}: the {what} is not UTF-8 text (byte {data[err.start]:#04x} "
                        f"at offset {err.start}); a {what} is TOML, which is UTF-8") from None


class OutputRefused(ValueError):
  """An output path that would replace or mix into what the user has there."""


def check_above(out, start, option):
  """Refuses `out` when the nearest existing path at or above `start` is a file or
  cannot be written (folders that do not exist yet are made later)."""
  for above in [start, *start.parents]:
    if above.exists():
      if not above.is_dir():
        raise OutputRefused(f"{option} {out}: {above} is a file, not a folder")
      try:                                 # os.access says yes to root, even on /proc
        tempfile.TemporaryFile(dir=above).close()
      except OSError as err:
        raise OutputRefused(f"{option} {out}: {above} cannot be written here "
                            f"({err.strerror or err})") from None
      return


def check_folder_out(out, option="--out"):
  """Refuses an output folder that is a file, or below a file, or not writable."""
  out = pathlib.Path(out)
  check_above(out, out, option)


def check_file_out(out, option, suffixes=None):
  """Refuses an output file that is a folder, whose folder is a file or cannot be
  written, or (with `suffixes`) whose suffix is not one of them; before any work."""
  out = pathlib.Path(out)
  if suffixes and out.suffix.lower() not in suffixes:
    raise OutputRefused(f"{option} {out}: allowed suffixes: {', '.join(suffixes)}")
  if out.is_dir():
    raise OutputRefused(f"{option} {out} is a folder; give a file name")
  if out.exists():
    try:
      open(out, "ab").close()             # opened to append, nothing written
    except OSError as err:
      raise OutputRefused(f"{option} {out} cannot be written here ({err.strerror or err})") \
          from None
  check_above(out, out.parent, option)
