"""One documentation page per task, written when the build starts from what the code
says: the dm_control domain's docstring (the task's own paragraph), the task
constructor's docstring and signature, the Gymnasium environment's docstring (its
manual, with Gymnasium's sections: description, action space, observation space
with a row per element, rewards, starting state, episode end, information,
arguments with their defaults, references, version history), and the environments
as built: their spaces, the observation table's bounds and the episode limit.
Nothing on these pages is copied by hand, so they cannot drift from the code; a task
without a page (or a page without a task), or an observation element without its
row, stops the build (tests/test_task_pages.py holds every page to the sections)."""
import inspect
import pathlib
import re
import textwrap

import gymnasium
import numpy as np
from gymnasium import spaces

import hpg_mj  # noqa: F401  (registers the Gymnasium ids)
from hpg_mj import envs
from hpg_mj import suite

import generated   # docs/_ext

REPO = pathlib.Path(__file__).resolve().parents[2]
OUT = "tasks"         # under docs/, written at build time (not tracked)

# The two ship subtasks' picture: their learning curves.
_SUBTASKS = ("figures/beyond/subtask_width.png",
             "the subtasks' success rate while learning (SPEC section 8's learned width "
             "against the paper's sigma = 1)")

# dm_control (domain, task) -> (Gymnasium id, a picture from videos/ or figures/, its caption)
TASKS = {
    ("ship", "steer"): ("hpg_mj/ShipSteering-v0", "videos/ship_steer_scripted.gif",
                        "the scripted helmsman steers the MuJoCo ship through the gate "
                        "(`hpg-mj render --domain ship --task steer --seed 3`)"),
    ("ship", "diagonal"): ("hpg_mj/ShipSteeringDiagonal-v0", *_SUBTASKS),
    ("ship", "straight"): ("hpg_mj/ShipSteeringStraight-v0", *_SUBTASKS),
    ("ship", "patrol"): ("hpg_mj/ShipPatrol-v0", "figures/beyond/beyond_patrol.png",
                         "gate passes an hour on the continuing task (`hpg-mj reproduce "
                         "beyond`)"),
    ("taxi", "fuel"): ("hpg_mj/TaxiFuel-v0", "videos/taxi_fuel_scripted.gif",
                       "the scripted driver delivers a passenger on the MuJoCo board"),
    ("taxi", "classic"): ("hpg_mj/Taxi-v0", "videos/taxi_fuel_scripted.gif",
                          "the board (shown here with the fuel station F, which the "
                          "classic task does not have)"),
    **{("ship_current", level): (
        "hpg_mj/ShipCurrent-v0", f"figures/tasks/ship_current_{level}.png",
        f"the still-water helmsman in the {level} current: where its wake bends, the water "
        "carried the ship (`scripts/task_pictures.py`)") for level in ("easy", "medium", "hard")},
    **{("ship_goal", level): (
        "hpg_mj/ShipGoal-v0", f"figures/tasks/ship_goal_{level}.png",
        f"a gate of the {level} level and the scripted helmsman's way through it "
        "(`scripts/task_pictures.py`)") for level in ("easy", "medium", "hard")},
    **{("ship_regatta", level): (
        "hpg_mj/ShipRegatta-v0", f"figures/tasks/ship_regatta_{level}.png",
        f"a course of the {level} level and the scripted helmsman's wake through its "
        "first gates (grey), with the next (yellow) and the rest (white) to pass "
        "(`scripts/task_pictures.py`)") for level in ("easy", "medium", "hard")},
    **{("ship_harbour", level): (
        "hpg_mj/ShipHarbour-v0", f"figures/tasks/ship_harbour_{level}.png",
        f"the {level} level's islands and piers and the scripted helmsman's wake round them "
        "to the gate, down the level's distance field (the rangefinders' rays in yellow; "
        "`scripts/task_pictures.py`)") for level in ("easy", "medium", "hard")},
}

