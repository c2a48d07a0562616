"""Where the MJCF models are read from.

An installed hpg_mj carries `assets/` inside the wheel as the `hpg_mj.assets`
package; a source checkout that was not installed reads the top-level folder.
"""
import functools
import numbers
import pathlib
import re

_PACKAGED_ASSETS = pathlib.Path(__file__).resolve().parent / "assets"
_SOURCE_ASSETS = pathlib.Path(__file__).resolve().parents[1] / "assets"


def assets_dir() -> pathlib.Path:
  """The folder holding the MJCF models this hpg_mj uses."""
  for path in (_PACKAGED_ASSETS, _SOURCE_ASSETS):
    if path.is_dir():
      return path
  raise FileNotFoundError(
      "hpg_mj's MJCF assets are missing: neither the installed package folder "
      f"{_PACKAGED_ASSETS} nor the checkout's {_SOURCE_ASSETS} exists; "
      "reinstall with `pip install .`")


def read_model(name: str) -> str:
  """Returns the text of `assets/<name>` (for example `ship.xml`)."""
  path = assets_dir() / name
  if not path.is_file():
    available = sorted(p.name for p in assets_dir().glob("*.xml"))
    raise FileNotFoundError(f"no MJCF model {name!r} in {assets_dir()}; available: {available}")
  return path.read_text()


def included_assets(name: str) -> dict:
  """The files `assets/<name>` includes (`<include file="...">`, and theirs), as MuJoCo's
  `from_xml_string` takes them: {file name: bytes}; empty for a model that includes
  nothing. A model read from its text (`read_model`) finds them only here."""
  found, todo = {}, [name]
  while todo:
    for included in re.findall(r'<include\s+file="([^"]+)"', read_model(todo.pop())):
      if included not in found:
        found[included] = read_model(included).encode()
        todo.append(included)
  return found


def load_model(name: str):
  """The compiled `mujoco.MjModel` of `assets/<name>`, with the files it includes."""
  import mujoco
  return mujoco.MjModel.from_xml_string(read_model(name), included_assets(name))


@functools.lru_cache(maxsize=None)
def offscreen_buffer(name: str) -> tuple:
  """(width, height): the largest frame in pixels MuJoCo can draw of `assets/<name>`,
  its offscreen buffer (`<visual><global offwidth offheight>`, read from the
  compiled model, so MuJoCo's own default where the file says nothing)."""
  model = load_model(name)
  return int(model.vis.global_.offwidth), int(model.vis.global_.offheight)


def check_frame_size(name: str, width, height, who=None, options=("width", "height")):
  """Refuses a frame of `width` x `height` pixels that `assets/<name>`'s offscreen
  buffer cannot hold, before anything is drawn (MuJoCo's own refusal comes from the
  render worker, after it has tried every OpenGL backend, and reads as a missing
  library); `who` begins the message, and `options` name the two sizes, as the
  caller's user knows them."""
  who = f"{who}: " if who else ""
  for option, value, limit, attribute in zip(options, (width, height), offscreen_buffer(name),
                                             ("offwidth", "offheight")):
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
      raise ValueError(f"{who}{option} must be a positive integer number of pixels, "
                       f"got {value!r}")
    if value > limit:
      raise ValueError(f"{who}{option} {value} is more than the {name} model's offscreen "
                       f"buffer holds (its <visual><global {attribute}>); allowed: at most "
                       f"{limit} pixels")
