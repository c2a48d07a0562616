"""`hpg-mj bench envs`: environment steps per second, side by side in one run.

Speed is measured here, in a command that prints figures, never in tests.
"""
import time

import numpy as np

from hpg_mj.worlds import ship_core as core


def _rate(steps, seconds):
  return steps / seconds if seconds > 0 else float("inf")


def _timed(fn, min_seconds, warm_up=True):
  """Calls `fn()` (which returns the steps it took) until `min_seconds` have passed,
  after a first call (`warm_up`: compile, allocate, fill caches) left out."""
  if warm_up:
    fn()
  steps, start = 0, time.perf_counter()
  while True:
    steps += fn()
    elapsed = time.perf_counter() - start
    if elapsed >= min_seconds:
      return _rate(steps, elapsed)


def bench_analytic_single(min_seconds):
  """Analytic Euler steps per second of one ship (`ship_core.euler_run`), timed for at
  least `min_seconds`."""
  state = np.array([500.0, 500.0, 10.0, 0.0])
  n = 5_000_000

  def run():
    state[:] = (500.0, 500.0, 10.0, 0.0)
    core.euler_run(state, 3.0, n)
    return n
  return _timed(run, min_seconds)


def bench_analytic_batch(min_seconds, ships=1024, controls=200):
  """Analytic Euler steps per second of `ships` ships stepped together
  (`ship_core.euler_batch`) over `controls` control steps, timed for at least
  `min_seconds`."""
  rng = np.random.default_rng(0)
  states = np.column_stack([rng.uniform(0, 1000, ships), rng.uniform(0, 1000, ships),
                            rng.uniform(-180, 180, ships), rng.uniform(-15, 15, ships)])
  r = rng.uniform(-15, 15, ships)
  samples = np.empty((ships, core.SAMPLES_PER_CONTROL + 1, 2))

  def run():
    for _ in range(controls):
      core.euler_batch(states, r, samples)
    return ships * controls * core.SAMPLES_PER_CONTROL
  return _timed(run, min_seconds)


def bench_current_batch(min_seconds, level="hard", ships=1024, controls=200):
  """`bench_analytic_batch` for the ship in a current: the same starts and turning
  rates, every ship sailing (`ship_current_core.drift_batch`)."""
  from hpg_mj.worlds import ship_current_core as current_core
  rng = np.random.default_rng(0)
  states = np.column_stack([rng.uniform(0, 1000, ships), rng.uniform(0, 1000, ships),
                            rng.uniform(-180, 180, ships), rng.uniform(-15, 15, ships)])
  r = rng.uniform(-15, 15, ships)
  samples = np.empty((ships, core.SAMPLES_PER_CONTROL + 1, 2))
  active = np.ones(ships, dtype=np.bool_)
  field = current_core.level_field(level)

  def run():
    for _ in range(controls):
      current_core.drift_batch(states, r, active, samples, field)
    return ships * controls * core.SAMPLES_PER_CONTROL
  return _timed(run, min_seconds)


def _dm_stepper(env, actions, chunk=2000):
  """A function that steps the dm_control `env` `chunk` times through `actions` in turn
  (reset at each end) and returns the steps it took."""
  env.reset()
  n = len(actions)

  def run():
    for i in range(chunk):
      if env.step(actions[i % n]).last():
        env.reset()
    return chunk
  return run


def _gym_stepper(env, actions, chunk=2000):
  env.reset(seed=0)
  n = len(actions)

  def run():
    for i in range(chunk):
      _, _, terminated, truncated, _ = env.step(actions[i % n])
      if terminated or truncated:
        env.reset()
    return chunk
  return run


def _vector_stepper(env, actions, chunk=200):
  """Control (or primitive) steps of a vector env: copies x batch steps."""
  env.reset(seed=0)
  n = len(actions)

  def run():
    for i in range(chunk):
      env.step(actions[i % n])
    return chunk * env.num_envs
  return run


def _interleaved(reference, run, min_seconds, rounds=5):
  """(`run`'s steps per second, its speed over `reference`'s, a warm function): the two
  timed in turn, `rounds` times (one where `min_seconds` is under a second), each for
  `min_seconds / rounds`; the medians of `run`'s rates and of each round's ratio. A
  ratio of two rates measured apart moves with the machine's speed, which drifts by the
  minute (20-30% by the hour here)."""
  rounds = rounds if min_seconds >= 1.0 else 1
  run()                                   # warm up, once
  rates, ratios = [], []
  for _ in range(rounds):
    against = _timed(reference, min_seconds / rounds, warm_up=False)
    rates.append(_timed(run, min_seconds / rounds, warm_up=False))
    ratios.append(rates[-1] / against if against else float("inf"))
  return float(np.median(rates)), float(np.median(ratios))


# The ladder's rows of `bench_envs`, each measured in turn with the steering task's
# same row (SPEC section 11: each task's analytic batch and MuJoCo backend at least half
# the steering task's).
_LADDER_DOMAINS = ("ship_current", "ship_goal", "ship_regatta", "ship_harbour")
_LADDER_IDS = ("ShipCurrent", "ShipGoal", "ShipRegatta", "ShipHarbour")


