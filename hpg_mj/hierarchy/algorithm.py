"""Algorithm 1 of the paper, once, for any task graph (the open machine).

```
Function HPG(Task i, State s)                         -> a call: `enter(G, i)`
  if i is primitive: execute it, return its reward    -> `descend` returns the action;
                                                         the world steps
  while i has not terminated:                         -> `step`: `judge(G, i)`
    choose a with mu^i(s, theta^i)                    -> `enter`: the learner's choose
    R = HPG(Task a, State s)                          -> rewards summed per call
    observe s' and internal reward G^i(s'|s, a)       -> `judge`: event and G
    z, theta updates (Eq. 3)                          -> `resume`: the learner's observe
                                                         (and its next choice)
```

Every subtask also returns when the episode ends (terminated or truncated). A
subtask's *run* is a call that ended by its own termination; a call cut short by the
end of the episode is counted as a call but no run.

This module is the algorithm's text; `hierarchy.program` compiles it once per graph,
with the graph's own operations written below it: `enter`, `resume`, `judge` and
`chosen` (each a chain over the graph's nodes that calls the node's kinds,
`hierarchy.kinds`), `ROOT` (the root's node), `SEEN_STEP` (whether a node's learner
sees -1 a primitive step, SPEC section 3, rather than its child's rewards summed) and
`CONTINUING` (whether the root is a continuing task's, SPEC section 8: the world's
events end its children's calls only, and it ends by its own termination). So
a graph compiles only the kinds it holds, a user's rules and kinds among them, and the
algorithm never asks which kind a node holds. Its state is one record of named
arrays (`Frames`), the same on both paths: fused with the analytic ship (`run_ship`)
or the taxi's rules (`run_taxi`) or a ladder task's world (`run_world`: the world's own
functions, `world_draw` ..., bound per graph), and step by step under any environment
(`begin`, `advance`).
"""
import collections

import numba
import numpy as np

from hpg_mj.hierarchy import ship_rules
from hpg_mj.hierarchy import taxi_subtasks
from hpg_mj.learners import arrays
from hpg_mj.learners import jit
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import taxi_rules

Frames = collections.namedtuple("Frames", (
    "stack", "choice", "action", "steps", "child_steps", "reward", "origin", "args", "x",
    "counters", "episode", "total", "flags", "rng", "fault", "obs", "samples", "board",
    "mask", "restart", "ops"))
Frames.__doc__ = """The machine's state, per node (a node is on the call stack at
most once: the graph is acyclic) and per run. `stack[d]`: the node called at depth d. Per node: its
`choice` (a child's index) and `action` (a continuous child's value), its call's
primitive `steps`, the steps and the summed `reward` of its current child's run,
the `origin` (the observation where the call began), its arguments (`args`, as
its `Child` bound them), its features (`x`: a features view's numbers), and its
`counters` [calls, runs, successes] in this episode. Per run: the `episode`
[depth of the primitive, steps, the root's last event, learning episodes, a
restart pending (a continuing root's: it sees `restart` next)], the
return (`total`), `flags` [learn, sample], the generator (`rng`, copied in and
out around a compiled call), the `fault` a boundary check wrote
(`hierarchy.boundary`), the observation (`obs`), the positions sampled in the
ship's step (`samples`), the taxi's own state in its fused loop (`board`:
taxi_rules' int64 state, then its episode's steps, outcome and illegal moves) and,
per node, the children it may choose now (`mask`: its `available`'s, else all);
the continuing ship's state after a departure (`restart`); the addresses of the
code of the graph's `enter`, `resume` and `judge` in this process (`ops`, as OP_ENTER
...: `learners.jit.call_at`)."""
OP_ENTER, OP_RESUME, OP_JUDGE = range(3)
E_DEPTH, E_STEPS, E_EVENT, E_LEARNED, E_RESTART = range(5)
LEARN, SAMPLE = range(2)
CALLS, RUNS, SUCCESSES = range(3)
# A record row: how the episode ended, its steps, its
# return, 0, then calls, runs and successes of each node.
ROW_END, ROW_STEPS, ROW_RETURN, ROW_ILLEGAL, ROW_COUNTERS = range(5)
NO_EVENT, SUCCESS = core.NO_EVENT, core.SUCCESS

# Compiled without reference counting (the state is views of arrays it never frees),
# and, but for the entry points (`_ENTRY`), without the wrappers that let Python or a
# C caller call a function: nothing does, and each wrapper cost about a quarter of a
# second of a graph's first compile.
_JIT = dict(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True,
            no_cfunc_wrapper=True)
_ENTRY = dict(cache=True, error_model="numpy", _nrt=False, no_cfunc_wrapper=True)
_INLINE = dict(cache=True, error_model="numpy", _nrt=False, inline="always")


# ---- the graph's operations (written per graph by `hierarchy.program`) -------------

