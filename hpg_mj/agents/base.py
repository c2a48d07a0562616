"""The agent interface: what every agent answers, so that the experiments, the
command line, the figures, the reports and `hpg-mj render --agent` work with any
agent, the shipped ones and a user's (registered with `hpg_mj.agents.register`).

An agent is one class with:

  name            the task files' `[task] kind`
  Config          a dataclass of section dataclasses: the task file's schema
                  (`hpg_mj.taskfile.param` fields: default, meaning, range)
  record_fields   the names of its per-episode record's fields (float64 each)
  figure          the metric its progress reports, by name (a key of `metrics`)
  tags            e.g. ("baseline",): what it is, for listings
  record_steps    None for an episodic agent (one record row per episode); for a
                  continuing one (SPEC section 8) the control steps of one record
                  row, an "episode" of its record: then its task file's
                  [protocol] may give `control_steps` or `hours` instead of
                  `episodes` (hpg_mj.taskfile)
  checkpoint_rows None, or the record rows between a run's checkpoints at the
                  most (`hpg-mj run` checkpoints at least that often)

and it implements

  state()                      its whole training state: name -> array (the
                               live arrays: restoring writes into them, or
                               `restore(arrays, where)` if it overrides that)
  make_env(api, backend, ...)  an environment of its task ("gymnasium" or
                               "dm_control"), configured from its task file
  metrics(record)              what a record says (a dict of numbers): its online
                               measures over the last `metric_window` rows
                               (1,000 by default), counts such as control_steps
                               over the whole record
  compiled(n, learn, sample)   optional: the fused loop over the analytic world,
                               returning (n, len(record_fields)) float rows
  final_metrics(record)        optional: numbers measured once training is over
                               (greedy evaluations, comparisons); `hpg-mj train`
                               prints them beside `metrics(record)`
  graph(), start_state(),      the step-by-step path: the task graph its learners
  begin_episode(learn),        form, a start drawn from its generator, what
  end_episode(row, ...)        happens around each episode (fills the row)

The base class gives the rest: `train`, `evaluate`, `run_stepwise` (the one
step-by-step loop over any Gymnasium or dm_control environment), records with
named fields, seeding, progress. A minimal agent can skip `compiled`: the
"analytic" backend then runs its step-by-step path on the Gymnasium
environment.
"""
import dataclasses

import numpy as np

from hpg_mj.hierarchy import executor as executor_mod
from hpg_mj.hierarchy import algorithm
from hpg_mj.hierarchy import program as program_mod
from hpg_mj.learners import rng

BACKENDS = ("analytic", "mujoco")
POLICIES = ("greedy", "sampled")

# SPEC section 7's greedy measure: a fixed seeded set of starts, the same for every
# agent of a world and every run. Start i is the first start drawn by the agent's
# generator restarted from GREEDY_SEED + i (far from any training or tuning seed).
GREEDY_STARTS = 1000
GREEDY_SEED = 1_000_000
# The online metrics (`metrics(record)`) are over a record's last METRIC_WINDOW rows:
# an episodic agent's last 1,000 episodes; a continuing agent sets its own
# `metric_window` (ship_patrol: its last 125 hours). hpg_mj.agents.window names it.
METRIC_WINDOW = 1000


def _check_count(name, value):
  if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
    raise ValueError(f"{name} must be a non-negative integer, got {value!r}")


def seeded_starts(draw, episodes=GREEDY_STARTS, seed=GREEDY_SEED):
  """SPEC section 7's fixed start set: row i is `draw(generator)`, the first start
  drawn by a generator (`learners.rng`) made from `seed + i`. The one rule behind
  `Agent.fixed_starts`, `Agent.evaluate_fixed` and `hpg_mj.benchmark`."""
  _check_count("episodes", episodes)
  _check_count("seed", seed)
  return np.array([np.array(draw(rng.make_state(int(seed) + i)), dtype=np.float64)
                   for i in range(int(episodes))])


def _check_sections(cls, config):
  """Refuses, in one line, a configuration whose section is not of the class its agent's
  `Config` declares (a dataclass does not check it): a ladder task's environment given to
  an agent of the steering ship trained the steering ship without a word."""
  if cls.Config is None or not dataclasses.is_dataclass(config):
    return
  for field in dataclasses.fields(cls.Config):
    want = field.type if isinstance(field.type, type) else None
    if want is None and field.default_factory is not dataclasses.MISSING:
      want = field.default_factory if isinstance(field.default_factory, type) else None
    got = getattr(config, field.name, None)
    if want is None or not dataclasses.is_dataclass(want) or isinstance(got, want):
      continue
    hint = ""
    if field.name == "environment" and hasattr(got, "level") and not hasattr(want, "level"):
      hint = ("; a ladder task's environment is for an agent of the ladder (subclass "
              "hpg_mj.agents.ShipLadderHierarchy, whose Config takes a LadderEnvironment)")
    raise ValueError(f"{cls.__name__}: its [{field.name}] is a {type(got).__name__}; its Config "
                     f"takes a {want.__name__}{hint}")


