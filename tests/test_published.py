"""What the README and the site publish is what the reports say: their results tables
are made from the reports (docs/_ext/published.py) and equal what the reports make
now; every interval a page quotes in its prose is one a report gives (to the page's
rounding), but those marked as history; the site shows each report once, under a
title of its own, and no two of the reports it shows disagree on a table."""
import pathlib
import re
import sys

import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]
if str(REPO / "docs" / "_ext") not in sys.path:
  sys.path.insert(0, str(REPO / "docs" / "_ext"))
import published  # noqa: E402  (docs/_ext: the tables made from the reports)

# Pages of history, whose numbers are those of their day.
HISTORY_PAGES = ("docs/changelog.md", "docs/tuning_history.md")
_HISTORY = re.compile(r"<!-- history:.*?-->.*?<!-- /history -->", re.S)
_INTERVAL = re.compile(r"([-+]?\d[\d,]*(?:\.\d+)?) \[([-+]?\d[\d,]*(?:\.\d+)?), "
                       r"([-+]?\d[\d,]*(?:\.\d+)?)\]")


def _reports():
  return sorted(REPO.glob("figures/**/REPORT.md"))


def test_every_published_table_is_made_from_its_report_as_it_is_now():
  assert published.stale() == [], "run `python docs/_ext/published.py`"
  parts = {name for page in published.pages()
           for name in re.findall(r"^<!-- published (\w+):", (REPO / page).read_text(), re.M)}
  assert parts == set(published.PARTS)


def test_a_report_that_changes_changes_the_page(monkeypatch):
  """The README's table follows its report: a changed number there is a stale page."""
  readme = (REPO / "README.md").read_text()
  real = published._read
  monkeypatch.setattr(published, "_read", lambda report: real(report).replace(
      "| SAC (SB3) | `reference_ship_sac` | 0.107 [0.055, 0.176]",
      "| SAC (SB3) | `reference_ship_sac` | 0.999 [0.055, 0.176]"))
  changed = published.updated(readme, "README.md")
  assert "| ship (gate rate) | SAC (SB3) | 0.999 [0.055, 0.176] |" in changed


def test_the_ladders_summary_follows_its_report(monkeypatch):
  """Who leads, whether the lead is distinguishable, and who has not run yet are the
  ladder report's, as is results_ladder.md's table of every learner: a learner landing
  there changes both."""
  real = published._read
  monkeypatch.setattr(published, "_read", lambda report: real(report).replace(
      "- hard: SAC (JAX) leads (63.4 [50.5, 75.1]); not distinguishable",
      "- hard: SAC (JAX) leads (71.0 [70.1, 75.1]); its interval lies above").replace(
      "| - | - | - | - | 63.4 [50.5, 75.1] | 61.8 [51.7, 71.8] | 0, 0, 10 |",
      "| 1.0 [0.0, 2.0] | 1.0 [0.0, 2.0] | 1.0 [0.0, 2.0] | 1.0 [0.0, 2.0] | 71.0 [70.1, 75.1] "
      "| 61.8 [51.7, 71.8] | 10, 10, 10 |"))
  summary = published.ladder_summary()
  assert "| ship_current (gate pass rate) | Waypoints 97.9 | Waypoints 97.8 | SAC (JAX) 71.0 |" \
      in summary
  assert "| ship_harbour (gate pass rate) | Waypoints 96.6 | Waypoints 93.9 | Flat PGRL 12.1 " \
         "(not distinguishable) |" in summary
  assert "SAC (JAX) on ship_goal; ship_regatta; ship_harbour." in summary
  learners = published.ladder_learners()
  assert "| ship_current (gate pass rate) | SAC (JAX) | 1.0 [0.0, 2.0] | 1.0 [0.0, 2.0] | " \
         "71.0 [70.1, 75.1] |" in learners
  assert "| ship_regatta (finish rate) | Waypoints | 97.2 [96.4, 97.8] | 98.7 [98.2, 99.0] | " \
         "49.2 [46.5, 52.4] |" in learners


def _number(text):
  return float(text.replace(",", ""))


def _digits(text):
  return len(text.split(".")[1]) if "." in text else 0


def _matches(quoted, given):
  """Whether an interval quoted on a page is `given` (a report's) to the page's rounding."""
  return all(abs(_number(q) - _number(g)) <= 0.5 * 10 ** -_digits(q) + 1e-9
             for q, g in zip(quoted, given))


def test_every_interval_a_page_quotes_is_a_reports():
  given = [m for report in _reports() for m in _INTERVAL.findall(report.read_text())]
  assert len(given) > 100
  unsourced = {}
  for page in published.pages():
    if page in HISTORY_PAGES:
      continue
    text = " ".join(_HISTORY.sub("", (REPO / page).read_text()).split())
    for quoted in _INTERVAL.findall(text):
      if not any(_matches(quoted, g) for g in given):
        unsourced.setdefault(page, []).append("{} [{}, {}]".format(*quoted))
  assert unsourced == {}