def enter(G, node):
  """Task `node` is called in the observation G.M.obs: its learner starts (z <- 0),
  views the state and makes its first choice."""
  raise NotImplementedError("compiled per graph by hierarchy.program")


def resume(G, node, signal, done, terminal, terminated):
  """The learner of `node` takes R + G = `signal` of its child's run in s' (its view
  of G.M.obs) and, unless `done`, makes its next choice. `terminal`: s' ends the
  call's own task (its termination's event, or the world's end: `terminated`)."""
  raise NotImplementedError("compiled per graph by hierarchy.program")


def judge(G, node):
  """After a child of `node` returned: (the call's event by its termination, G)."""
  raise NotImplementedError("compiled per graph by hierarchy.program")


def chosen(G, node):
  """The child `node` chose: a subtask's node, its arguments bound (`G.M.args`); or
  -1 for a primitive, whose action is then `G.M.action[node]`."""
  raise NotImplementedError("compiled per graph by hierarchy.program")


def schedule_run(G, node, success):
  """A run of `node` ended (its success): the exploration schedule notes it, if it
  watches `node`."""
  raise NotImplementedError("compiled per graph by hierarchy.program")


def schedule_episode(G, learned):
  """The episode ended, the `learned`-th learning episode: the schedule's step."""
  raise NotImplementedError("compiled per graph by hierarchy.program")


def schedule_decided(G):
  """The root's child returned: a schedule counted in decisions steps."""
  raise NotImplementedError("compiled per graph by hierarchy.program")


ROOT = 0
SEEN_STEP = (False,)
CONTINUING = False


# ---- the world a program is fused with (bound per graph by `hierarchy.program`) ------

def world_draw(W, S, rng_state, start):
  """An episode's start (the ship's state and the task's layout) drawn from the run's
  generator into `start` (`hierarchy.ladder`)."""
  raise NotImplementedError("bound per graph by hierarchy.program (Program(fused=...))")


def world_reset(W, S, start, obs):
  """The world's state `S` set from `start`; the observation into `obs`."""
  raise NotImplementedError("bound per graph by hierarchy.program (Program(fused=...))")


def world_step(W, S, action, samples, obs, steps):
  """One primitive step under `action`, `steps` steps in: the positions sampled and the
  observation written; returns (event, reward, terminated, truncated)."""
  raise NotImplementedError("bound per graph by hierarchy.program (Program(fused=...))")


def world_end(W, S, event):
  """An ended episode's (the row's end, its ROW_ILLEGAL column)."""
  raise NotImplementedError("bound per graph by hierarchy.program (Program(fused=...))")


# ---- Algorithm 1 ----------------------------------------------------------------

@numba.njit(**_INLINE)
def call(G, d, node):
  """Task `node` is called at depth d."""
  M = G.M
  M.stack[d] = node
  M.steps[node] = 0
  M.child_steps[node] = 0
  M.reward[node] = 0.0
  arrays.copy_into(M.origin[node], M.obs)
  jit.call_at(enter, M.ops[OP_ENTER], (G, node))


@numba.njit(**_INLINE)
def descend(G, d):
  """From depth d, calls the chosen children down to a primitive; returns its action."""
  M = G.M
  while True:
    child = chosen(G, M.stack[d])
    if child < 0:
      M.episode[E_DEPTH] = d
      return M.action[M.stack[d]]
    d += 1
    call(G, d, child)


@numba.njit(**_INLINE)
def begin(G):
  """An episode starts in G.M.obs: the root is called; returns the first action."""
  M = G.M
  for i in range(M.counters.shape[0]):
    for j in range(3):
      M.counters[i, j] = 0.0
  M.episode[E_STEPS] = 0
  M.episode[E_EVENT] = NO_EVENT
  M.total[0] = 0.0
  call(G, 0, np.int64(ROOT))
  return descend(G, 0)