# Domains whose tasks are the levels of one Gymnasium id (its `level` argument).
_LEVEL_DOMAINS = ("ship_current", "ship_goal", "ship_regatta", "ship_harbour")

# Gymnasium's make() arguments for building each id here: the analytic ship needs
# neither MuJoCo nor a renderer.
_MAKE_KWARGS = {"hpg_mj/ShipSteering-v0": {"backend": "analytic"},
                "hpg_mj/ShipSteeringDiagonal-v0": {"backend": "analytic"},
                "hpg_mj/ShipSteeringStraight-v0": {"backend": "analytic"},
                "hpg_mj/ShipPatrol-v0": {"backend": "analytic"},
                "hpg_mj/ShipCurrent-v0": {"backend": "analytic"},
                "hpg_mj/ShipGoal-v0": {"backend": "analytic"},
                "hpg_mj/ShipRegatta-v0": {"backend": "analytic"},
                "hpg_mj/ShipHarbour-v0": {"backend": "analytic"}}


def page_name(domain, task):
  return f"{domain}_{task}"


def _check_coverage():
  """Every suite task and every Gymnasium id has exactly one page."""
  if set(TASKS) != set(suite.ALL_TASKS):
    raise ValueError(f"docs/_ext/task_pages.py TASKS names {sorted(TASKS)}, the suite has "
                     f"{sorted(suite.ALL_TASKS)}: add or remove the task's page")
  ids = sorted({env_id for env_id, _, _ in TASKS.values()})
  if ids != sorted(envs.ENV_IDS):
    raise ValueError(f"docs/_ext/task_pages.py TASKS names the ids {ids}, hpg_mj registers "
                     f"{sorted(envs.ENV_IDS)}")
  for _, picture, _ in TASKS.values():
    if not (REPO / picture).is_file():
      raise ValueError(f"docs/_ext/task_pages.py: the picture {picture} does not exist")


def _entry_class(env_id):
  module, name = envs.ENV_IDS[env_id][0].split(":")
  return getattr(__import__(module, fromlist=[name]), name)


def manuals():
  """(name, docstring) of every docstring the task pages render: the domains', the
  task constructors' and the environments' (tests/test_doc_blocks.py runs their code)."""
  seen = {}
  for (domain, task), (env_id, _, _) in TASKS.items():
    module = suite._DOMAINS[domain]
    cls = _entry_class(env_id)
    seen[module.__name__] = inspect.getdoc(module)
    seen[f"{module.__name__}.{task}"] = inspect.getdoc(module.SUITE[task])
    seen[f"{cls.__module__}.{cls.__qualname__}"] = inspect.getdoc(cls)
  return sorted(seen.items())


def manual_classes():
  """The environments whose docstring is a manual, each with its first task page."""
  pages = {}
  for (domain, task), (env_id, _, _) in TASKS.items():
    cls = _entry_class(env_id)
    pages.setdefault(f"{cls.__module__}.{cls.__qualname__}", f"/{OUT}/{page_name(domain, task)}")
  return pages


def task_paragraph(module_doc, task):
  """The task's own entry in a domain docstring's "Tasks:" list."""
  match = re.search(rf"^  {task}:\s+(.*?)(?=^  \w+:\s|^\S|\Z)", module_doc, re.M | re.S)
  if match is None:
    raise ValueError(f"the domain's docstring lists no task {task!r} under 'Tasks:'")
  return " ".join(match.group(1).split())


def _sentence(text):
  """A docstring's or a caption's fragment ("the full task: ...") as the page's
  sentence: its first letter a capital."""
  return text[:1].upper() + text[1:]


def _shift_headings(text):
  """The manual's `##` sections one level down, under the page's "Manual"."""
  return re.sub(r"^(#+) ", r"#\1 ", text, flags=re.M)


def _signature(name, function):
  """`name(...)` with one parameter a line, so that a long signature stays on the page."""
  parameters = [str(p) for p in inspect.signature(function).parameters.values()]
  return f"{name}(" + "".join(f"\n    {p}," for p in parameters) + ("\n)" if parameters else ")")