class Agent:
  """Base class of every agent (see the module docstring)."""

  name = None
  Config = None
  record_fields = ()
  required_fields = ()            # the record fields its metrics read
  figure = None
  tags = ()
  record_steps = None                # control steps per record row of a continuing agent
  metric_window = METRIC_WINDOW      # the record's last rows `metrics` is over
  checkpoint_rows = None             # a run checkpoints at least this often (rows), if set
  raw_observation = False            # True: its policy reads the observation's numbers as
                                     # they are, not scaled by its space's bounds, so it
                                     # acts alike at a level with other bounds (`at_level`)

  def __init__(self, config=None, seed=0, task=None):
    if self.Config is not None and config is None:
      config = self.Config()
    _check_sections(type(self), config)
    self.config = config
    self.task = task                 # the TaskFile it came from, if any
    self.seed = int(seed)
    self.rng_state = rng.make_state(self.seed)
    self.episodes = 0                # learning episodes so far
    self.row = None                  # the record row of the step-by-step episode running

  # ---- what a subclass provides -------------------------------------------

  def state(self):
    """Its whole training state: name -> array, the live arrays (restoring writes
    into them)."""
    raise NotImplementedError

  def restore(self, arrays, where):
    """Puts saved arrays (name -> array, as `state()` gave them) back into the agent;
    by default copied into the live arrays of `state()`. `where` names where they came
    from (the saved folder, say) in the one-line error that refuses arrays that do not
    fit. An agent whose state is not a fixed set of arrays (e.g. an outside library's,
    hpg_mj.agents.sb3) overrides it."""
    from hpg_mj import storage
    storage.restore_into(self.state(), arrays, where)

  def make_env(self, api="gymnasium", backend="analytic", **kwargs):
    """An environment of its task (`api` "gymnasium" or "dm_control", `backend`
    "analytic" or "mujoco"), configured from its task file."""
    raise NotImplementedError

  def metrics(self, record):
    """What `record` says, a dict of numbers: its online measures over the last
    `metric_window` rows, counts such as control_steps over the whole record."""
    raise NotImplementedError

  compiled = None                    # or a method: (episodes, learn, sample) -> float rows

  def final_metrics(self, record):
    """Numbers measured after training on `record` (none by default)."""
    return {}

  def graph(self):
    """The task graph its learners form (`hpg_mj.hierarchy.graph.TaskGraph`), which
    the step-by-step path runs."""
    raise NotImplementedError

  def start_state(self):
    """The start of the next step-by-step episode (None: the environment's own)."""
    return None

  def begin_episode(self, learn):
    """Called before each step-by-step episode."""

  def end_episode(self, row, total, steps, last, learn):
    """Fills the record row of a finished step-by-step episode."""

  @property
  def backend(self):
    """The backend its task file trains on."""
    env = getattr(self.config, "environment", None)
    return getattr(env, "backend", "analytic")

  # ---- records ---------------------------------------------------------------

  @classmethod
  def record_dtype(cls):
    """Its record's numpy dtype: one float64 field per name of `record_fields`."""
    return np.dtype([(name, np.float64) for name in cls.record_fields])

  @classmethod
  def as_record(cls, rows):
    """Float rows (episodes, fields) as a record with named fields."""
    rows = np.ascontiguousarray(rows, dtype=np.float64)
    if rows.ndim != 2 or rows.shape[1] != len(cls.record_fields):
      raise ValueError(f"{cls.__name__}.as_record: rows must have shape (episodes, "
                       f"{len(cls.record_fields)}), one column per record field "
                       f"{list(cls.record_fields)}; got shape {rows.shape}")
    return rows.view(cls.record_dtype()).reshape(-1)

  @classmethod
  def empty_record(cls):
    """A record of no rows (the record of an agent not yet trained)."""
    return np.zeros(0, dtype=cls.record_dtype())

  # ---- training and evaluation -------------------------------------------------

  def set_seed(self, seed):
    """Restarts the agent's generator from `seed` (its learned state is kept)."""
    self.rng_state[:] = rng.make_state(int(seed))

  def train(self, episodes, backend=None):
    """Learns for `episodes` more episodes; returns the record of those episodes alone
    (a later call goes on from where this one ended)."""
    return self.run(episodes, backend, learn=True)

  def evaluate(self, episodes, backend=None, policy="greedy"):
    """Runs `episodes` episodes without learning, greedily or sampling its policy."""
    if policy not in POLICIES:
      raise ValueError(f"policy {policy!r} is not known; allowed: {list(POLICIES)}")
    return self.run(episodes, backend, learn=False, sample=policy == "sampled")

  def evaluate_fixed(self, episodes=GREEDY_STARTS, backend=None, policy="greedy",
                     seed=GREEDY_SEED):
    """`evaluate` on the fixed seeded start set (SPEC section 7): episode i runs
    with the generator restarted from `seed + i`, so it starts at
    `fixed_starts(...)[i]` whatever the agent (and draws its ties, if any, from
    that generator too). The agent's own generator is left as it was."""
    if policy not in POLICIES:
      raise ValueError(f"policy {policy!r} is not known; allowed: {list(POLICIES)}")
    backend = backend or self.backend
    if backend not in BACKENDS:
      raise ValueError(f"unknown backend {backend!r}; valid backends: {list(BACKENDS)}")
    _check_count("episodes", episodes)
    _check_count("seed", seed)
    saved = self.rng_state.copy()
    env = None if backend == "analytic" and self.compiled is not None else \
        self.stepwise_env(backend)
    rows = []
    try:
      for i in range(int(episodes)):
        self.set_seed(int(seed) + i)
        if env is None:
          rows.append(self.evaluate(1, backend, policy))
        else:
          rows.append(self.run_stepwise(env, 1, learn=False, sample=policy == "sampled"))
    finally:
      self.rng_state[:] = saved
    return np.concatenate(rows) if rows else self.empty_record()

  def fixed_starts(self, episodes=GREEDY_STARTS, seed=GREEDY_SEED):
    """The starts of `evaluate_fixed` (rows), for checking that they are fixed."""
    saved = self.rng_state.copy()

    def draw(generator):
      self.rng_state[:] = generator
      return self.start_state()
    try:
      return seeded_starts(draw, episodes, seed)
    finally:
      self.rng_state[:] = saved

  def run(self, episodes, backend=None, learn=True, sample=None):
    """Episodes on a backend: "analytic" (the compiled loop, or the step-by-step
    path on the analytic Gymnasium environment), "mujoco" (step by step through
    the MuJoCo world)."""
    backend = backend or self.backend
    if backend not in BACKENDS:
      raise ValueError(f"unknown backend {backend!r}; valid backends: {list(BACKENDS)}")
    if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 0:
      raise ValueError(f"episodes must be a non-negative integer, got {episodes!r}")
    if backend == "analytic" and self.compiled is not None:
      sample = learn if sample is None else (sample or learn)
      rows = self.compiled(int(episodes), learn, sample)
      if learn:
        self.episodes += int(episodes)
      return self.as_record(rows)
    return self.run_stepwise(self.stepwise_env(backend), episodes, learn=learn, sample=sample)

  def stepwise_env(self, backend):
    """The environment the step-by-step path uses on `backend`."""
    return self.make_env("gymnasium", backend=backend)

  def train_stepwise(self, env, episodes):
    """Learns step by step through `env` (a Gymnasium or dm_control environment)."""
    return self.run_stepwise(env, episodes, learn=True)

  def run_stepwise(self, env, episodes, learn=True, sample=None, start=None, on_call=None):
    """The one step-by-step loop: `episodes` episodes of the agent's task graph
    through `env`, from starts drawn from the agent's generator (or `start`).
    Without learning the policies are greedy unless `sample`. `on_call(call)`
    is told of every subtask called."""
    adapter = executor_mod.adapter_for(env)
    run = executor_mod.Executor(self.graph(), adapter, self.rng_state, on_call=on_call)
    rows = np.zeros((int(episodes), len(self.record_fields)))
    for i in range(int(episodes)):
      self.row = rows[i]
      begin = self.start_state() if start is None else np.array(start)
      self.begin_episode(learn)
      total, steps, last = run.run_episode(begin, learn=learn, sample=sample)
      self.end_episode(rows[i], total, steps, last, learn)
      if learn:
        self.episodes += 1
    self.row = None
    return self.as_record(rows)

  def progress(self, record):
    """{short name: value} of the figure's metric over `record`, for progress bars."""
    value = self.metrics(record)[self.figure]
    return {self.figure: float("nan") if value is None else float(value)}


