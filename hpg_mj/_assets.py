"""Where the MJCF models are read from.

An installed hpg_mj carries `assets/` inside the wheel as the `hpg_mj.assets`
package; a source checkout that was not installed reads the top-level folder.
"""
import pathlib

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
