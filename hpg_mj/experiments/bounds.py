"""SPEC section 7.1: each benchmark task's published bounds, the random policy's
score and the best known one on the fixed greedy starts, and normalized scores
(0 = random, 100 = best known, as D4RL and Minari). `hpg_mj.benchmark` computes
the bounds (`hpg-mj bounds`) into `hpg_mj/benchmark_bounds.json`; this module
reads them, for the benchmark's scores and the experiments' reports alike."""
import json
import pathlib

TASKS = ("ship", "taxi_fuel", "taxi")
# SPEC section 11's task ladder: each task at each level, its bounds under
# "<task>/<level>" (`bounds_key`).
LADDER = ("ship_current", "ship_goal", "ship_regatta", "ship_harbour")
LEVELS = ("easy", "medium", "hard")
LADDER_KEYS = tuple(f"{name}/{level}" for name in LADDER for level in LEVELS)
KEYS = TASKS + LADDER_KEYS
# The scores normalized against the bounds (higher is better for each).
SCORES = {"ship": ("J", "gate_pass_rate"), "taxi_fuel": ("mean_return",),
          "taxi": ("mean_return",),
          **{key: ("mean_return", "finish_rate") if key.startswith("ship_regatta/")
             else ("J", "gate_pass_rate") for key in LADDER_KEYS}}
BOUNDS_FILE = pathlib.Path(__file__).resolve().parents[1] / "benchmark_bounds.json"

_LOADED = []


def bounds(task=None, level=None):
  """The published bounds: {"protocol": ..., "tasks": {task: {"random": metrics,
  "best": metrics, ...}}} (no tasks where the file is missing). With `task` (a name
  of `KEYS`, "ship_goal/easy", or a ladder task and its `level`), that task's entry
  alone: {"random": ..., "helmsman": ..., "best": ..., "reference": ...}."""
  if not _LOADED:
    _LOADED.append(json.loads(BOUNDS_FILE.read_text()) if BOUNDS_FILE.is_file() else
                   {"protocol": None, "tasks": {}})
  if task is None:
    if level is not None:
      raise ValueError(f"level={level!r} needs a task, one of {list(LADDER)}")
    return _LOADED[0]
  key = bounds_key(task, level)
  if key not in KEYS:
    hint = (f"; give a level of {list(LEVELS)}, e.g. {task}/easy" if task in LADDER
            else "")
    raise ValueError(f"bounds: no task {key!r}{hint}; allowed: {list(KEYS)}")
  entry = _LOADED[0]["tasks"].get(key)
  if entry is None:
    raise ValueError(f"bounds: {BOUNDS_FILE.name} holds no bounds of {key!r} "
                     "(`hpg-mj bounds --task` computes them)")
  return entry


def bounds_key(name, level=None):
  """The bounds' name of a task: "ship", or "<task>/<level>" on the ladder."""
  return name if level is None else f"{name}/{level}"


def task_name(agent):
  """The benchmark task an agent acts on ("ship", "taxi_fuel", "taxi", or a ladder task
  at its level, "ship_goal/hard"), or None (a subtask, a continuing agent). An agent whose record rows are control steps but
  whose scores are over the task's episodes (`per_episode_scores`, the SB3 agents)
  acts on the task."""
  if getattr(agent, "record_steps", None) is not None and \
      not getattr(agent, "per_episode_scores", False):
    return None
  env = getattr(getattr(agent, "config", None), "environment", None)
  world = getattr(env, "world", None)
  if world == "ship" and hasattr(env, "out_of_bounds_reward"):
    return "ship"
  if world == "taxi":
    return "taxi_fuel" if env.fuel else "taxi"
  if world in LADDER and getattr(env, "level", None) in LEVELS:
    return bounds_key(world, env.level)
  return None


def normalize(task, score, value, published=None):
  """One value of `score` on `task` normalized: 100 (value - random) / (best known -
  random); None without published bounds or a value. Linear, so an interval's
  ends normalize to the normalized interval."""
  entry = (published or bounds())["tasks"].get(task) if task is not None else None
  if entry is None or value is None:
    return None
  low, high = entry["random"][score], entry["best"][score]
  return None if low is None or high is None or high == low else \
      100.0 * (value - low) / (high - low)


def normalized(task, metrics, published=None):
  """{"<score>_normalized": `normalize(...)`} for the scores of `SCORES[task]` in
  `metrics` (`task` a name of `KEYS`: "ship", "ship_goal/hard", ...); empty for no
  task (None) or where no bounds are published."""
  if task is None or (published or bounds())["tasks"].get(task) is None:
    return {}
  return {f"{score}_normalized": normalize(task, score, metrics.get(score), published)
          for score in SCORES[task]}
