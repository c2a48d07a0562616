"""`hpg-mj tune`: one tuning procedure for every learner (SPEC section 7).

Each task file's [tuning] section declares what its hyper-parameters are tuned
over (a grid of its own keys: step sizes, exploration schedule), the score and
the training length. Every learner gets the same `budget`: that many
configurations of its grid (all of them if the grid is no larger; otherwise a
seeded random draw without replacement, so that a larger grid buys no extra
tries), each trained on the same tuning seeds for the same number of episodes,
and scored by the mean over those seeds. Tuning seeds only: no reported number
comes from them.
"""
import dataclasses
import itertools
import time

import numpy as np

from hpg_mj import _stack
from hpg_mj import agents
from hpg_mj.experiments import cores

DRAW_SEED = 0      # the generator that draws a budget's configurations from a larger grid
SCORES_EXTRA = ("steps_to_95",)   # taxi: primitive steps until the trailing 1,000-episode
                                  # mean return first reaches 95% of the optimum (Figure 6)


def grid(task):
  """Every configuration of the task's [tuning.grid]: a list of {section: {key: value}}."""
  if task.tuning is None:
    raise ValueError(f"{task.path}: has no [tuning] section saying what it is tuned over "
                     f"(see hpg_mj.experiments.tuning)")
  keys = [(section, key) for section, table in task.tuning["grid"].items() for key in table]
  options = [task.tuning["grid"][s][k] for s, k in keys]
  out = []
  for combo in itertools.product(*options):
    config = {}
    for (section, key), value in zip(keys, combo):
      config.setdefault(section, {})[key] = value
    out.append(config)
  return out


def candidates(task, budget):
  """`budget` configurations of the task's grid (all of it if no larger)."""
  if isinstance(budget, bool) or not isinstance(budget, int) or budget < 1:
    raise ValueError(f"budget must be a positive number of configurations, got {budget!r}")
  every = grid(task)
  if len(every) <= budget:
    return every
  picked = np.random.default_rng(DRAW_SEED).choice(len(every), size=budget, replace=False)
  return [every[i] for i in sorted(picked)]


def configure(task, changes):
  """The task's configuration with `changes` ({section: {key: value}}) applied."""
  config = task.config
  sections = {name: dataclasses.replace(getattr(config, name), **keys)
              for name, keys in changes.items()}
  return dataclasses.replace(config, **sections)


def score(agent, record, name):
  """The tuning score of one run's record: a metrics key (online, the last 1,000
  episodes), or "steps_to_95" (inf when never reached)."""
  if name == "steps_to_95":
    from hpg_mj.worlds import taxi_values
    steps = taxi_values.steps_to_reach(record["return"], record["steps"],
                                       agent.optimal_mean_return())
    return float("inf") if np.isnan(steps) else steps
  metrics = agent.metrics(record)
  if name not in metrics:
    raise ValueError(f"score {name!r} is not a metric of {agent.name}; allowed: "
                     f"{sorted(k for k, v in metrics.items() if isinstance(v, (int, float)))}"
                     f" or {list(SCORES_EXTRA)}")
  value = metrics[name]
  return float("nan") if value is None else float(value)


def _one_run(path, changes, seed, episodes, score_name):
  """Trains one candidate on one seed; returns (its score, seconds). A module-level
  function, so that a process pool can run it."""
  task = agents.load_task(path)
  start = time.perf_counter()
  agent = agents.lookup(task.kind)(configure(task, changes), seed=seed, task=task)
  record = agent.train(episodes)
  return score(agent, record, score_name), time.perf_counter() - start


def tune(task, budget=None, episodes=None, seeds=None, progress=None, workers=1):
  """Trains every candidate on every seed, `workers` runs at a time in separate
  processes (the result does not depend on it); returns {"task", "budget",
  "episodes", "seeds", "score", "better", "results": [{"changes", "scores",
  "mean"}], "best"}."""
  spec = task.tuning
  if spec is None:
    grid(task)                  # raises, naming the file
  if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
    raise ValueError(f"workers must be a positive number of processes, got {workers!r}")
  budget = spec["budget"] if budget is None else budget
  episodes = spec["episodes"] if episodes is None else episodes
  seeds = list(task.tuning_seeds) if seeds is None else list(seeds)
  if not seeds:
    raise ValueError(f"{task.path}: no tuning seeds ([protocol] tuning_seeds) to tune on")
  outside = sorted(set(seeds) - set(task.tuning_seeds))
  if outside:
    raise ValueError(f"seeds {outside} are not tuning seeds of {task.path.name} "
                     f"({list(task.tuning_seeds)}); tuning uses those only (SPEC section 7)")
  agents.lookup(task.kind)
  chosen = candidates(task, budget)
  jobs = [(k, seed) for k in range(len(chosen)) for seed in seeds]
  scores = {}

  def finished(job, value, seconds):
    scores[job] = value
    if progress:
      progress(job[0], chosen[job[0]], job[1], value, seconds)

  arguments = [(str(task.path), chosen[k], seed, episodes, spec["score"]) for k, seed in jobs]
  workers = cores.pool_size(workers, len(jobs))      # at most the runs, and the cores here
  if workers == 1:
    for job, args in zip(jobs, arguments):
      finished(job, *_one_run(*args))
  else:
    import concurrent.futures
    with concurrent.futures.ProcessPoolExecutor(max_workers=workers) as pool:
      futures = {pool.submit(_stack.roomy, _one_run, *args): job
                 for job, args in zip(jobs, arguments)}
      try:
        for future in concurrent.futures.as_completed(futures):
          finished(futures[future], *future.result())
      except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
  results = []
  for k, changes in enumerate(chosen):
    values = [scores[(k, seed)] for seed in seeds]
    results.append({"changes": changes, "scores": values, "mean": float(np.mean(values))})
  lower = spec["better"] == "lower"
  order = sorted(range(len(results)), key=lambda i: (np.isnan(results[i]["mean"]),
                 results[i]["mean"] if lower else -results[i]["mean"]))
  return {"task": task.path.stem, "budget": budget, "episodes": episodes, "seeds": seeds,
          "score": spec["score"], "better": spec["better"], "results": results,
          "best": results[order[0]]["changes"]}


def describe(changes):
  """A tuning change as one line: "section.key = value, ..."."""
  return ", ".join(f"{s}.{k} = {v}" for s, keys in changes.items() for k, v in keys.items())