def episode_limit(env):
  """The steps after which an episode ends at the latest: the environment's own limit
  (its `max_steps` argument or the task's default; the ids are registered without
  Gymnasium's TimeLimit wrapper, since each environment truncates itself)."""
  rules = getattr(env.unwrapped, "rules", None)
  if getattr(rules, "max_steps", None) is None:
    raise ValueError(f"{env.unwrapped!r}: a task page reads the episode limit from "
                     "env.unwrapped.rules.max_steps, which it lacks")
  return int(rules.max_steps)


def _bound(value):
  return f"{float(value):g}"


def element_bounds(space):
  """"Num" -> (min, max) for every element of an observation space: "i" in a Box or
  MultiDiscrete of one dimension, "key[i]" in a Dict of those."""
  if isinstance(space, spaces.Dict):
    return {f"{key}[{num}]": bounds for key, sub in space.spaces.items()
            for num, bounds in element_bounds(sub).items()}
  if isinstance(space, spaces.Box) and len(space.shape) == 1:
    return {str(i): (_bound(low), _bound(high))
            for i, (low, high) in enumerate(zip(space.low, space.high))}
  if isinstance(space, spaces.MultiDiscrete) and space.nvec.ndim == 1:
    start = getattr(space, "start", np.zeros_like(space.nvec))
    return {str(i): (str(int(s)), str(int(s + n - 1)))
            for i, (s, n) in enumerate(zip(start, space.nvec))}
  if isinstance(space, spaces.Discrete):
    return {"0": (str(int(space.start)), str(int(space.start + space.n - 1)))}
  raise ValueError(f"no per-element bounds for the observation space {space!r}")


def _cells(line):
  return [cell.strip() for cell in line.strip().strip("|").split("|")]


def element_table(manual, space, where):
  """The manual with its observation table's Min and Max columns those of `space` as
  built (inserted after the second column, or replacing the table's own): the table
  under "## Observation space" whose first column is "Num", a row per element. A row
  whose element this task's space lacks is left out (the classic taxi has no fuel);
  an element without a row is refused."""
  section = re.search(r"^## Observation space[ \t]*$(.*?)(?=^## |\Z)", manual, re.M | re.S | re.I)
  if section is None:
    raise ValueError(f"{where}: the manual has no '## Observation space' section")
  lines = section.group(1).split("\n")
  first = next((i for i, line in enumerate(lines) if line.startswith("|")
                and _cells(line)[0] == "Num"), None)
  if first is None:
    raise ValueError(f"{where}: its observation space has no table of elements "
                     "('| Num | Observation | ... |', a row per element)")
  last = first
  while last + 1 < len(lines) and lines[last + 1].startswith("|"):
    last += 1
  header = _cells(lines[first])
  if "Min" in header and "Max" in header:
    columns = header.index("Min"), header.index("Max")
    build = lambda cells, low, high: [*cells[:columns[0]], low, *cells[columns[0] + 1:
                                      columns[1]], high, *cells[columns[1] + 1:]]
  else:
    build = lambda cells, low, high: [*cells[:2], low, high, *cells[2:]]
  bounds = element_bounds(space)
  table = [build(header, "Min", "Max"), build(["---"] * len(header), "---", "---")]
  for line in lines[first + 2:last + 1]:
    cells = _cells(line)
    num = cells[0].strip("`")
    if num in bounds:
      table.append(build(cells, *bounds.pop(num)))
  if bounds:
    raise ValueError(f"{where}: its observation table has no row for the elements "
                     f"{sorted(bounds)} of {space!r}")
  lines[first:last + 1] = ["| " + " | ".join(cells) + " |" for cells in table]
  start, end = section.span(1)
  return manual[:start] + "\n".join(lines) + manual[end:]


