"""Issue 24, item 1: the loop a greedy average-reward root settles into on the
continuing ship task, and what holds it there.

  .venv/bin/python scripts/patrol_loop.py --seeds 2 [--root '{...}'] [--rollouts 20]
  .venv/bin/python scripts/patrol_loop.py --seeds 5004 --episodic    # the episodic hybrid

For each seed, tasks/ship_patrol_average_reward.toml's agent trains on its
protocol (`[root]` keys replaced by the JSON object given; in blocks of 100 hours,
the same process, to see when each Q(s, a) last moved), then sails 100 greedy
hours from the evaluation's start (`ShipPatrol.evaluation`) and prints:

- the learned gain rho (reward per control step, and as gates an hour), the
  online gates an hour of the last 125 training hours, epsilon at the end;
- where the greedy hours go: the (root state, direction) pairs with the largest
  share of the control steps, their steps, gate passes and subtask successes per
  call, and the training hour their Q(s, a) last moved;
- the loop, if the last 600 calls repeat with a period: its calls, steps and
  gates an hour; in each of its root states Q(s, .), and the backup's target with
  today's rho against the value that holds (a large gap: a stale value);
- rollouts: from the ship's state at each of the loop's calls, every first
  direction sailed, then the greedy root, for `--horizon` control steps, the
  subtasks steered as in training (sampled, `--rollouts` times) and as in the
  evaluation (their mean, once): the reward over the horizon minus the greedy
  choice's (a positive number: a direction that earns more than the greedy one
  from this very state), and the first call's subtask success;
- the subtasks' success over their last 1,000 runs (what holds epsilon) and over
  the last 125 training hours.

With --episodic, the episodic hybrid (the task file's [comparison] episodic_task,
trained on its own protocol with the seed) is sailed instead, its root's cell-only
table of discounted values in place of Q.

Seeds looked at before: 100-119 (the design before), 4001-4009 and 5000-5009
(issue 24); 4004 and 5004 were used for this diagnosis. Tune only on 0-9
(scripts/patrol_tuning.py).
"""
import argparse
import dataclasses
import json

import numba
import numpy as np

from hpg_mj import agents
from hpg_mj.agents import _ship
from hpg_mj.agents import ship_patrol as sp
from hpg_mj.hierarchy import ship_rules as rules
from hpg_mj.learners import policies
from hpg_mj.learners import qlambda
from hpg_mj.learners import rng
from hpg_mj.learners import tiles
from hpg_mj.worlds import ship_core as core

# Columns of one recorded call.
X, Y, HEADING, STATE, ACTION, STEPS, REWARD, G_EVENT, L_EVENT, RATE = range(10)


def _scratch(tiling):
  n = tiling.offsets.shape[0]
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  return (np.empty(n, dtype=np.int64), np.empty(n), samples, np.empty_like(samples),
          np.empty(4), np.empty(2))


class Sailing:
  """What `sail_calls` needs of an agent: its local tiles, its subtasks' max steps and
  the task's rewards."""

  def __init__(self, agent):
    self.tiling = agent.coder.arrays()
    self.s = (int(agent.config.low_level.max_steps), float(agent.config.environment.gate_reward),
              float(agent.config.environment.out_of_bounds_reward))


@numba.njit
def run_call(state, direction, trace, values, tiling, s, sample, rng_state, scratch):
  """One call of a low-level subtask from `state` (in place), its policy only (no
  learning; the machine's LocalGoal end, cut by a gate pass or a departure):
  (global event, local event, reward to the root, control steps)."""
  max_steps, gate_reward, out_of_bounds_reward = s
  tiles_, psi, samples, local_samples, local, origin = scratch
  origin[0], origin[1] = state[0], state[1]
  core.global_to_local(state, origin, direction, local)
  reward_root, k = 0.0, 0
  while True:
    tiles.active_tiles(local, tiling, tiles_)
    r = policies.gaussian_choose(trace, values, tiles_, psi, 0.0, 0.0, core.MAX_TURN_RATE,
                                 False, sample, rng_state)
    core.euler_control(state, r, samples)
    k += 1
    g, reward = core.global_outcome(samples, gate_reward, out_of_bounds_reward)
    reward_root += reward
    l, _ = core.low_level_outcome(samples, state, origin, direction, k, local_samples, local,
                                  max_steps)
    if g != core.NO_EVENT or l != core.NO_EVENT:
      return g, l, reward_root, k


