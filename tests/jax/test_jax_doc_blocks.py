"""The Python blocks of the pages about JAX (test_doc_blocks.JAX_PAGES) run as
printed, here in the JAX tests' own process."""
import pathlib
import sys

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests"))
import test_doc_blocks  # noqa: E402


@pytest.mark.parametrize("page", test_doc_blocks.JAX_PAGES)
def test_every_python_block_of_the_jax_pages_runs(page, tmp_path, monkeypatch):
  monkeypatch.chdir(tmp_path)
  code = test_doc_blocks.blocks((REPO / "docs" / page).read_text())
  assert code
  namespace = {"__name__": "doc_block"}
  for k, block in enumerate(code):
    exec(compile(block, f"docs/{page}, Python block {k + 1}", "exec"), namespace)
