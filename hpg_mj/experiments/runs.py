"""One (task, seed) run of an experiment: trained in chunks, its metrics written as
it goes, its whole training state checkpointed atomically, resumed exactly.

A run folder (`OUT/<experiment>/<task>/seed<k>/`) holds:

    progress.csv          one row per chunk of episodes (`agents.chunks`), flushed:
                          episodes, wall_seconds, episodes_per_second and the
                          chunk's figure (gate_pass_rate or mean_return)
    checkpoints/ep<N>/    the agent after N episodes with its record so far
                          (`agents.save`, uncompressed); the newest two
                          are kept
    events.log            what happened to the run: started, resumed from
                          episode N, a damaged checkpoint set aside
    run.lock              held (flock) by the process writing the run
                          (`hpg_mj.experiments.locks`)
    record.npy            the per-episode record       } written when the run
    agent/                the final agent (`hpg-mj     } finishes; metrics.json
                          evaluate`, `render --agent`)  } last, and a run with
    greedy.npy            the final agent's greedy     } (SPEC section 7)
                          episodes from the fixed start
                          set (`Agent.evaluate_fixed`)
    metrics.json          metrics over the last 1,000   } it is never run again
                          episodes (online), "greedy":
                          the same over greedy.npy,
                          "greedy_curve" (below), and
                          what made them (`hpg_mj.provenance`)
    greedy_curve.jsonl    with `greedy_at` (an experiment's sample-efficiency
                          curve): one line per point, the greedy metrics on the
                          fixed starts after that many episodes (record rows),
                          with the control (primitive) steps trained so far; the
                          last line is the finished run's "greedy"

A checkpoint is written to `checkpoints/.tmp-ep<N>` and renamed into place, so a
run killed at any moment leaves either the new checkpoint whole or none of it.
Resuming loads the newest checkpoint; one that does not load (its SHA-256 or its
archive does not check out) is reported in events.log and on stderr, renamed to
`damaged-ep<N>`, and the run resumes from the one before it (or from the start).
The saved state is the agent's whole training state (parameters, traces, the
generator, counters), so a resumed run ends bit-identical to one never stopped.
A greedy point neither learns nor draws from the agent's generator
(`Agent.evaluate_fixed`), so a run with points ends as one without them; a resumed
run keeps the points up to its checkpoint and measures the later ones again.
"""
import json
import os
import pathlib
import shutil
import sys
import time

import numpy as np

from hpg_mj import _compiling
from hpg_mj import agents
from hpg_mj import provenance
from hpg_mj.agents import base
from hpg_mj import storage
from hpg_mj.experiments import bounds
from hpg_mj.experiments import locks

CHECKPOINT_EVERY = 25000    # a killed 50,000-episode ship run loses at most ~5 s of training
KEEP_CHECKPOINTS = 2
GREEDY_STARTS = base.GREEDY_STARTS     # SPEC section 7: the fixed seeded set of starts
PROGRESS_COLUMNS = ("episodes", "wall_seconds", "episodes_per_second")


class RunInterrupted(Exception):
  """Raised by `run(stop_after=...)`: the run stopped as if killed (for tests)."""


def is_finished(run_dir):
  """Whether the run in `run_dir` finished (it wrote its metrics.json)."""
  return (pathlib.Path(run_dir) / "metrics.json").is_file()


def read_metrics(run_dir):
  """A finished run's metrics.json, or a ValueError that names the damaged file."""
  path = pathlib.Path(run_dir) / "metrics.json"
  try:
    metrics = json.loads(path.read_text())
  except (json.JSONDecodeError, UnicodeDecodeError) as err:
    raise ValueError(f"{path} is damaged ({err}); delete {path.parent} to run it "
                     f"again") from None
  if not isinstance(metrics, dict) or not isinstance(metrics.get("episodes"), int):
    raise ValueError(f"{path} is not a run's metrics (it has no episode count); delete "
                     f"{path.parent} to run it again")
  return metrics


def _log(run_dir, message, stderr=False):
  line = f"{time.strftime('%Y-%m-%d %H:%M:%S')} {message}"
  with open(pathlib.Path(run_dir) / "events.log", "a") as f:
    f.write(line + "\n")
  if stderr:
    print(f"{run_dir}: {message}", file=sys.stderr)


def resumed(run_dir):
  """Whether the run's latest start (its events.log) resumed from a checkpoint."""
  path = pathlib.Path(run_dir) / "events.log"
  if not path.exists():
    return False
  starts = [line for line in path.read_text().splitlines()
            if " started seed " in line or " resumed from checkpoint " in line]
  return bool(starts) and " resumed from checkpoint " in starts[-1]


def _checkpoints(run_dir):
  """The checkpoint folders, newest first."""
  folder = pathlib.Path(run_dir) / "checkpoints"
  found = [p for p in folder.glob("ep*") if p.is_dir() and p.name[2:].isdigit()]
  return sorted(found, key=lambda p: int(p.name[2:]), reverse=True)


def _steps(records):
  """Control (primitive) steps trained so far: every record has "steps"."""
  return int(sum(float(r["steps"].sum()) for r in records))