@numba.njit
def sail_calls(ship, q, low, tiling, s, view, sample_low, rng_state, first, max_steps, out,
               scratch):
  # (`s`: Sailing.s)
  """Greedy root calls from `ship` (in place) until `max_steps` control steps or
  `out` is full; the first call is `first` when >= 0. Returns the calls made."""
  diagonal, diagonal_values, straight, straight_values = low
  sectors, near_m, near_cell_m = view
  steps = 0
  i = 0
  while steps < max_steps and i < out.shape[0]:
    state = rules.root_state(ship, sectors, near_m, near_cell_m)
    # epsilon 0 through epsilon_greedy: the generator's draws are the evaluation's.
    a = first if (i == 0 and first >= 0) else qlambda.epsilon_greedy(
        q, state, rules.N_DIRECTIONS, 0.0, rng_state)
    row = out[i]
    row[0], row[1], row[2], row[9] = ship[0], ship[1], ship[2], ship[3]
    trace, values = ((diagonal, diagonal_values) if rules.subtask_of(a) == rules.DIAGONAL
                     else (straight, straight_values))
    g, l, reward, k = run_call(ship, a, trace, values, tiling, s, sample_low, rng_state, scratch)
    row[3], row[4], row[5], row[6], row[7], row[8] = state, a, k, reward, g, l
    if g == core.FAILURE:
      _ship.sample_start(rng_state, ship)
    steps += k
    i += 1
  return i