def bench_envs(min_seconds=1.0):
  """Rows of (name, unit, steps per second), a ladder task's with a fourth: its speed
  over the steering task's same row, timed in turn with it (`_interleaved`)."""
  import gymnasium

  import hpg_mj  # noqa: F401  (registers the ids)
  from hpg_mj import suite

  rows = []
  rows.append(("analytic ship, one ship (compiled)", "0.2 s steps/s",
               bench_analytic_single(min_seconds)))
  rows.append(("analytic ship, batch of 1024 (compiled)", "0.2 s steps/s",
               bench_analytic_batch(min_seconds)))
  rows.append(("analytic ship in the hard current, batch of 1024 (compiled)", "0.2 s steps/s",
               bench_current_batch(min_seconds)))

  def ladder_rows(name_of, steering, stepper_of, unit="control steps/s"):
    for domain, env_id in zip(_LADDER_DOMAINS, _LADDER_IDS):
      rate, ratio = _interleaved(steering, stepper_of(domain, env_id), min_seconds)
      rows.append((name_of(domain, env_id), unit, rate, ratio))

  action = [np.array([5.0])]
  steering = _dm_stepper(suite.load("ship", "steer", {"random": 0}), action)
  rows.append(("dm_control ship steer (MuJoCo)", "control steps/s",
               _timed(steering, min_seconds)))
  ladder_rows(lambda domain, _: f"dm_control {domain} hard (MuJoCo)", steering,
              lambda domain, _: _dm_stepper(suite.load(domain, "hard", {"random": 0}), action))
  ship_actions = [np.array([r]) for r in np.random.default_rng(0).uniform(-15, 15, 97)]
  for backend in ("mujoco", "analytic"):   # as a user gets it: with gymnasium.make's wrappers
    env = gymnasium.make("hpg_mj/ShipSteering-v0", backend=backend)
    rows.append((f"Gymnasium ShipSteering-v0 backend={backend} (gymnasium.make)",
                 "control steps/s", _timed(_gym_stepper(env, ship_actions), min_seconds)))
  # Native batches (hpg_mj.envs.vector), random actions, autoreset NextStep.
  rng = np.random.default_rng(0)
  for backend, ships, chunk, how in (("analytic", 1024, 200, ""), ("mujoco", 16, 20, " (loop)")):
    actions = rng.uniform(-15, 15, (97, ships, 1))
    steering = _vector_stepper(gymnasium.make_vec("hpg_mj/ShipSteering-v0", ships,
                                                  backend=backend), actions, chunk)
    rows.append((f"Gymnasium ShipSteering-v0 {backend}, make_vec batch of {ships}{how}",
                 "control steps/s", _timed(steering, min_seconds)))
    ladder_rows(   # the ladder's, hardest
        lambda _, env_id: f"Gymnasium {env_id}-v0 hard {backend}, make_vec batch of {ships}{how}",
        steering,
        lambda _, env_id: _vector_stepper(gymnasium.make_vec(
            f"hpg_mj/{env_id}-v0", ships, level="hard", backend=backend), actions, chunk))
  env = gymnasium.make_vec("hpg_mj/TaxiFuel-v0", 1024)
  rows.append(("Gymnasium TaxiFuel-v0, make_vec batch of 1024", "primitive steps/s",
               _timed(_vector_stepper(env, rng.integers(0, 7, (101, 1024))), min_seconds)))
  for task in ("fuel", "classic"):
    n_actions = 7 if task == "fuel" else 6
    env = suite.load("taxi", task, {"random": 0})
    actions = np.random.default_rng(0).integers(0, n_actions, 101)
    rows.append((f"dm_control taxi {task}", "primitive steps/s",
                 _timed(_dm_stepper(env, actions), min_seconds)))
  for env_id, n_actions in (("hpg_mj/TaxiFuel-v0", 7), ("hpg_mj/Taxi-v0", 6), ("Taxi-v4", 6)):
    env = gymnasium.make(env_id).unwrapped
    actions = [int(a) for a in np.random.default_rng(0).integers(0, n_actions, 101)]
    rows.append((f"Gymnasium {env_id}", "primitive steps/s",
                 _timed(_gym_stepper(env, actions), min_seconds)))
  return rows


def format_rows(rows):
  """The table `hpg-mj bench envs` prints: one line per (name, unit, steps per
  second) row; a ladder task's row (a fourth item) also gives its speed over the
  steering task's same row, measured in turn with it (`_interleaved`)."""
  width = max(len(row[0]) for row in rows)
  lines = [f"{'':<{width}}  {'steps per second':>18}  unit"]
  for name, unit, rate, *over_steering in rows:
    line = f"{name:<{width}}  {rate:>18,.0f}  {unit}"
    if over_steering:
      line += f" (x{over_steering[0]:.2f} the steering task's, interleaved)"
    lines.append(line)
  return "\n".join(lines)