def _included():
  """page -> (report, its text as the include options cut it) of each report a page
  includes."""
  shown = {}
  for path in sorted((REPO / "docs").glob("*.md")):
    for target, options in re.findall(r"^```\{include\} (\S+)\n((?::.*\n)*)",
                                      path.read_text(), re.M):
      if "figures/" not in target:
        continue
      text = (path.parent / target).resolve().read_text()
      option = {key: value.strip().strip('"')      # MyST reads the options as YAML
                for key, value in re.findall(r"^:([\w-]+):[ \t]*(.*)$", options, re.M)}
      if "start-line" in option:
        text = "".join(text.splitlines(keepends=True)[int(option["start-line"]):])
      if "end-before" in option:
        assert option["end-before"] in text, (path.name, option["end-before"])
        text = text.split(option["end-before"], 1)[0]
      shown.setdefault(path.relative_to(REPO).as_posix(), []).append((target, text))
  return shown


def test_every_report_is_on_the_site_once_under_a_title_of_its_own():
  shown = _included()
  reports = [t for parts in shown.values() for t, _ in parts if t.endswith("REPORT.md")]
  assert sorted(pathlib.Path(t).parent.name for t in reports) == sorted(
      r.parent.name for r in _reports())
  titles = {}
  for path in sorted((REPO / "docs").glob("*.md")):
    title = re.search(r"^# (.+)$", path.read_text(), re.M).group(1)
    titles.setdefault(title, []).append(path.name)
  assert {t: names for t, names in titles.items() if len(names) > 1} == {}
  for page in shown:      # the page's title is its own, not an included report's
    first = (REPO / page).read_text().split("```{include}")[0]
    assert first.startswith("# "), page


def _disagreements(included):
  """(where, where, table) of each table shown twice with other cells: the same
  columns and rows under the same protocol (the quick protocol's are its own)."""
  seen, disagree = {}, []
  for page, parts in included.items():
    for target, text in parts:
      for section in re.split(r"^(?=## )", text, flags=re.M):
        quick = "QUICK protocol" in section
        for block in re.findall(r"((?:^\|.*\|\n)+)", section, re.M):
          rows = [[c.strip() for c in line.strip().strip("|").split("|")]
                  for line in block.splitlines()]
          key = (quick, tuple(rows[0]), tuple(row[0] for row in rows[2:]))
          if key in seen and seen[key][1] != rows:
            disagree.append((seen[key][0], f"{page} ({target})", rows[0][0]))
          seen.setdefault(key, (f"{page} ({target})", rows))
  return disagree


def test_no_two_reports_on_the_site_disagree_on_a_table():
  """The full report's section of the reference scores, written before the reference
  runs were made again, is left off the site for the reference report's own."""
  assert _disagreements(_included()) == []


def test_a_table_shown_twice_with_another_number_is_a_disagreement():
  """The check above is not vacuous: the reference report shown a second time with
  one cell changed (as figures/REPORT.md's older reference section once was)."""
  included = _included()
  text = (REPO / "figures/reference/REPORT.md").read_text()
  cell = re.search(r"\| (-?\d+\.\d+ \[-?\d+\.\d+, -?\d+\.\d+\]) \|", text).group(1)
  included["docs/stale.md"] = [("an older copy", text.replace(cell, "0.537 [0.1, 0.9]", 1))]
  assert {table for _, _, table in _disagreements(included)} >= {"learner"}


def test_the_full_reports_reference_section_is_the_reference_report(tmp_path):
  """figures/REPORT.md kept an older copy of the reference report's section after the
  reference was made again on its own; `python docs/_ext/published.py` now makes the
  section again (`figures.replace_section`), and the site's build stops on a stale one."""
  from hpg_mj.experiments import figures
  assert not figures.replace_section(REPO / "figures", "reference", write=False)
  import shutil
  shutil.copy(REPO / "figures" / "REPORT.md", tmp_path / "REPORT.md")
  (tmp_path / "reference").mkdir()
  text = (REPO / "figures/reference/REPORT.md").read_text()
  cell = re.search(r"\| (-?\d+\.\d+ \[-?\d+\.\d+, -?\d+\.\d+\]) \|", text).group(1)
  (tmp_path / "reference" / "REPORT.md").write_text(text.replace(cell, "0.537 [0.1, 0.9]", 1))
  before = (tmp_path / "REPORT.md").read_text()
  assert figures.replace_section(tmp_path, "reference")
  after = (tmp_path / "REPORT.md").read_text()
  assert "0.537 [0.1, 0.9]" in after and "0.537 [0.1, 0.9]" not in before
  assert after.split("## reference: ")[0] == before.split("## reference: ")[0]
  assert not figures.replace_section(tmp_path, "reference")
