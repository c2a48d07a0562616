"""Every task page has the sections Gymnasium's environment pages have, the observation
element by element, every argument with its default, and the episode limit in its
summary table. The pages are generated here by docs/_ext/task_pages.py's own functions
(no Sphinx build: a few seconds), one per task of the suite, so a task added to the
suite is held to the same list the day it comes."""
import ast
import inspect
import pathlib
import re
import sys

import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]
if str(REPO / "docs" / "_ext") not in sys.path:
  sys.path.insert(0, str(REPO / "docs" / "_ext"))
import task_pages  # noqa: E402  (docs/_ext: the generator of the task pages)

# Gymnasium's sections of an environment page, in its order (its Taxi page's, with
# Information and References), as the manual's headings (`## ...` in the docstring).
SECTIONS = ("Description", "Action space", "Observation space", "Rewards", "Starting state",
            "Episode end", "Information", "Arguments", "References", "Version history")


def _sections(page):
  """The manual's sections of a page: heading (lower case) -> text."""
  manual = page.split("\n## Manual\n", 1)[1]
  parts = re.split(r"^### (.+?)[ \t]*$", manual, flags=re.M)
  return {heading.strip().lower(): text for heading, text in zip(parts[1::2], parts[2::2])}


def problems(page, cls):
  """What a task page lacks (an empty list: nothing)."""
  found = []
  sections = _sections(page)
  found += [f"no section {name!r}" for name in SECTIONS if name.lower() not in sections]
  table = re.search(r"^\| Num \| .*\| Min \| Max \|.*\n\|[- |]+\|\n((?:\|.*\|\n?)+)",
                    sections.get("observation space", ""), re.M)
  if table is None:
    found.append("no table of the observation's elements with their Min and Max")
  limit = re.search(r"^\| max episode steps \| ([\d,]+) ", page, re.M)
  if limit is None:
    found.append("no 'max episode steps' row in the summary table")
  arguments = sections.get("arguments", "")
  for name, parameter in inspect.signature(cls.__init__).parameters.items():
    if name == "self" or parameter.kind in (parameter.VAR_POSITIONAL, parameter.VAR_KEYWORD):
      continue
    shown = re.search(rf"`{name}=([^`]+)`", arguments)
    if shown is None:
      found.append(f"argument {name} without its default (`{name}={parameter.default!r}`)")
      continue
    try:
      value = ast.literal_eval(shown.group(1))
    except (ValueError, SyntaxError):
      value = shown.group(1)
    if value != parameter.default:
      found.append(f"argument {name} shown with default {shown.group(1)}, "
                   f"the code's is {parameter.default!r}")
  numbered = r'^(<a id="\w+"></a>)?\[\d+\] \S'      # "[1] A. Author, ..." (an anchor before)
  if "references" in sections and not re.search(numbered, sections["references"], re.M):
    found.append("no numbered reference ('[1] ...') under References")
  for block in re.findall(r"^```text\n(.*?)^```", page, re.M | re.S):
    found += [f"a line of {len(line)} characters runs off the page: {line[:40]}..."
              for line in block.splitlines() if len(line) > 88]
  return found


@pytest.fixture(scope="module")
def pages():
  return {key: task_pages.render(*key) for key in task_pages.TASKS}


@pytest.mark.parametrize("key", list(task_pages.TASKS), ids="/".join)
def test_every_task_page_has_gymnasiums_sections_and_its_episode_limit(pages, key):
  cls = task_pages._entry_class(task_pages.TASKS[key][0])
  assert problems(pages[key], cls) == []


def test_a_scored_tasks_page_gives_its_published_bounds(pages):
  # Every task the benchmark scores (not the subtasks, not the patrol) gives each
  # score's random and best known as `benchmark.bounds()` publishes them.
  from hpg_mj import benchmark
  published = benchmark.bounds()["tasks"]
  for key, page in pages.items():
    name = task_pages._BENCHMARK.get(key)
    row = re.search(r"^\| bounds \(`benchmark.bounds\(\)`\) \| (.*) \|$", page, re.M)
    assert (row is None) == (name is None), key
    for score in published[name]["scores"] if name else ():
      entry = published[name]
      assert (f"{score}: random {entry['random'][score]:.5g}, best known "
              f"{entry['best'][score]:.5g}") in row.group(1), (key, score)


def test_the_observation_table_is_the_space_as_built(pages):
  """Min and Max are the built space's, a row per element of this task's space: the
  classic taxi's page has no fuel row, the hard current's the fastest water."""
  classic = _sections(pages[("taxi", "classic")])["observation space"]
  fuel = _sections(pages[("taxi", "fuel")])["observation space"]
  assert "| 3 | `destination` | 0 | 3 |" in classic and "`fuel`" not in classic
  assert "| 4 | `fuel` (with fuel only) | 0 | 12 |" in fuel
  hard = _sections(pages[("ship_current", "hard")])["observation space"]
  env = task_pages._make("ship_current", "hard")
  assert f"| {env.observation_space.high[4]:g} |" in hard
  env.close()
  assert "| 5,000 (" in pages[("ship", "steer")] and "| 6,000 (" in pages[("ship", "patrol")]
  assert "| 200 (" in pages[("taxi", "fuel")]


def test_the_check_finds_what_a_page_lacks(pages):
  """A page without Information or References, or whose arguments lack a default,
  is named (so a new task's page that lacks one fails the test above)."""
  page = pages[("ship", "steer")]
  cls = task_pages._entry_class("hpg_mj/ShipSteering-v0")
  cut = re.sub(r"^### Information\n", "### Info\n", page, flags=re.M)
  cut = cut.replace("`width=640`", "`width`").replace("| max episode steps |", "| limit |")
  found = problems(cut.replace("### References", "### Further reading"), cls)
  assert found == ["no section 'Information'", "no section 'References'",
                   "no 'max episode steps' row in the summary table",
                   "argument width without its default (`width=640`)"], found


def test_the_index_gives_every_tasks_episode_limit():
  index = task_pages.index()
  assert "| dm_control | Gymnasium | max episode steps | page |" in index
  assert "| `ship/steer` | `hpg_mj/ShipSteering-v0` | 5,000 |" in index
  assert "| `taxi/fuel` | `hpg_mj/TaxiFuel-v0` | 200 |" in index


def test_a_missing_element_row_stops_the_page():
  env = task_pages._make("ship", "steer")
  manual = inspect.getdoc(task_pages._entry_class("hpg_mj/ShipSteering-v0"))
  env.close()
  cut = re.sub(r"^\| 3 \|.*\n", "", manual, flags=re.M)
  with pytest.raises(ValueError, match=r"no row for the elements \['3'\]"):
    task_pages.element_table(cut, env.observation_space, "ShipSteeringEnv")
