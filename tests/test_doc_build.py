"""The documentation builds from the checkout's tracked files alone, as in a fresh
clone, with warnings as errors and nitpicky references (scripts/docs.sh's command):
a broken link or cross-reference, a task without its page or a docstring that does
not parse fails it (issue 22). The task pages carry what the code says."""
import pathlib
import shutil
import subprocess
import sys

import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]


def _tracked():
  try:
    names = subprocess.run(["git", "-C", str(REPO), "ls-files"], capture_output=True,
                           text=True, check=True).stdout.split()
  except (OSError, subprocess.CalledProcessError):
    pytest.skip("not a git checkout")
  return names


@pytest.fixture(scope="module")
def site(tmp_path_factory):
  pytest.importorskip("sphinx")
  clone = tmp_path_factory.mktemp("clone")
  for name in _tracked():                   # the clone: every tracked file, nothing built
    if not (REPO / name).is_file():         # deleted in the work tree, not yet committed
      continue
    (clone / name).parent.mkdir(parents=True, exist_ok=True)
    shutil.copy2(REPO / name, clone / name)
  html = clone / "html"
  done = subprocess.run([sys.executable, "-m", "sphinx", "-q", "-n", "-W", "--keep-going",
                         "-b", "html", "-j", "2", str(clone / "docs"), str(html)],
                        capture_output=True, text=True)
  assert done.returncode == 0, done.stderr[-5000:]
  return html


def test_the_site_builds_with_warnings_as_errors(site):
  for page in ("index", "getting_started", "tutorial_agent", "api", "SPEC", "changelog",
               "tasks/ship_steer", "tasks/taxi_fuel", "results_report"):
    assert (site / f"{page}.html").is_file(), page


def test_a_task_page_shows_what_the_code_says(site):
  import gymnasium

  import hpg_mj  # noqa: F401
  from hpg_mj.envs import ship
  page = (site / "tasks" / "ship_patrol.html").read_text()
  space = gymnasium.make("hpg_mj/ShipPatrol-v0", backend="analytic").observation_space
  assert repr(space).split("(")[0] in page and "1001.8" in page      # built, not copied
  assert "Version history" in page and "state_before_restart" in page
  assert "beyond_patrol.png" in page and (site / "_images" / "beyond_patrol.png").is_file()
  assert "Rewards" in ship.ShipSteeringEnv.__doc__


def test_the_learner_contract_and_the_api_are_documented(site):
  interfaces = (site / "interfaces.html").read_text()
  assert "hpg_mj.hierarchy.graph.Learner" in interfaces and "observe" in interfaces
  api = (site / "api" / "hpg_mj.hierarchy.html").read_text()
  assert "hpg_mj.hierarchy.program.Program" in api and "hpg_mj.hierarchy.blocks" in api


def test_the_front_page_installs_runs_and_scores_and_every_task_page_links_to_scoring(site):
  """The front page: the install, the README's two commands and a five-line example
  (load a task, step it, score a policy; tests/test_doc_blocks.py runs it). "Score
  any policy" shows a plain function and an SB3 model once, and every task page
  links to it."""
  import html
  import re

  if str(REPO / "docs" / "_ext") not in sys.path:
    sys.path.insert(0, str(REPO / "docs" / "_ext"))
  import task_pages      # docs/_ext: the pages' list
  front = html.unescape(re.sub(r"<[^>]+>", "", (site / "index.html").read_text()))
  for text in ("pip install", "bash scripts/run.sh", "bash scripts/test.sh",
               "hpg_mj/ShipSteering-v0", "env.step", "benchmark.evaluate"):
    assert text in front, text
  five = re.search(r"## In five lines\n.*?```python\n(.*?)```",
                   (REPO / "docs" / "index.md").read_text(), re.S).group(1)
  assert len(five.strip().splitlines()) == 5
  guide = (REPO / "docs" / "getting_started.md").read_text()
  section = guide.split("## Score any policy\n", 1)[1].split("\n## ", 1)[0]
  assert section.count("```python") == 1 and "{include}" not in section
  shown = re.sub(r"^<!--.*-->\n", "", section, flags=re.M)    # less the tests' reductions
  assert shown.count("steer = lambda") == 1 and shown.count("PPO(") == 1
  assert guide.count("benchmark.evaluate(steer") == 1
  for domain, task in task_pages.TASKS:
    page = (site / "tasks" / f"{task_pages.page_name(domain, task)}.html").read_text()
    assert 'href="../getting_started.html#score-any-policy"' in page, (domain, task)
