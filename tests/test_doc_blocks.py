"""Every Python block of the README, of the documentation's pages and of the
docstrings the task pages show runs as printed (issue 22): each file's blocks in
order, in one namespace, in a fresh folder. A block too long for the tests is
preceded by `<!-- test: OLD -> NEW -->` comments (docs/contributing.md), each of
which must replace text that is in its block. The README's blocks that a test of
their own runs and checks (RUN_ELSEWHERE) are not run twice."""
import pathlib
import re
import subprocess
import sys
import tempfile

import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "docs" / "_ext"))
import task_pages  # noqa: E402  (docs/_ext: the docstrings the task pages render)

_BLOCK = re.compile(r"((?:^<!-- test: .*? -> .*? -->\n)*)^```python\n(.*?)^```", re.M | re.S)
_REDUCE = re.compile(r"^<!-- test: (.*?) -> (.*?) -->$", re.M)


def blocks(text):
  """The Python blocks of a Markdown text, each with its test replacements applied."""
  found = []
  for reductions, code in _BLOCK.findall(text):
    for old, new in _REDUCE.findall(reductions):
      assert old in code, f"<!-- test: {old} -> ... --> replaces nothing in:\n{code}"
      code = code.replace(old, new)
    found.append(code)
  return found


# README section -> the test file that runs its block and checks what it prints.
RUN_ELSEWHERE = {"Write your own agent": "tests/agents/test_user_agents.py",
                 "Write your own hierarchy": "tests/agents/test_user_agents.py",
                 "Score your own policy": "tests/test_benchmark.py"}


def _readme():
  """The README less the sections whose blocks RUN_ELSEWHERE's tests run."""
  sections = re.split(r"^(?=## )", (REPO / "README.md").read_text(), flags=re.M)
  return "".join(s for s in sections if s.split("\n", 1)[0][3:] not in RUN_ELSEWHERE)


# Pages whose blocks import JAX: run by tests/jax/test_jax_doc_blocks.py in the JAX
# tests' own process (a worker that had imported JAX would then fork the runs'
# process pools, which may deadlock).
JAX_PAGES = ("jax.md",)


def _sources():
  pages = sorted(p for p in (REPO / "docs").glob("*.md") if p.name not in JAX_PAGES)
  sources = {"README.md": _readme()}
  sources.update({f"docs/{p.name}": p.read_text() for p in pages})
  # Indented in a docstring; dedented by inspect.getdoc.
  sources.update({f"docstring of {name}": doc for name, doc in task_pages.manuals()})
  return {name: text for name, text in sources.items() if blocks(text)}


SOURCES = _sources()


def test_the_pages_with_examples_are_found():
  assert {"README.md", "docs/getting_started.md"} <= set(SOURCES)
  assert any(name.startswith("docstring of") for name in SOURCES)


@pytest.mark.parametrize("heading", sorted(RUN_ELSEWHERE))
def test_the_blocks_run_elsewhere_are_run_there(heading):
  readme = (REPO / "README.md").read_text()
  assert f"## {heading}\n" in readme and blocks(readme.split(f"## {heading}\n", 1)[1])
  assert heading in (REPO / RUN_ELSEWHERE[heading]).read_text()


@pytest.mark.parametrize("name", sorted(SOURCES))
def test_every_python_block_runs(name, tmp_path, monkeypatch):
  monkeypatch.chdir(tmp_path)
  # A user's own SB3 model (getting_started's blocks) makes a log folder in the
  # temporary directory at each `learn`: kept in this test's folder.
  monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
  namespace = {"__name__": "doc_block"}
  for k, code in enumerate(blocks(SOURCES[name])):
    exec(compile(code, f"{name}, Python block {k + 1}", "exec"), namespace)


def test_the_front_pages_block_runs_in_a_fresh_interpreter(tmp_path):
  """As a newcomer pastes it: run beside the other pages, their imports had hidden that
  `hpg_mj.benchmark` was no attribute of the package until something imported it."""
  code = "".join(blocks((REPO / "docs" / "index.md").read_text()))
  done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                        text=True, timeout=600)
  assert done.returncode == 0, done.stderr[-3000:]
  assert "'gate_pass_rate'" in done.stdout


def test_a_reduction_that_replaces_nothing_is_refused():
  text = "<!-- test: 100_000 -> 10 -->\n```python\nx = 5\n```\n"
  with pytest.raises(AssertionError, match="replaces nothing"):
    blocks(text)
  assert blocks("<!-- test: 5 -> 6 -->\n```python\nx = 5\n```\n") == ["x = 6\n"]