def _write_checkpoint(agent, record, run_dir, done, wall, compiled):
  folder = pathlib.Path(run_dir) / "checkpoints"
  tmp = folder / f".tmp-ep{done}"
  if tmp.exists():
    shutil.rmtree(tmp)
  # Uncompressed: a checkpoint lives until the next but one, and deflating the mostly
  # zero traces took longer than writing them (0.4 s of 0.5 s for the actor-critic).
  agents.save(agent, tmp, record, {"episodes_done": done, "wall_seconds": wall,
                                   "compile_seconds": compiled}, compress=False)
  os.replace(tmp, folder / f"ep{done}")
  for old in _checkpoints(run_dir)[KEEP_CHECKPOINTS:]:
    shutil.rmtree(old)


def _resume(task, seed, run_dir):
  """(agent, records, episodes done, wall seconds, of them compiling) from the newest
  good checkpoint, or a fresh agent."""
  folder = pathlib.Path(run_dir) / "checkpoints"
  for tmp in folder.glob(".tmp-*"):        # a checkpoint whose writing was cut short
    shutil.rmtree(tmp)
  for path in _checkpoints(run_dir):
    try:
      agent, record, meta = agents.load(path)
      done = int(meta["episodes_done"])
      if record is None or len(record) != done or agent.seed != seed:
        raise storage.AgentFileError(f"{path}: holds {None if record is None else len(record)} "
                                     f"episodes of seed {agent.seed}, expected {done} of {seed}")
    except (storage.AgentFileError, KeyError, ValueError) as err:
      aside = path.with_name("damaged-" + path.name)
      if aside.exists():
        shutil.rmtree(aside)
      os.replace(path, aside)
      _log(run_dir, f"damaged checkpoint {path.name} set aside as {aside.name}: {err}",
           stderr=True)
      continue
    _log(run_dir, f"resumed from checkpoint {path.name} (episode {done})")
    return (agent, [record], done, float(meta.get("wall_seconds", 0.0)),
            float(meta.get("compile_seconds", 0.0)))
  agent = agents.build(task, seed)
  _log(run_dir, f"started seed {seed}")
  return agent, [], 0, 0.0, 0.0


class _ProgressFile:
  """progress.csv, cut back to the episodes a resumed run really has."""

  def __init__(self, run_dir, key, done):
    self.path = pathlib.Path(run_dir) / "progress.csv"
    header = ",".join(PROGRESS_COLUMNS + (key,))
    keep = []
    if done and self.path.is_file():
      for line in self.path.read_text().splitlines()[1:]:
        fields = line.split(",")
        if len(fields) == len(PROGRESS_COLUMNS) + 1 and fields[0].isdigit() and int(fields[0]) <= done:
          keep.append(line)
    tmp = self.path.with_name("progress.csv.tmp")
    tmp.write_text("\n".join([header] + keep) + "\n")
    os.replace(tmp, self.path)
    self.file = open(self.path, "a")

  def write(self, done, wall, rate, value):
    self.file.write(f"{done},{wall:.3f},{rate:.1f},{value:.6g}\n")
    self.file.flush()

  def close(self):
    self.file.close()


class _GreedyCurve:
  """greedy_curve.jsonl, cut back to the points a resumed run really has."""

  def __init__(self, run_dir, done):
    self.path = pathlib.Path(run_dir) / "greedy_curve.jsonl"
    self.points = []
    if done and self.path.is_file():
      for line in self.path.read_text().splitlines():
        try:
          point = json.loads(line)
        except json.JSONDecodeError:        # a line cut short by a kill
          continue
        if isinstance(point, dict) and isinstance(point.get("episodes"), int) and \
            point["episodes"] <= done:
          self.points.append(point)
    tmp = self.path.with_name("greedy_curve.jsonl.tmp")
    tmp.write_text("".join(json.dumps(p) + "\n" for p in self.points))
    os.replace(tmp, self.path)

  def add(self, point):
    self.points.append(point)
    with open(self.path, "a") as f:
      f.write(json.dumps(point) + "\n")


def _greedy_scores(agent, greedy):
  """The greedy metrics on the fixed starts (SPEC section 7), normalized too (7.1)."""
  scores = dict(agent.metrics(greedy), starts=GREEDY_STARTS, start_seed=base.GREEDY_SEED)
  scores.update(bounds.normalized(bounds.task_name(agent), scores))
  return scores


def read_progress(run_dir):
  """(episodes done, latest figure) from a run's progress.csv; (0, None) if none yet."""
  path = pathlib.Path(run_dir) / "progress.csv"
  try:
    lines = path.read_text().splitlines()
  except OSError:
    return 0, None
  for line in reversed(lines[1:]):
    fields = line.split(",")
    if len(fields) == len(PROGRESS_COLUMNS) + 1 and fields[0].isdigit():
      try:
        return int(fields[0]), float(fields[-1])
      except ValueError:
        continue
  return 0, None