def period(pairs):
  """The shortest p with all of `pairs` ((state, action) of the last calls)
  repeating with period p (p at most a third of them), or None."""
  for p in range(1, len(pairs) // 3 + 1):
    if all(pairs[i] == pairs[i + p] for i in range(len(pairs) - p)):
      return p
  return None


def describe(state, view):
  """(cell, sector) of a root state in words (`ship_rules.root_state`)."""
  sectors, near_m, near_cell_m = view
  cell, sector = divmod(int(state), sectors)
  if cell < rules.ROOT_GRID ** 2:
    i, j = divmod(cell, rules.ROOT_GRID)
    where = f"cell ({i * 50}-{i * 50 + 50} m, {j * 50}-{j * 50 + 50} m)"
  else:
    side = int(round(2.0 * near_m / near_cell_m))
    i, j = divmod(cell - rules.ROOT_GRID ** 2, side)
    x0 = 0.5 * (core.GATE[0, 0] + core.GATE[1, 0]) - near_m + i * near_cell_m
    y0 = 0.5 * (core.GATE[0, 1] + core.GATE[1, 1]) - near_m + j * near_cell_m
    where = f"near-gate cell ({x0:.0f}-{x0 + near_cell_m:.0f} m, {y0:.0f}-{y0 + near_cell_m:.0f} m)"
  return where + (f" sector {sector}" if sectors > 1 else "")


def main():
  p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  p.add_argument("--seeds", default="2")
  p.add_argument("--root", default="{}", help="JSON object of [root] keys to replace")
  p.add_argument("--task", default="ship_patrol_average_reward")
  p.add_argument("--episodic", action="store_true",
                 help="the episodic hybrid (its task file, this seed) sailed greedily instead")
  p.add_argument("--rollouts", type=int, default=20, help="sampled rollouts per direction")
  p.add_argument("--horizon", type=int, default=3000, help="control steps per rollout")
  args = p.parse_args()
  task = agents.load_task(args.task)
  overrides = json.loads(args.root)
  config = dataclasses.replace(task.config,
                               root=dataclasses.replace(task.config.root, **overrides))
  low_seed, _, high_seed = args.seeds.partition("-")
  for seed in range(int(low_seed), int(high_seed or low_seed) + 1):
    agent = agents.lookup(task.kind)(config, seed=seed, task=task)
    if args.episodic:
      episodic_task = agents.load_task(config.comparison.episodic_task)
      episodic, _, _ = agents.train(episodic_task, seed=seed)
      low = episodic.low_arrays()
      print(f"seed {seed}, the episodic hybrid ({episodic_task.path.name}, "
            f"{episodic_task.protocol.episodes} episodes) on the continuing task; its root's "
            f"values are discounted returns of episodes that end at the gate", flush=True)
      report(agent, episodic.parameters()["root.q"], low, (1, 0.0, 25.0), None, None, args)
      continue
    # In blocks of 100 hours (the same process as one call): the hour each Q(s, a)
    # last moved.
    hours = task.protocol.episodes
    moved = np.full(agent.q.size, -1)
    records = []
    for start in range(0, hours, 100):
      before = agent.q.copy()
      records.append(agent.train(min(100, hours - start)))
      moved[agent.q != before] = start + 100
    record = np.concatenate(records)
    print(f"seed {seed}: learned gain rho {agent.gain[0]:+.4f}/step = "
          f"{(agent.gain[0] + 1) / 100 * core.HOUR_STEPS:.1f} gates/h equivalent; online last "
          f"125 h {agent.metrics(record[-125:])['gates_per_hour']:.1f} gates/h; epsilon "
          f"{agent.machine.state()['schedule.state'][0]:.3f}", flush=True)
    view = (int(config.root.heading_sectors), float(config.root.near_gate_m),
            float(config.root.near_gate_cell_m))
    report(agent, agent.q, low_arrays(agent), view, agent.gain[0], moved, args)
    subtasks(agent, record)


def low_arrays(agent):
  """(diagonal trace, its baseline, straight trace, its baseline) of the patrol (the
  episodic hybrid gives its own: `ShipHybrid.low_arrays`)."""
  from hpg_mj.agents import ship_hybrid
  return ship_hybrid.low_arrays(agent)


def report(agent, q, low, view, rho, moved, args):
  """The greedy policy of root values `q` over `view` with subtasks `low`, sailed
  100 hours from the evaluation's start; `rho` the learned gain (None: none)."""
  sailing = Sailing(agent)
  s, tiling = sailing.s, sailing.tiling
  scratch = _scratch(tiling)
  rng_state = rng.make_state(sp.EVALUATION_SEED)
  ship = np.empty(4)
  _ship.sample_start(rng_state, ship)
  out = np.zeros((200_000, 10))
  n = 0
  for _ in range(100):          # hour by hour, as the evaluation's rows: the same calls
    n += sail_calls(ship, q, low, tiling, s, view, False, rng_state, -1,
                    core.HOUR_STEPS, out[n:], scratch)
  calls = out[:n]
  gates = (calls[:, G_EVENT] == core.SUCCESS).sum()
  print(f"  greedy: {gates / (calls[:, STEPS].sum() / core.HOUR_STEPS):.1f} gates/h, "
        f"{(calls[:, G_EVENT] == core.FAILURE).sum()} departures in 100 h", flush=True)
  # Where the 100 greedy hours' control steps go, by (root state, direction).
  keys = calls[:, STATE] * rules.N_DIRECTIONS + calls[:, ACTION]
  uniq, inverse = np.unique(keys, return_inverse=True)
  share = np.bincount(inverse, weights=calls[:, STEPS]) / calls[:, STEPS].sum()
  for u in np.argsort(-share)[:6]:
    m = inverse == u
    st, a = divmod(int(uniq[u]), rules.N_DIRECTIONS)
    print(f"  {share[u]:5.1%} of the steps: {describe(st, view)} -> {a}: {m.sum()} calls, "
          f"{calls[m, STEPS].mean():.0f} steps, gate {np.mean(calls[m, G_EVENT] == core.SUCCESS):.2f}"
          f", subtask success {np.mean(calls[m, L_EVENT] == core.SUCCESS):.2f}"
          + (f"; Q(s, a) last moved in training hour {moved[int(uniq[u])]}"
             if moved is not None else ""), flush=True)
  pairs = [(int(c[STATE]), int(c[ACTION])) for c in calls[-600:]]
  per = period(pairs)
  if per is None:
    print("  no loop repeats over the last 600 calls; the last 6 calls:", flush=True)
    loop = calls[-6:]
  else:
    loop = calls[-per:]
    k = loop[:, STEPS].sum()
    g = (loop[:, G_EVENT] == core.SUCCESS).sum()
    print(f"  the loop: {per} calls, {k:.0f} control steps, {g} gate passes: "
          f"{g / k * core.HOUR_STEPS:.1f} gates/h, reward/step {loop[:, REWARD].sum() / k:+.4f}",
          flush=True)
  for c, after in zip(loop, np.roll(loop, -1, axis=0)):
    st, a = int(c[STATE]), int(c[ACTION])
    qs = q[st * rules.N_DIRECTIONS:(st + 1) * rules.N_DIRECTIONS]
    line = (f"  at ({c[X]:.0f}, {c[Y]:.0f}) heading {c[HEADING]:+.0f}: {describe(st, view)} "
            f"-> direction {a} ({'diagonal' if a % 2 else 'straight'}), {c[STEPS]:.0f} steps"
            f"{', GATE' if c[G_EVENT] == core.SUCCESS else ''}"
            f"{', subtask success' if c[L_EVENT] == core.SUCCESS else ''}"
            f"\n    Q {np.array2string(qs, precision=1, suppress_small=True)}")
    if rho is not None:
      # The backup's target with the learned gain now, against the value that holds.
      target = c[REWARD] - rho * c[STEPS] + q[int(after[STATE]) * rules.N_DIRECTIONS:][
          :rules.N_DIRECTIONS].max()
      line += (f"; the backup's target now {target:+.1f} (Q {qs[a]:+.1f}); each Q(s, .) last "
               f"moved in training hour "
               f"{moved[st * rules.N_DIRECTIONS:(st + 1) * rules.N_DIRECTIONS]}")
    print(line, flush=True)
  if args.rollouts:
    rollouts(tiling, q, loop, view, s, low, scratch, args)


def rollouts(tiling, q, loop, view, s, low, scratch, args):
  buf = np.zeros((20_000, 10))
  rng_state = rng.make_state(1)
  for c in loop:
    start = np.array([c[X], c[Y], c[HEADING], c[RATE]])
    totals = {}
    for mode, reps in (("sampled", args.rollouts), ("mean", 1)):
      ret = np.zeros(rules.N_DIRECTIONS)
      ok = np.zeros(rules.N_DIRECTIONS)
      for a in range(rules.N_DIRECTIONS):
        for _ in range(reps):
          ship = start.copy()
          m = sail_calls(ship, q, low, tiling, s, view, mode == "sampled",
                         rng_state, a, args.horizon, buf, scratch)
          rewards = buf[:m, REWARD].copy()
          over = buf[:m, STEPS].sum() - args.horizon      # the last call past the horizon
          rewards[-1] -= over * core.STEP_REWARD
          ret[a] += rewards.sum() / reps
          ok[a] += (buf[0, L_EVENT] == core.SUCCESS) / reps
      totals[mode] = (ret, ok)
    a = int(c[ACTION])
    sampled, mean = totals["sampled"], totals["mean"]
    print(f"  from ({c[X]:.0f}, {c[Y]:.0f}, {c[HEADING]:+.0f}) greedy {a}: reward over "
          f"{args.horizon} steps minus the greedy's, sampled subtasks "
          f"{np.array2string(sampled[0] - sampled[0][a], precision=0)}, their means "
          f"{np.array2string(mean[0] - mean[0][a], precision=0)}; first call's success "
          f"(sampled) {np.array2string(sampled[1], precision=2)}", flush=True)


def subtasks(agent, record):
  tail = record[-125:]
  rates = [agent.machine.state()["schedule.outcomes"][k].mean() for k in range(2)]
  print(f"  subtasks, last 1,000 runs: diagonal {rates[0]:.2f}, straight {rates[1]:.2f}; last "
        f"125 h: diagonal {tail['diagonal_successes'].sum() / tail['diagonal_runs'].sum():.2f}"
        f", straight {tail['straight_successes'].sum() / tail['straight_runs'].sum():.2f}",
        flush=True)


if __name__ == "__main__":
  main()
