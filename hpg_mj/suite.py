"""The hpg_mj benchmark as a dm_control suite.

```python
from hpg_mj import suite
env = suite.load("ship", "steer")
```

Domains and tasks are listed in `ALL_TASKS`, as in `dm_control.suite`.
"""
from hpg_mj.worlds import ship, ship_current, ship_goal, ship_harbour, ship_regatta, taxi

_DOMAINS = {"ship": ship, "taxi": taxi, "ship_current": ship_current, "ship_goal": ship_goal,
            "ship_regatta": ship_regatta, "ship_harbour": ship_harbour}

# (domain_name, task_name) for every task, in a fixed order.
ALL_TASKS = tuple((domain_name, task_name)
                  for domain_name, domain in _DOMAINS.items()
                  for task_name in domain.SUITE)

TASKS_BY_DOMAIN = {name: tuple(domain.SUITE) for name, domain in _DOMAINS.items()}


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
                     f"valid tasks: {sorted(domain.SUITE)}")
  task_kwargs = dict(task_kwargs or {})
  if environment_kwargs is not None:
    task_kwargs["environment_kwargs"] = environment_kwargs
  env = domain.SUITE[task_name](**task_kwargs)
  env.task.visualize_reward = visualize_reward
  return env