def run(task_path, seed, episodes, run_dir, checkpoint_every=CHECKPOINT_EVERY, stop_after=None,
        wait=True, command=None, greedy_at=()):
  """Trains one (task, seed) run to `episodes`, resuming from its checkpoints;
  returns its metrics. A finished run is not run again. `greedy_at`: episode
  counts (below `episodes`) after which the agent is also measured greedily on
  the fixed starts (greedy_curve.jsonl).

  The run folder is locked meanwhile (`locks`): a run that another process holds
  is waited for (its metrics returned once it has finished them), or, with
  `wait=False`, refused with `locks.RunLocked` naming the holder. `command` is
  the command line written into the lock for the next one to read.
  """
  run_dir = pathlib.Path(run_dir)
  if is_finished(run_dir):
    return read_metrics(run_dir)
  if checkpoint_every < 1:
    raise ValueError(f"checkpoint_every must be a positive number of episodes, got "
                     f"{checkpoint_every}")
  with locks.hold(run_dir, wait=wait, command=command):
    if is_finished(run_dir):            # finished by the process we waited for
      return read_metrics(run_dir)
    return _run_locked(task_path, seed, episodes, run_dir, checkpoint_every, stop_after,
                       greedy_at)


def _run_locked(task_path, seed, episodes, run_dir, checkpoint_every, stop_after, greedy_at):
  task = agents.load_task(task_path)
  (run_dir / "checkpoints").mkdir(parents=True, exist_ok=True)
  agent, records, done, wall, compiled = _resume(task, seed, run_dir)
  compiling = []                      # numba's and XLA's compile seconds in this process's chunks
  if done > episodes:
    raise ValueError(f"{run_dir}: its checkpoint is at episode {done}, past the {episodes} "
                     f"episodes asked for; use another output folder")
  progress = _ProgressFile(run_dir, agent.figure, done)
  curve = _GreedyCurve(run_dir, done) if greedy_at else None
  # An agent whose rows are dear (e.g. hpg_mj.agents.sb3's) asks for checkpoints at
  # least every `checkpoint_rows` rows.
  checkpoint_every = min(checkpoint_every, agent.checkpoint_rows or checkpoint_every)
  # Training stops at each greedy point still to come (chunks never cross one).
  stops = sorted({p for p in greedy_at if done < p < episodes} | {episodes})
  try:
    with _compiling.timer(compiling.append, _compiling.uses_jax(agent)):
      for stop in stops:
        for now, record, seconds in agents.chunks(agent, stop, done=done,
                                                  every=checkpoint_every):
          n, done = now - done, now
          records.append(record)
          wall += seconds
          progress.write(done, wall, n / max(seconds, 1e-9),
                         next(iter(agent.progress(record).values())))
          if curve is not None and done == stop < episodes:   # before its checkpoint
            before = len(compiling)
            curve.add({"episodes": done, "steps": _steps(records),
                       **_greedy_scores(agent, agent.evaluate_fixed(GREEDY_STARTS))})
            del compiling[before:]     # its compiles are not in `wall`, the chunks' time
          if done % checkpoint_every == 0 and done < episodes:
            records = [np.concatenate(records)]
            _write_checkpoint(agent, records[0], run_dir, done, wall, compiled + sum(compiling))
          if stop_after is not None and done >= stop_after and done < episodes:
            raise RunInterrupted(f"stopped at episode {done}")
  finally:
    progress.close()
  compiled += sum(compiling)
  record = np.concatenate(records)
  metrics = agent.metrics(record)
  # SPEC section 7: the final agent, greedy, without learning, on the fixed starts;
  # 7.1: every score also normalized (0 = random, 100 = best known).
  greedy = agent.evaluate_fixed(GREEDY_STARTS)
  metrics["greedy"] = _greedy_scores(agent, greedy)
  metrics.update(bounds.normalized(bounds.task_name(agent), metrics))
  if curve is not None:
    curve.add({"episodes": episodes, "steps": _steps(records), **metrics["greedy"]})
    metrics["greedy_curve"] = curve.points
  metrics.update({"task": task.path.stem, "seed": seed, "episodes": episodes,
                  # wall = compile + train: numba's and XLA's compiling apart (numba's 0
                  # once cached), so that a speed is computed from train_seconds
                  "wall_seconds": round(wall, 3), "compile_seconds": round(compiled, 3),
                  "train_seconds": round(wall - compiled, 3),
                  "provenance": provenance.collect(task.text, seed)})
  agent_dir = run_dir / "agent"
  if agent_dir.exists():
    shutil.rmtree(agent_dir)
  agents.save(agent, agent_dir, record, {"metrics": metrics})
  for name, array in (("record", record), ("greedy", greedy)):
    tmp = run_dir / f"{name}.npy.tmp"
    with open(tmp, "wb") as f:
      np.save(f, array)
    os.replace(tmp, run_dir / f"{name}.npy")
  tmp = run_dir / "metrics.json.tmp"
  tmp.write_text(json.dumps(metrics, indent=2) + "\n")
  os.replace(tmp, run_dir / "metrics.json")     # written last: the run is finished
  shutil.rmtree(run_dir / "checkpoints")
  _log(run_dir, f"finished {episodes} episodes in {wall:.1f} s of training")
  return metrics
