"""The command line's argument types, each refusing a bad value in one line naming
what is allowed (argparse prints it with the option's name), and its parser."""
import argparse
import math


def _seed(text):
  """An argparse type: a seed the agents' generator takes (0..rng.MAX_SEED)."""
  from hpg_mj.learners import rng
  value = _at_least(0)(text)
  if value > rng.MAX_SEED:
    raise argparse.ArgumentTypeError(f"{value} is out of range; allowed: 0..{rng.MAX_SEED} "
                                     f"(the generator keeps a seed's low 64 bits)")
  return value


def _positive_seconds(text):
  """An argparse type: a positive finite number of seconds."""
  import math
  try:
    value = float(text)
  except ValueError:
    raise argparse.ArgumentTypeError(f"{text!r} is not a number; allowed: seconds > 0") from None
  if not (math.isfinite(value) and value > 0):
    raise argparse.ArgumentTypeError(f"{text!r} is out of range; allowed: seconds > 0")
  return value


def _at_least(low):
  """An argparse type: an integer >= low, refused in the words of task-file ranges."""
  def convert(text):
    try:
      value = int(text)
    except ValueError:
      raise argparse.ArgumentTypeError(f"{text!r} is not an integer; allowed: >= {low}") from None
    if value < low:
      raise argparse.ArgumentTypeError(f"{value} is out of range; allowed: >= {low}")
    return value
  convert.__name__ = f"integer >= {low}"
  return convert


class _Parser(argparse.ArgumentParser):
  """Refuses a bad option in one line, naming it and what is allowed,
  instead of argparse's usage block."""

  def error(self, message):
    self.exit(2, f"{self.prog}: error: {' '.join(message.split())} (see {self.prog} --help)\n")


def _render_policy(text):
  """An argparse type: `hpg-mj render --policy`, scripted, random or module:name (the
  user's, loaded when the video is made)."""
  if text in ("scripted", "random") or (":" in text and text.rsplit(":", 1)[1]):
    return text
  raise argparse.ArgumentTypeError(f"{text!r}: give scripted, random, or your own policy as "
                                   "module:name or path/file.py:name")