def _spec_lines(spec):
  return [f"`{name}`: `{value!r}`" for name, value in spec.items()] if isinstance(
      spec, dict) else [f"`{spec!r}`"]


# dm_control (domain, task) -> its name in hpg_mj.benchmark (the tasks it scores)
_BENCHMARK = {("ship", "steer"): "ship", ("taxi", "fuel"): "taxi_fuel",
              ("taxi", "classic"): "taxi",
              **{(domain, level): f"{domain}/{level}" for domain in _LEVEL_DOMAINS
                 for level in ("easy", "medium", "hard")}}
SCORE_ANY_POLICY = "../getting_started.md#score-any-policy"


def _scoring(domain, task):
  """The page's line on scoring a policy: the call, and the section that shows it."""
  name = _BENCHMARK.get((domain, task))
  link = f"[Score any policy]({SCORE_ANY_POLICY})"
  if name is None:
    names = dict.fromkeys(n.split("/")[0] for n in _BENCHMARK.values())
    return (f"{link}: `hpg_mj.benchmark.evaluate` scores a function, an SB3 model or an "
            f"agent on {', '.join(f'`{n}`' for n in names)} (the ladder's at a level)")
  return (f"`hpg_mj.benchmark.evaluate(policy, {name!r})`: {link} (a function, an SB3 "
          "model, an agent)")


def _bounds(domain, task):
  """The page's line on the task's published bounds (`benchmark.bounds()`, SPEC section
  7.1): each score's random and best known, what the best known is, and how a score is
  normalized; None for a task without bounds (a subtask, the patrol)."""
  from hpg_mj import benchmark
  name = _BENCHMARK.get((domain, task))
  entry = benchmark.bounds()["tasks"].get(name) if name else None
  if entry is None:
    return None
  scores = "; ".join(f"{score}: random {entry['random'][score]:.5g}, best known "
                     f"{entry['best'][score]:.5g}" for score in entry["scores"])
  return (f"{scores} (over the {entry['max_steps']:,}-step limit). `<score>_normalized` = "
          "100 (score - random) / (best known - random). Best known: "
          f"{entry['best_is']}")


def _make(domain, task):
  """The task's Gymnasium environment as the page describes it (the analytic ship)."""
  env_id = TASKS[(domain, task)][0]
  level = {"level": task} if domain in _LEVEL_DOMAINS else {}
  return gymnasium.make(env_id, **_MAKE_KWARGS.get(env_id, {}), **level)


def _entry_point(env_id, domain, task):
  """The page's entry-point row: the id's class and the arguments this page's task
  gets. A ladder's id registers its easy level; the page's `level=` replaces it."""
  entry_point, kwargs = envs.ENV_IDS[env_id]
  if domain not in _LEVEL_DOMAINS or kwargs.get("level") == task:
    return f"`{entry_point}` with `{kwargs!r}`"
  here = {**kwargs, "level": task}
  return (f"`{entry_point}` with `{here!r}` (the id registers `{kwargs!r}`; "
          "`level=` replaces it)")