def bench_task(path, min_seconds=2.0, assignments=()):
  """One task file's agent (a shipped one, or a user's; with `assignments` set as
  `hpg-mj train --set` sets them) on its compiled path, learning: {task, unit,
  compile_seconds, train_seconds, steps, steps_per_second}. The first call, one
  episode, is timed apart: it holds numba's compiling (or loading from its cache); the
  speed is over at least `min_seconds` of training after it."""
  from hpg_mj import agents

  task = agents.load_task(path, assignments)
  agent = agents.build(task, seed=0)
  unit = "primitive steps/s" if task.section("environment")["world"] == "taxi" else \
      "control steps/s"                    # the ship's tasks, the ladder's among them
  chunk = 1000
  if agent.record_steps:                   # a continuing agent: rows of an hour each
    chunk = 20
  start = time.perf_counter()
  agent.train(1, "analytic")                          # compile (or load), one episode
  compile_seconds = time.perf_counter() - start
  steps, start = 0, time.perf_counter()
  n = 10
  # An agent that learns in whole updates (hpg_mj.agents.jax_ppo) may train past the
  # rows asked for: its own count of control steps trained, where it keeps one.
  trained = lambda: getattr(agent, "control_steps", None)  # noqa: E731
  before = trained()
  while time.perf_counter() - start < min_seconds:
    steps += int(agent.train(n, "analytic")["steps"].sum())
    n = min(2 * n, chunk)
  if before is not None:
    steps = trained() - before
  seconds = time.perf_counter() - start
  return {"task": task.path.stem, "unit": unit, "compile_seconds": compile_seconds,
          "train_seconds": seconds, "steps": steps, "steps_per_second": _rate(steps, seconds)}


def bench_rounds(tasks, min_seconds=2.0, rounds=1, assignments=()):
  """`bench_task` of each task file (with `assignments`) in `rounds` interleaved rounds
  (the order reversed every other round, so that all see the same machine load): a row
  per task file, the median round's whole (the lower middle of an even count), so that
  its `steps_per_second` is its steps over its seconds, with `median_round` (0-based)
  and `rounds_steps_per_second` each round's."""
  rows = {path: [] for path in tasks}
  for r in range(rounds):
    for path in (tasks if r % 2 == 0 else tasks[::-1]):
      rows[path].append(bench_task(path, min_seconds, assignments))
  out = []
  for each in rows.values():
    rates = [row["steps_per_second"] for row in each]
    median = sorted(range(len(rates)), key=rates.__getitem__)[(len(rates) - 1) // 2]
    out.append({**each[median], "median_round": median, "rounds_steps_per_second": rates})
  return out


def bench_train(min_seconds=2.0, tasks=None, rounds=1, assignments=()):
  """Rows of (name, unit, steps per second): every shipped task file's agent (or the
  task files `tasks`, each with `assignments`) on its compiled path, learning, and, for
  the shipped set, the stand-alone subtasks and the hybrid step by step through
  dm_control. The task files `tasks` are measured in `rounds` interleaved rounds (the
  order reversed every other round, so that all see the same machine load), each row
  the median."""
  from hpg_mj import agents

  if tasks:
    return [(f"{row['task']}, learning" + (f", median of {rounds} rounds" if rounds > 1
                                            else ""), row["unit"], row["steps_per_second"])
            for row in bench_rounds(tasks, min_seconds, rounds, assignments)]
  rows = []
  for path in agents.shipped_tasks().values():
    if "stable-baselines3" in agents.lookup(agents.load_task(path).kind).tags:
      continue                 # scripts/sb3_speed.py measures those, with the sb3 extra
    row = bench_task(path, min_seconds)
    rows.append((f"{row['task']}, compiled, learning", row["unit"], row["steps_per_second"]))

  # The stand-alone subtasks with the learned exploration width (SPEC section 8).
  from hpg_mj.hierarchy import ship_subtask
  for task in ship_subtask.TASKS:
    ship_subtask.train_subtask(task, 5, 0, width_alpha=0.003)         # compile, warm up
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < min_seconds:
      steps += int(ship_subtask.train_subtask(task, 1000, 0, width_alpha=0.003)["steps"].sum())
    rows.append((f"ship {task} subtask, learned width, compiled, learning", "control steps/s",
                 _rate(steps, time.perf_counter() - start)))

  agent = agents.build(agents.load_task("ship_hybrid"), seed=0)
  # The plain dm_control task (its -100 for leaving; the speed does not depend on
  # it): `agent.make_env("dm_control")` passes the task file's rewards, which the
  # suite's `steer` does not take yet.
  from hpg_mj import suite
  env = suite.load("ship", "steer", {"random": 0})
  agent.train_stepwise(env, 2)
  steps, start = 0, time.perf_counter()
  while time.perf_counter() - start < min_seconds:
    steps += int(agent.train_stepwise(env, 5)["steps"].sum())
  rows.append(("ship hybrid, step by step through dm_control (MuJoCo)", "control steps/s",
               _rate(steps, time.perf_counter() - start)))
  return rows