@numba.njit(**_INLINE)
def step(G, reward, terminated, truncated):
  """A primitive step ended in G.M.obs with `reward`. Returns (episode over, the next
  action): each call from the primitive's parent up judges whether it has ended
  (and, its learner having observed, returns to its parent), the first that goes on
  chooses again and descends."""
  M = G.M
  learn = M.flags[LEARN]
  depth = M.episode[E_DEPTH]
  for level in range(depth + 1):
    node = M.stack[level]
    M.reward[node] += reward
    M.steps[node] += 1
    M.child_steps[node] += 1
  M.episode[E_STEPS] += 1
  M.total[0] += reward
  over = terminated or truncated
  d = depth
  while True:
    node = M.stack[d]
    event, internal = jit.call_at(judge, M.ops[OP_JUDGE], (G, node))
    done = event != NO_EVENT or over
    terminal = terminated or event != NO_EVENT
    if CONTINUING and d == 0:      # the world's events end the children's calls only
      done = event != NO_EVENT
      terminal = False
      if M.episode[E_RESTART] != 0:          # after a departure, it sees the restart
        M.episode[E_RESTART] = 0
        arrays.copy_into(M.obs, M.restart)
    seen = core.STEP_REWARD * M.child_steps[node] if SEEN_STEP[node] else M.reward[node]
    M.reward[node] = 0.0
    if d == 0 and learn:
      schedule_decided(G)
    jit.call_at(resume, M.ops[OP_RESUME], (G, node, seen + internal, done, terminal, terminated))
    M.child_steps[node] = 0        # (after `resume`: a learner may read its tau)
    if not done:
      return False, descend(G, d)
    # The call returns (Algorithm 1: return to the parent).
    if d == 0:
      M.episode[E_EVENT] = event
      if learn:
        M.episode[E_LEARNED] += 1
        schedule_episode(G, M.episode[E_LEARNED])
      return True, 0.0
    c = M.counters[node]
    c[CALLS] += 1
    if not over:
      c[RUNS] += 1
      c[SUCCESSES] += event == SUCCESS
      if learn:
        schedule_run(G, node, event == SUCCESS)
    d -= 1


# ---- the two paths -------------------------------------------------------------

@numba.njit(**_ENTRY)
def run_ship(G, n_episodes, rng_state, world, record, fixed_start):
  """`n_episodes` episodes of the full ship task on Equation 1 (SPEC section 2):
  `world` = [gate reward, out-of-bounds reward, max steps]; each from `fixed_start`
  if it has 4 numbers, else from a start drawn from the generator. Record rows as
  ROW_END ...: passed the gate, steps, return, 0, then the nodes' counters."""
  M = G.M
  state, samples = M.obs, M.samples
  arrays.copy_into(M.rng, rng_state)
  max_steps = np.int64(world[2])
  for episode in range(n_episodes):
    if fixed_start.shape[0] == 4:
      arrays.copy_into(state, fixed_start)
    else:
      ship_rules.sample_start(M.rng, state)
    action = begin(G)
    event = NO_EVENT
    while True:
      core.euler_control(state, action, samples)
      event, reward = core.global_outcome(samples, world[0], world[1])
      terminated = event != NO_EVENT
      truncated = (not terminated) and M.episode[E_STEPS] + 1 >= max_steps
      over, action = step(G, reward, terminated, truncated)
      if over:
        break
    write_row(M, record[episode], 1.0 if event == SUCCESS else 0.0, 0.0)
  arrays.copy_into(rng_state, M.rng)


@numba.njit(**_ENTRY)
def run_continuing(G, n_rows, rng_state, world, record, ship):
  """`n_rows` record rows of the continuing ship task (SPEC section 8; a root whose
  termination is a continuing one, a Clock): the ship sails on from `ship` (the
  process's state, written back); each gate pass pays `world[0]` and it sails on;
  each departure pays `world[1]` and it restarts at a start drawn from the
  generator, which the root sees (the children's calls end at either). Record rows
  as `run_ship`'s, ROW_END the row's gate passes and ROW_ILLEGAL its departures."""
  M = G.M
  state, samples = M.obs, M.samples
  arrays.copy_into(M.rng, rng_state)
  arrays.copy_into(state, ship)
  for row in range(n_rows):
    passes, departures = 0.0, 0.0
    action = begin(G)
    while True:
      core.euler_control(state, action, samples)
      event, reward = core.global_outcome(samples, world[0], world[1])
      if event == SUCCESS:
        passes += 1.0
      elif event != NO_EVENT:                  # SPEC section 8: a fresh start, sail on
        departures += 1.0
        ship_rules.sample_start(M.rng, M.restart)
        M.episode[E_RESTART] = 1
      over, action = step(G, reward, event != NO_EVENT, False)
      if over:
        break
    write_row(M, record[row], passes, departures)
  arrays.copy_into(ship, state)
  arrays.copy_into(rng_state, M.rng)


@numba.njit(**_ENTRY)
def run_alone(G, n_episodes, rng_state, direction, record):
  """`n_episodes` calls of the root on its own, a stand-alone subtask of the ship
  (SPEC section 8): each from a start drawn at the local start of `direction`
  (`ship_rules.sample_local_start`), -1 a step, ended by the root's own termination.
  Record rows as `run_ship`'s, ROW_END the root's success."""
  M = G.M
  state, samples = M.obs, M.samples
  arrays.copy_into(M.rng, rng_state)
  for episode in range(n_episodes):
    ship_rules.sample_local_start(M.rng, direction, state)
    action = begin(G)
    while True:
      core.euler_control(state, action, samples)
      over, action = step(G, core.STEP_REWARD, False, False)
      if over:
        break
    write_row(M, record[episode], 1.0 if M.episode[E_EVENT] == SUCCESS else 0.0, 0.0)
  arrays.copy_into(rng_state, M.rng)


