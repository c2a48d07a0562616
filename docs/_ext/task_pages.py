"""One documentation page per task, written when the build starts from what the code
says: the dm_control domain's docstring (the task's own paragraph), the task
constructor's docstring and signature, the Gymnasium environment's docstring (its
manual: spaces, rewards, starts, endings, arguments, version history), and the
spaces of the environments as built. Nothing on these pages is copied by hand, so
they cannot drift from the code; a task without a page (or a page without a task)
stops the build."""
import inspect
import pathlib
import re
import textwrap

import gymnasium

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
}

# Domains whose tasks are the levels of one Gymnasium id (its `level` argument).
_LEVEL_DOMAINS = ("ship_current", "ship_goal", "ship_regatta")

# Gymnasium's make() arguments for building each id here: the analytic ship needs
# neither MuJoCo nor a renderer.
_MAKE_KWARGS = {"hpg_mj/ShipSteering-v0": {"backend": "analytic"},
                "hpg_mj/ShipSteeringDiagonal-v0": {"backend": "analytic"},
                "hpg_mj/ShipSteeringStraight-v0": {"backend": "analytic"},
                "hpg_mj/ShipPatrol-v0": {"backend": "analytic"},
                "hpg_mj/ShipCurrent-v0": {"backend": "analytic"},
                "hpg_mj/ShipGoal-v0": {"backend": "analytic"},
                "hpg_mj/ShipRegatta-v0": {"backend": "analytic"}}


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


def _shift_headings(text):
  """The manual's `##` sections one level down, under the page's "Manual"."""
  return re.sub(r"^(#+) ", r"#\1 ", text, flags=re.M)


def _spec_lines(spec):
  return [f"`{name}`: `{value!r}`" for name, value in spec.items()] if isinstance(
      spec, dict) else [f"`{spec!r}`"]


# dm_control (domain, task) -> its name in hpg_mj.benchmark (the tasks it scores)
_BENCHMARK = {("ship", "steer"): "ship", ("taxi", "fuel"): "taxi_fuel",
              ("taxi", "classic"): "taxi"}
SCORE_ANY_POLICY = "../getting_started.md#score-any-policy"


def _scoring(domain, task):
  """The page's line on scoring a policy: the call, and the section that shows it."""
  name = _BENCHMARK.get((domain, task))
  link = f"[Score any policy]({SCORE_ANY_POLICY})"
  if name is None:
    return (f"{link}: `hpg_mj.benchmark.evaluate` scores a function, an SB3 model or an "
            f"agent on {', '.join(f'`{n}`' for n in _BENCHMARK.values())}")
  return (f"`hpg_mj.benchmark.evaluate(policy, {name!r})`: {link} (a function, an SB3 "
          "model, an agent)")


def render(domain, task):
  """The Markdown of one task's page."""
  env_id, picture, caption = TASKS[(domain, task)]
  module = suite._DOMAINS[domain]
  constructor = module.SUITE[task]
  cls = _entry_class(env_id)
  level = {"level": task} if domain in _LEVEL_DOMAINS else {}
  env = gymnasium.make(env_id, **_MAKE_KWARGS.get(env_id, {}), **level)
  dm_env = suite.load(domain, task)
  arguments = f", level={task!r}" if level else ""
  try:
    facts = [
        ("dm_control", f"`suite.load({domain!r}, {task!r})`"),
        ("Gymnasium", f"`gymnasium.make({env_id!r}{arguments})`"),
        ("vector", f"`gymnasium.make_vec({env_id!r}, num_envs=N{arguments})` "
                   f"(`{envs.VECTOR_ENTRY_POINTS[envs.ENV_IDS[env_id][0]]}`)"),
        ("entry point", f"`{envs.ENV_IDS[env_id][0]}` with `{envs.ENV_IDS[env_id][1]!r}`"),
        ("action space", f"`{env.action_space!r}`"),
        ("observation space", f"`{env.observation_space!r}`"),
        ("dm_control action spec", "<br>".join(_spec_lines(dm_env.action_spec()))),
        ("dm_control observation spec", "<br>".join(_spec_lines(dm_env.observation_spec()))),
        ("dm_control tags", ", ".join(sorted(
            tag for tag in module.SUITE.tags() if task in module.SUITE.tagged(tag))) or "none"),
        ("score a policy", _scoring(domain, task)),
    ]
  finally:
    env.close()
    dm_env.close()
  # One line a row: a long space's repr (numpy's) wraps.
  rows = "\n".join(f"| {name} | {' '.join(value.split()).replace('|', '&#124;')} |"
                   for name, value in facts)
  signature = f"{module.__name__}.{task}{inspect.signature(constructor)}"
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
                  task=task, caption=caption, rows=rows,
                  paragraph=task_paragraph(inspect.getdoc(module), task),
                  module=module.__name__, signature=signature,
                  constructor_doc=inspect.getdoc(constructor),
                  cls=f"{cls.__module__}.{cls.__qualname__}") \
      + _shift_headings(inspect.getdoc(cls)) + "\n"


def index():
  lines = ["# Tasks", "",
           "One page per task: its dm_control name and Gymnasium id, its spaces, rewards,",
           "starts, endings, arguments and version history, written at build time from",
           "the environments' docstrings.", "",
           "| dm_control | Gymnasium | page |", "|---|---|---|"]
  for (domain, task), (env_id, _, _) in TASKS.items():
    lines.append(f"| `{domain}/{task}` | `{env_id}` | [{task}]({page_name(domain, task)}.md) |")
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
