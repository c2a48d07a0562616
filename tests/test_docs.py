"""A clone explains itself: the specification the code cites is docs/SPEC.md, a
file of the repository; no tracked file points outside it; every cited section and
every deviation the results name exists there; the README's links lead somewhere."""
import pathlib
import re
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]
SPEC = REPO / "docs" / "SPEC.md"


def _tracked_text_files():
  try:
    names = subprocess.run(["git", "-C", str(REPO), "ls-files"], capture_output=True, text=True,
                           check=True).stdout.split()
  except (OSError, subprocess.CalledProcessError):
    pytest.skip("not a git checkout")
  for name in names:
    path = REPO / name
    if path.suffix in (".py", ".md", ".toml", ".sh", ".txt", ".xml", ".cfg") and path.is_file():
      yield name, path.read_text()


def _sections():
  return {int(n) for n in re.findall(r"^## (\d+)\. ", SPEC.read_text(), flags=re.M)}


def test_no_tracked_file_points_outside_the_repository():
  shared, work = ".." + "/shared", "/" + "work/"     # (not literal: this file is tracked)
  outside = [name for name, text in _tracked_text_files() if shared in text or work in text]
  assert outside == []


def test_every_cited_spec_section_exists():
  sections = _sections()
  assert sections == set(range(1, 12))
  cited = {}
  for name, text in _tracked_text_files():
    for first, last in re.findall(r"SPEC\s+sections?\s+(\d+)(?:\s*-\s*(\d+))?", text):
      for n in range(int(first), int(last or first) + 1):
        cited.setdefault(n, []).append(name)
  assert cited, "no citation found: the pattern is wrong"
  missing = {n: files for n, files in cited.items() if n not in sections}
  assert missing == {}


def test_every_deviation_the_results_name_is_specified():
  spec = SPEC.read_text()
  declared = set(re.findall(r"^\| (D\d+) \|", spec, flags=re.M))
  assert declared == {f"D{k}" for k in range(1, len(declared) + 1)} and len(declared) >= 7
  results = (REPO / "docs" / "results.md").read_text()      # the README's results, in full
  named = set(re.findall(r"\b(D\d)\b", results))
  assert named == declared
  anchors = {re.sub(r"[^a-z0-9 -]", "", h.lower()).replace(" ", "-")
             for h in re.findall(r"^## (.+)$", spec, flags=re.M)}
  for page, prefix in (("README.md", "docs/"), ("docs/results.md", "")):
    for link in re.findall(rf"\]\(({prefix}SPEC\.md[^)]*)\)", (REPO / page).read_text()):
      assert (REPO / page).parent.joinpath(link.split("#")[0]).is_file(), (page, link)
      if "#" in link:          # GitHub's anchor of the heading it names
        assert link.split("#")[1] in anchors, (page, link)


def test_every_relative_link_of_the_readme_exists():
  readme = (REPO / "README.md").read_text()
  links = [link.split("#")[0] for link in re.findall(r"\]\(([^)]+)\)", readme)
           if "://" not in link]
  assert links and [link for link in links if not (REPO / link).exists()] == []


def _pages():
  """Every documentation page's source: docs/*.md, the README, and the files they
  include (the committed reports)."""
  pages = {}
  for path in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]:
    text = path.read_text()
    pages[path.relative_to(REPO).as_posix()] = text
    for included in re.findall(r"^```\{include\} (\S+)", text, flags=re.M):
      target = (path.parent / included).resolve()
      pages[target.relative_to(REPO).as_posix()] = target.read_text()
  return pages


# "issue 24", "issues 3 and 4", "issue #644", "Issue no. 7" (tests/test_api_docstrings.py
# holds the docstrings the site shows to the same rule).
TRACKER_NUMBER = r"(?i)\bissues?\s*(?:no\.?\s*)?#?\s*\d+[^.;,)]*"


def test_no_page_says_a_tracker_number_for_the_thing_itself():
  """A reader has no tracker: "issue 24" tells them nothing that "the unseen seeds
  that had shown the failure" does not. An outside project's report is cited as a
  link the reader can follow ([mujoco#644](https://github.com/...)), not as
  "issue #644"."""
  pages = _pages()
  assert "figures/REPORT.md" in pages and "docs/changelog.md" in pages
  found = {name: re.findall(TRACKER_NUMBER, text) for name, text in pages.items()}
  assert {name: hits for name, hits in found.items() if hits} == {}


def test_the_experiments_page_names_every_figure_kind_and_its_keys():
  from hpg_mj.experiments import figures
  from hpg_mj.experiments import runner
  page = (REPO / "docs" / "experiments.md").read_text()
  table = page.split("each kind has keys of its\nown:", 1)[1].split("\n\n", 2)[1]
  rows = {line.split("|")[1].strip(" `"): line for line in table.splitlines()
          if line.startswith("| `")}
  assert set(rows) == set(runner.FIGURE_KINDS)
  for kind, (required, optional) in runner.FIGURE_KINDS.items():
    for key in [*required, *optional]:
      assert f"`{key}`" in rows[kind], (kind, key)
  for metric in figures.METRICS:
    assert metric in rows["curve"], metric
  for metric in {m for ms in figures.GREEDY_METRICS.values() for m in ms if
                 not m.endswith("_normalized")}:
    assert metric in rows["greedy_curve"], metric