def render(domain, task):
  """The Markdown of one task's page."""
  env_id, picture, caption = TASKS[(domain, task)]
  module = suite._DOMAINS[domain]
  constructor = module.SUITE[task]
  cls = _entry_class(env_id)
  env = _make(domain, task)
  dm_env = suite.load(domain, task)
  arguments = f", level={task!r}" if domain in _LEVEL_DOMAINS else ""
  where = f"{cls.__module__}.{cls.__qualname__} ({domain}/{task})"
  try:
    manual = element_table(inspect.getdoc(cls), env.observation_space, where)
    limit = episode_limit(env)
    dm_limit = getattr(getattr(dm_env.task, "rules", None), "max_steps", limit)
    if dm_limit != limit:
      raise ValueError(f"{where}: the Gymnasium environment ends an episode after {limit} "
                       f"steps, the dm_control task after {dm_limit}")
    facts = [
        ("dm_control", f"`suite.load({domain!r}, {task!r})`"),
        ("Gymnasium", f"`gymnasium.make({env_id!r}{arguments})`"),
        ("vector", f"`gymnasium.make_vec({env_id!r}, num_envs=N{arguments})` "
                   f"(`{envs.VECTOR_ENTRY_POINTS[envs.ENV_IDS[env_id][0]]}`)"),
        ("entry point", _entry_point(env_id, domain, task)),
        ("action space", f"`{env.action_space!r}`"),
        ("observation space", f"`{env.observation_space!r}`"),
        ("max episode steps", f"{limit:,} (`max_steps`: the environment's own limit, "
                              "the same in both APIs; no TimeLimit wrapper)"),
        ("dm_control action spec", "<br>".join(_spec_lines(dm_env.action_spec()))),
        ("dm_control observation spec", "<br>".join(_spec_lines(dm_env.observation_spec()))),
        ("dm_control tags", ", ".join(sorted(
            tag for tag in module.SUITE.tags() if task in module.SUITE.tagged(tag))) or "none"),
        ("score a policy", _scoring(domain, task)),
    ]
    bounds = _bounds(domain, task)
    if bounds is not None:
      facts.append(("bounds (`benchmark.bounds()`)", bounds))
  finally:
    env.close()
    dm_env.close()
  # One line a row: a long space's repr (numpy's) wraps.
  rows = "\n".join(f"| {name} | {' '.join(value.split()).replace('|', '&#124;')} |"
                   for name, value in facts)
  signature = _signature(f"{module.__name__}.{task}", constructor)
  image = "../../" + picture
  return textwrap.dedent("""\
      # {title}

      ```{{figure}} {image}
      :alt: {domain}/{task}
      :width: 480px

      {caption}
      ```

      | | |
      |---|---|
      {rows}

      ## The task

      {paragraph}

      From the docstring of the dm_control domain `{module}`.

      ```text
      {signature}
      ```

      {constructor_doc}

      ## Manual

      The Gymnasium environment's docstring (`{cls}`), which is also the dm_control
      task's: both run the same rules.

      """).format(title=f"{domain} / {task}: `{env_id}`", image=image, domain=domain,
                  task=task, caption=_sentence(caption), rows=rows,
                  paragraph=_sentence(task_paragraph(inspect.getdoc(module), task)),
                  module=module.__name__, signature=signature,
                  constructor_doc=inspect.getdoc(constructor),
                  cls=f"{cls.__module__}.{cls.__qualname__}") \
      + _shift_headings(manual) + "\n"


def index():
  lines = ["# Tasks", "",
           "One page per task: its dm_control name and Gymnasium id, its spaces (the",
           "observation element by element), rewards, starts, endings, information,",
           "arguments with their defaults, references and version history, written at",
           "build time from the environments' docstrings and the environments as built.",
           "Each environment ends its episodes itself, after its `max_steps`.", "",
           "| dm_control | Gymnasium | max episode steps | page |", "|---|---|---|---|"]
  for (domain, task), (env_id, _, _) in TASKS.items():
    env = _make(domain, task)
    try:
      limit = episode_limit(env)
    finally:
      env.close()
    lines.append(f"| `{domain}/{task}` | `{env_id}` | {limit:,} | "
                 f"[{task}]({page_name(domain, task)}.md) |")
  lines += ["", "```{toctree}", ":hidden:", ""]
  lines += [page_name(domain, task) for domain, task in TASKS]
  return "\n".join(lines + ["```", ""])


def write_pages(srcdir):
  """Writes docs/tasks/*.md."""
  _check_coverage()
  pages = {"index": index()}
  pages.update({page_name(d, t): render(d, t) for d, t in TASKS})
  generated.write(pathlib.Path(srcdir) / OUT, pages)


def setup(app):
  app.add_config_value("task_manual_pages", manual_classes(), "env")
  app.connect("builder-inited", lambda app: write_pages(app.srcdir))
  return {"parallel_read_safe": True}
