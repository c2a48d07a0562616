"""The API reference's JAX entries (tests/test_api_docstrings.py's checks), here in
the JAX tests' own process: hpg_mj.jax's modules import JAX."""
import pathlib
import sys

REPO = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests"))
import test_api_docstrings as checks  # noqa: E402

REFERENCE = checks.entries([m for m in checks.api_pages.modules() if m.startswith(checks.JAX)])


def test_the_jax_reference_is_read_whole():
  assert len(REFERENCE) > 100 and "hpg_mj.jax.environment.Environment.step_env" in REFERENCE


def test_every_jax_entry_says_what_it_is():
  assert checks.lacking(REFERENCE) == []


def test_no_jax_docstring_cites_a_tracker_number():
  assert checks.tracker_numbers(REFERENCE) == {}


def test_every_example_in_a_jax_docstring_is_highlighted():
  assert checks.unhighlighted(REFERENCE) == {}
