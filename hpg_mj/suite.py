"""The hpg_mj benchmark as a dm_control suite.

```python
from hpg_mj import suite
env = suite.load("ship", "steer")
```

Domains and tasks are listed in `ALL_TASKS`, and by tag as in `dm_control.suite`:
`BENCHMARKING` (every task the benchmark scores), `EXTRA` (the rest: none today),
`EASY`, `MEDIUM` and `HARD` (the task ladder's levels; the steering and taxi tasks
have no level). `TAGS` lists every tag a task carries, `tagged(tag)` the tasks of one.
"""
from hpg_mj.worlds import ship, ship_current, ship_goal, ship_harbour, ship_regatta, taxi

_DOMAINS = {"ship": ship, "taxi": taxi, "ship_current": ship_current, "ship_goal": ship_goal,
            "ship_regatta": ship_regatta, "ship_harbour": ship_harbour}

# (domain_name, task_name) for every task, in a fixed order.
ALL_TASKS = tuple((domain_name, task_name)
                  for domain_name, domain in _DOMAINS.items()
                  for task_name in domain.SUITE)

TASKS_BY_DOMAIN = {name: tuple(domain.SUITE) for name, domain in _DOMAINS.items()}

# Every tag some task carries, in a fixed order (dm_control's TaggedTasks lists none).
TAGS = tuple(dict.fromkeys(tag for domain in _DOMAINS.values()
                           for tag in domain.SUITE._tags))  # pylint: disable=protected-access


def tagged(tag):
  """Returns the (domain_name, task_name) of every task carrying `tag`, in `ALL_TASKS`' order.

  Raises:
    ValueError: for a tag no task carries, listing those some task does (`TAGS`).
  """
  if tag not in TAGS:
    raise ValueError(f"no task is tagged {tag!r}; tags: {list(TAGS)}")
  return tuple((domain_name, task_name) for domain_name, domain in _DOMAINS.items()
               for task_name in domain.SUITE if task_name in domain.SUITE.tagged(tag))


BENCHMARKING = tagged("benchmarking")
EXTRA = tuple(task for task in ALL_TASKS if task not in BENCHMARKING)
EASY = tagged("easy")
MEDIUM = tagged("medium")
HARD = tagged("hard")


def load(domain_name, task_name, task_kwargs=None, environment_kwargs=None,
         visualize_reward=False):
  """Returns the dm_control environment of a domain and task.

  Args:
    domain_name: `"ship"`, `"taxi"`, `"ship_current"`, `"ship_goal"`,
      `"ship_regatta"` or `"ship_harbour"`.
    task_name: a task of that domain (see `TASKS_BY_DOMAIN`).
    task_kwargs: keyword arguments for the task constructor (for example
      `{"random": 0}` for a seed).
    environment_kwargs: keyword arguments for `control.Environment`.
    visualize_reward: kept for dm_control compatibility; unused.
  Raises:
    ValueError: for an unknown domain or task, listing the valid ones.
  """
  if domain_name not in _DOMAINS:
    raise ValueError(f"unknown domain {domain_name!r}; valid domains: {sorted(_DOMAINS)}")
  domain = _DOMAINS[domain_name]
  if task_name not in domain.SUITE:
    raise ValueError(f"unknown task {task_name!r} in domain {domain_name!r}; "
                     f"valid tasks: {list(domain.SUITE)}")
  task_kwargs = dict(task_kwargs or {})
  if "level" in task_kwargs:
    raise ValueError(f"task_kwargs: a ladder domain's level is its task name, "
                     f"load({domain_name!r}, {task_kwargs['level']!r}), not a 'level' argument")
  if environment_kwargs is not None:
    task_kwargs["environment_kwargs"] = environment_kwargs
  env = domain.SUITE[task_name](**task_kwargs)
  env.task.visualize_reward = visualize_reward
  return env