@numba.njit(**_ENTRY)
def run_taxi(G, n_episodes, rng_state, world, record, starts):
  """`n_episodes` episodes of the taxi task `world` (`taxi_rules.world_config`; SPEC
  section 5), each from a start drawn from the generator (`taxi_subtasks.sample_start`)
  or, with starts int64[k, 5] (k > 0), from starts[e % k]. The graph sees the state
  as numbers (G.M.obs: its first 5, or 4 in the classic task); the world steps it as
  taxi_rules' int64 state. Record rows as `run_ship`'s, with the episode's outcome
  (`taxi_rules`: DELIVERED, OUT_OF_FUEL, TRUNCATED) and its illegal Pickups and
  Dropoffs."""
  M = G.M
  state, episode, obs = M.board[0:5], M.board[5:8], M.obs
  arrays.copy_into(M.rng, rng_state)
  for e in range(n_episodes):
    if starts.shape[0] > 0:
      for i in range(5):
        state[i] = starts[e % starts.shape[0], i]
    else:
      taxi_subtasks.sample_start(M.rng, world, state)
    for i in range(3):
      episode[i] = 0
    for i in range(obs.shape[0]):
      obs[i] = state[i]
    action = begin(G)
    while True:
      reward = taxi_rules.primitive_step(state, episode, np.int64(action), world)
      for i in range(obs.shape[0]):
        obs[i] = state[i]
      outcome = episode[taxi_rules.E_OUTCOME]
      truncated = outcome == taxi_rules.TRUNCATED
      terminated = outcome != taxi_rules.RUNNING and not truncated
      over, action = step(G, reward, terminated, truncated)
      if over:
        break
    write_row(M, record[e], episode[taxi_rules.E_OUTCOME], episode[taxi_rules.E_ILLEGAL])
  arrays.copy_into(rng_state, M.rng)


@numba.njit(**_ENTRY)
def run_world(G, n_episodes, rng_state, W, S, record, starts, start):
  """`n_episodes` episodes fused with the world the program binds (a ladder task,
  `hierarchy.ladder`: its parameters `W`, its state `S`): each from `starts[e % k]`
  (k > 0 rows) or from a start drawn from the generator (`world_draw`, into `start`);
  the world steps as its Gymnasium environment does, and the graph sees its
  observation. Record rows as `run_ship`'s, ROW_END and ROW_ILLEGAL the world's
  `world_end` (the ladder's: passed the gate or finished; the regatta's gates)."""
  M = G.M
  arrays.copy_into(M.rng, rng_state)
  for e in range(n_episodes):
    if starts.shape[0] > 0:
      arrays.copy_into(start, starts[e % starts.shape[0]])
    else:
      world_draw(W, S, M.rng, start)
    world_reset(W, S, start, M.obs)
    action = begin(G)
    event = NO_EVENT
    while True:
      event, reward, terminated, truncated = world_step(W, S, action, M.samples, M.obs,
                                                        M.episode[E_STEPS] + 1)
      over, action = step(G, reward, terminated, truncated)
      if over:
        break
    end, illegal = world_end(W, S, event)
    write_row(M, record[e], end, illegal)
  arrays.copy_into(rng_state, M.rng)


@numba.njit(**_INLINE)
def write_row(M, row, end, illegal):
  """The record row of the episode just ended."""
  row[ROW_END] = end
  row[ROW_STEPS] = M.episode[E_STEPS]
  row[ROW_RETURN] = M.total[0]
  row[ROW_ILLEGAL] = illegal
  for i in range(M.counters.shape[0]):
    for j in range(3):
      row[ROW_COUNTERS + 3 * i + j] = M.counters[i, j]


@numba.njit(**_ENTRY)
def begin_at(G, obs, rng_state):
  """The step-by-step path: an episode starts in `obs`; returns the first action."""
  M = G.M
  arrays.copy_into(M.obs, obs)
  arrays.copy_into(M.rng, rng_state)
  action = begin(G)
  arrays.copy_into(rng_state, M.rng)
  return action


@numba.njit(**_ENTRY)
def advance(G, obs, samples, reward, terminated, truncated, rng_state):
  """The step-by-step path: the environment stepped to `obs` (`samples`: the ship's
  positions sampled in the step, if the environment gave them). Returns (episode
  over, the next action)."""
  M = G.M
  arrays.copy_into(M.obs, obs)
  if samples.shape[0] == M.samples.shape[0]:
    for i in range(samples.shape[0]):
      M.samples[i, 0] = samples[i, 0]
      M.samples[i, 1] = samples[i, 1]
  arrays.copy_into(M.rng, rng_state)
  out = step(G, reward, terminated, truncated)
  arrays.copy_into(rng_state, M.rng)
  return out