class MachineAgent(Agent):
  """An agent whose `graph()` is made of blocks: the open machine (`hierarchy.program`)
  runs it on both paths (fused with the compiled world in the subclass's `compiled`;
  step by step through any environment of its task). Its state is the program's
  learned arrays by node name (`"<node>.<field>"`, beside the generator's
  `rng_state`), its `parameters()` each learner's. Its record fields may be the row's
  end (`end_field`: the ship's passed, the taxi's outcome), steps, return, illegal,
  calls (the calls below the root) and, per subtask, `{node}_runs` and
  `{node}_successes` (a run: a call that ended by the subtask's own termination, not
  by the episode's end). A subclass gives `_ended(last step)`, the row's end on the
  step-by-step path; `root_args`, the root call's arguments, if its rules read any."""

  _machine = None
  end_field = "passed"
  illegal_field = "illegal"          # the field of ROW_ILLEGAL (a patrol: departures)
  machine_world = None               # the program's `world` (the taxi's), if any
  fused_world = None                 # a world the program is fused with (a ladder task's)
  root_args = None
  own_fields = ()                    # record fields the agent fills itself (a patrol's gain)
  obs_size = 4                       # the observation's length (the taxi's: 5, or 4 classic)

  @property
  def machine(self):
    """The program of `graph()` (built when first needed, so that a subclass's graph
    is the one it runs)."""
    if self._machine is None:
      machine = program_mod.Program(self.graph(), root_args=self.root_args,
                                    obs_size=self.obs_size, world=self.machine_world,
                                    fused=self.fused_world)
      self._check_record_fields(machine)
      self._machine = machine
    return self._machine

  def _check_record_fields(self, machine):
    """Refuses, in one line, a record field the machine does not fill (a misspelt one
    would stay a column of zeros) and a missing one its task's metrics read."""
    fields = self.record_fields
    allowed = [self.end_field, "steps", "return", self.illegal_field, "calls",
               *self.own_fields]
    for name in machine.names[:-1]:
      allowed += [f"{name}_runs", f"{name}_successes"]
    who = f"{type(self).__name__}.record_fields"
    unknown = [f for f in fields if f not in allowed]
    if unknown:
      raise ValueError(f"{who}: {unknown[0]!r} is no field the machine records; allowed: "
                       f"{list(dict.fromkeys(allowed))}")
    missing = [f for f in self.required_fields if f not in fields]
    if missing:
      raise ValueError(f"{who} lacks {missing}: the task's metrics read "
                       f"{list(self.required_fields)}")

  def graph(self):
    raise NotImplementedError(f"{type(self).__name__}.graph(): a hierarchy gives its "
                              "task graph of blocks (hpg_mj.hierarchy.graph.TaskGraph)")

  def state(self):
    return {"rng_state": self.rng_state, **self.machine.state()}

  def parameters(self):
    """Each learner's parameters by its first node's name (`Program.parameters`)."""
    return self.machine.parameters()

  def run_stepwise(self, env, episodes, learn=True, sample=None, start=None, on_call=None):
    self.machine.start_schedule(self.episodes)
    rows = self.machine.run_stepwise(env, episodes, learn, sample, self.rng_state,
                                     lambda: self.start_state() if start is None else start,
                                     self._ended, on_call)
    if learn:
      self.episodes += int(episodes)
    return self.as_record(self._record_rows(rows))

  def _record_rows(self, rows):
    """The program's rows (`algorithm.ROW_END` ...) as this agent's record."""
    m = self.machine
    fields = self.record_fields
    out = np.zeros((rows.shape[0], len(fields)))
    for name, k in ((self.end_field, algorithm.ROW_END), ("steps", algorithm.ROW_STEPS),
                    ("return", algorithm.ROW_RETURN),
                    (self.illegal_field, algorithm.ROW_ILLEGAL)):
      if name in fields:
        out[:, fields.index(name)] = rows[:, k]
    for name in m.names[:-1]:
      col = algorithm.ROW_COUNTERS + 3 * m.index[name]
      if "calls" in fields:
        out[:, fields.index("calls")] += rows[:, col + algorithm.CALLS]
      for what, k in (("runs", algorithm.RUNS), ("successes", algorithm.SUCCESSES)):
        if f"{name}_{what}" in fields:
          out[:, fields.index(f"{name}_{what}")] = rows[:, col + k]
    return out
