"""What the agents on the task ladder share (SPEC section 11): the [environment] section
that names the task and its level, the environments, the starts (drawn from the
agent's generator by the fused loop's own rule, `hierarchy.ladder`; the fixed ones of
the reports, `worlds.ship_ladder`), the step-by-step path's adapter and the
benchmark's metrics; `LadderMachineAgent`, a graph of blocks fused with the task's
world (`Program.run_world`)."""
import dataclasses

import numpy as np

from hpg_mj.agents import _ship
from hpg_mj.agents import base
from hpg_mj import taskfile
from hpg_mj.taskfile import param
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy import executor
from hpg_mj.hierarchy import ladder
from hpg_mj.hierarchy.graph import Step
from hpg_mj.worlds import ship_core as core
from hpg_mj.worlds import ship_ladder
from hpg_mj.worlds import ship_regatta_core as regatta_core

# Where each task's observation holds the gate whose frame the reference learners'
# views read (`blocks.GateFrame`; None: the steering task's own gate, the ship's pose
# as it is).
GATE_FRAMES = {"ship_current": None, "ship_harbour": None,
               "ship_goal": blocks.GateFrame(at=8),                    # the desired goal
               "ship_regatta": blocks.GateFrame(at=4, relative=True)}  # the next gate, seen


def tiles_view(world, coder):
  """The view of a reference learner's CMAC over the ship's whole state (flat PGRL's,
  the option-critic's) on the task `world`: the ship's own state (`blocks.StateTiles`)
  on the current and the harbour, in the frame of the episode's (next) gate
  (`blocks.GateTiles`, `GATE_FRAMES`) on the goal and the regatta."""
  frame = GATE_FRAMES[world]
  return blocks.StateTiles(coder) if frame is None else blocks.GateTiles(frame, coder)


@dataclasses.dataclass(frozen=True)
class LadderEnvironment(taskfile.Section):
  """[environment] of a ladder task file (SPEC section 11): the task, its level, and the
  environment's rewards and step limit (its defaults the environments' own)."""
  world: str = param("ship_current", "the ladder's task", choices=ladder.TASKS)
  level: str = param("easy", "the task's level", choices=ladder.LEVELS)
  backend: str = param("analytic", "train on the analytic world (fused) or the MuJoCo ship",
                       choices=base.BACKENDS)
  gate_reward: float = param(core.GATE_REWARD, "reward for passing the gate (the regatta: "
                             "each gate but the last)")
  finish_reward: float = param(regatta_core.FINISH_REWARD, "the regatta's reward for its "
                               "last gate (unused by the other tasks)")
  out_of_bounds_reward: float = param(core.OUT_OF_BOUNDS_REWARD, "reward for leaving the "
                                      "field (the harbour: or touching an obstacle)")
  max_steps: int = param(core.STEER_MAX_STEPS, "control steps, then truncated (at hard, at "
                         "most the level's time limit: ship_ladder.episode_steps)", low=1)

  @property
  def episode_steps(self):
    """The control steps an episode runs at most: `max_steps`, or the level's time limit
    where shorter (`ship_ladder.episode_steps`)."""
    return ship_ladder.episode_steps(self.world, self.level, self.max_steps)


def make_env(env, api, backend, kwargs, dictionary=False):
  """The ladder task of an [environment] section (`LadderEnvironment`) with its rewards
  and step limit: Gymnasium's (`ship_ladder.ENV_IDS`) on `backend`, or dm_control's
  suite task (its level); `dictionary`: an agent that reads the goal's Gymnasium
  dictionary, which dm_control's goal does not give (refused in one line)."""
  settings = {"max_steps": env.max_steps, "gate_reward": env.gate_reward,
              "out_of_bounds_reward": env.out_of_bounds_reward}
  if env.world == "ship_regatta":
    settings["finish_reward"] = env.finish_reward
  if api == "gymnasium":
    import gymnasium

    import hpg_mj  # noqa: F401  (registers the ids)
    return gymnasium.make(ship_ladder.ENV_IDS[env.world], level=env.level,
                          backend=backend, **settings, **kwargs)
  if api == "dm_control":
    if dictionary and env.world == "ship_goal":
      raise ValueError("ship_goal's dm_control task observes the gate as (position, "
                       "heading), not the Gymnasium dictionary its agents read; use "
                       "api='gymnasium'")
    from hpg_mj import suite
    return suite.load(env.world, env.level, {"random": 0, **settings, **kwargs})
  raise ValueError(f"unknown environment api {api!r}; allowed: ['gymnasium', 'dm_control']")


def world_of(env):
  """The `hierarchy.ladder.World` of an [environment] section."""
  return ladder.world(env.world, env.level, env.gate_reward, env.out_of_bounds_reward,
                      env.max_steps, env.finish_reward)


def _left(record, success, trained, env):
  """Whether each episode left the field (or ran aground): it neither succeeded nor ran
  to its step limit, or it stopped at the limit with the agent's out-of-bounds reward
  in its return (`trained`: the return it would hold without that reward)."""
  return ~success & ((record["steps"] < env.episode_steps) | (
      (env.out_of_bounds_reward != 0.0) &
      np.isclose(record["return"], trained + env.out_of_bounds_reward)))


def regatta_returns(record, env):
  """Each regatta episode's return under SPEC section 11's rewards (-1 a control step,
  +100 each gate but the last, +500 the last, -100 off the field: those its bounds are
  on), whatever rewards the agent trained with (`env`, its [environment]): from its
  steps, gates and finish (record fields passed, gates, steps, return). An episode that
  neither finished nor ran to its step limit left the field; one that stopped at
  the limit left it only if its return holds the out-of-bounds reward."""
  steps, gates = record["steps"], record["gates"]
  finished = record["passed"] > 0
  left = _left(record, finished, -steps + env.gate_reward * gates, env)
  return (-steps + regatta_core.GATE_REWARD * (gates - finished)
          + regatta_core.FINISH_REWARD * finished + regatta_core.OUT_OF_BOUNDS_REWARD * left)


def gate_returns(record, env):
  """Each episode's return on the current, the goal or the harbour under SPEC section
  11's rewards (section 2's: -1 a control step, +100 the gate, -100 off the field or
  aground: those its bounds are on), whatever rewards the agent trained with (`env`,
  its [environment]): from its steps and pass (record fields passed, steps, return).
  An episode that neither passed nor ran to its step limit left the field; one that
  stopped at the limit left it only if its return holds the out-of-bounds reward."""
  steps, passed = record["steps"], record["passed"] > 0
  left = _left(record, passed, -steps, env)
  return -steps + core.GATE_REWARD * passed + core.OUT_OF_BOUNDS_REWARD * left


def regatta_metrics(record, env):
  """What a regatta record (fields passed: finished, gates, steps, return) says over all
  its episodes, as the benchmark names it: the finish rate, the mean gates passed, the
  control steps over the finishes, the mean return under SPEC section 11's rewards
  (`regatta_returns`: its score, whatever rewards trained the agent)."""
  finished = record["passed"] > 0
  n = len(record)
  return {"finish_rate": float(finished.mean()) if n else None,
          "gates_passed": float(record["gates"].mean()) if n else None,
          "steps_to_finish": float(record["steps"][finished].mean()) if finished.any() else None,
          "mean_return": float(regatta_returns(record, env).mean()) if n else None}


class LadderAdapter(executor.GymAdapter):
  """The step-by-step path's adapter over a ladder environment's (Gymnasium's or
  dm_control's): a start row (`hierarchy.ladder`) reset as the environment's options
  (the state, the gate, the course), and the goal's dictionary flattened
  (`ship_goal_core.OBSERVATION_KEYS`), so that the graph reads on this path what it
  reads fused with the world."""

  def __init__(self, inner, world):
    self.inner, self.env, self.world = inner, inner.env, world

  def reset(self, start=None):
    """Starts an episode at the start row `start` (None: the environment's own draw)."""
    return self.world.flatten(self.inner.reset(None if start is None else
                                               self.world.options(start)))

  def step(self, action):
    """One primitive step, its observation flattened."""
    step = self.inner.step(action)
    return Step(self.world.flatten(step.obs), step.reward, step.terminated, step.truncated,
                step.info)


class LadderMachineAgent(base.MachineAgent, _ship.ShipAgent):
  """An agent on a ladder task (its [environment]: `LadderEnvironment`) whose `graph()` is
  made of blocks, run by the open machine fused with the task's world
  (`Program.run_world`) and step by step through its environments (`LadderAdapter`);
  for a fixed seed both give the same rows. Its record: passed (the gate passed; the
  regatta's finish), steps, return, gates (the regatta's gates passed), and the
  machine's counters its `record_fields` name."""

  end_field, illegal_field = "passed", "gates"
  raw_observation = True      # its rules read the numbers; no level's bounds scale them

  @property
  def required_fields(self):
    """The record fields its metrics read: the regatta's gates too (`regatta_metrics`)."""
    gate = ("passed", "steps", "return")
    return gate + ("gates",) if self.config.environment.world == "ship_regatta" else gate

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    self.world = world_of(self.config.environment)
    if self.config.environment.world == "ship_regatta":
      self.figure = "finish_rate"         # the benchmark's score (and `progress`'s)

  @property
  def fused_world(self):
    """The world the program is fused with (`Program(fused=...)`)."""
    return self.world

  @property
  def obs_size(self):
    """The task's observation's length (the goal's dictionary flattened: 19)."""
    return self.world.obs_size

  def make_env(self, api="gymnasium", backend="analytic", **kwargs):
    return make_env(self.config.environment, api, backend, kwargs, dictionary=True)

  def start_state(self):
    """A start row drawn from the agent's generator (`hierarchy.ladder`)."""
    return self.world.draw(self.rng_state)

  def compiled(self, episodes, learn, sample, start=None):
    self.machine.start_schedule(self.episodes)
    starts = None if start is None else np.asarray(start, dtype=np.float64)[None]
    return self._record_rows(self.machine.run_world(episodes, learn, sample, self.rng_state,
                                                    starts))

  def run_stepwise(self, env, episodes, learn=True, sample=None, start=None, on_call=None):
    adapter = LadderAdapter(executor.adapter_for(env), self.world)
    return super().run_stepwise(adapter, episodes, learn, sample, start, on_call)

  def _ended(self, last):
    if self.config.environment.world == "ship_regatta":   # (finished, the gates passed:
      gates = self.world.params.layout[0]                  # those not left, obs[10])
      return float(last.info.get("event") == "finish"), float(gates - last.obs[10])
    return float(last.info.get("event") == "gate")

  # ---- the reports' fixed starts (the benchmark's) ---------------------------------

  def fixed_starts(self, episodes=base.GREEDY_STARTS, seed=base.GREEDY_SEED):
    """The benchmark's fixed starts of the task (`worlds.ship_ladder`), as start rows:
    row i the episode the environment lays out at `reset(seed=seed + i)`."""
    env = self.config.environment
    options = ship_ladder.fixed_starts(env.world, env.level, episodes, seed)
    return np.array([self.world.start_of({k: v[i] for k, v in options.items()})
                     for i in range(int(episodes))]).reshape(-1, self.world.start_size)

  def evaluate_fixed(self, episodes=base.GREEDY_STARTS, backend=None, policy="greedy",
                     seed=base.GREEDY_SEED):
    """`evaluate` from the benchmark's fixed starts (`fixed_starts`), episode i with the
    generator restarted from `seed + i` (its ties, its sampled actions), so that the
    agent is scored from the starts every policy is (`hpg_mj.benchmark`). The agent's
    own generator is left as it was."""
    if policy not in base.POLICIES:
      raise ValueError(f"policy {policy!r} is not known; allowed: {list(base.POLICIES)}")
    backend = backend or self.backend
    if backend not in base.BACKENDS:
      raise ValueError(f"unknown backend {backend!r}; valid backends: {list(base.BACKENDS)}")
    starts = self.fixed_starts(episodes, seed)
    saved = self.rng_state.copy()
    sample = policy == "sampled"
    env = None if backend == "analytic" else self.stepwise_env(backend)
    rows = []
    try:
      for i in range(int(episodes)):
        self.set_seed(int(seed) + i)
        if env is None:
          rows.append(self.as_record(self.compiled(1, False, sample, starts[i])))
        else:
          rows.append(self.run_stepwise(env, 1, learn=False, sample=sample, start=starts[i]))
    finally:
      self.rng_state[:] = saved
    return np.concatenate(rows) if rows else self.empty_record()

  def metrics(self, record):
    """The benchmark's metrics of the task (`hpg_mj.benchmark.metrics_of`) over the last
    `metric_window` episodes: the gate's (gate_pass_rate, steps_to_gate, J, and
    mean_return under SPEC section 11's rewards: `gate_returns`) or the regatta's
    (finish_rate, gates_passed, steps_to_finish, and mean_return under SPEC section 11's
    rewards, its score: `regatta_returns`): whatever rewards trained the agent, as the
    benchmark scores any policy."""
    if self.config.environment.world != "ship_regatta":
      out = super().metrics(record)
      w = record[-self.metric_window:]
      if len(w):
        out["mean_return"] = float(gate_returns(w, self.config.environment).mean())
      return out
    w = record[-self.metric_window:]
    return {"episodes_measured": int(len(w)), **regatta_metrics(w, self.config.environment),
            "control_steps": int(record["steps"].sum())}

  def scored(self, record):
    """Its record as the benchmark's (`hpg_mj.benchmark`): {field: values} of passed,
    steps and its return under SPEC section 11's rewards (`gate_returns`), or the
    regatta's finished, gates, steps and return (`regatta_returns`)."""
    if self.config.environment.world != "ship_regatta":
      return {"passed": record["passed"], "steps": record["steps"],
              "return": gate_returns(record, self.config.environment)}
    return {"finished": record["passed"], "gates": record["gates"], "steps": record["steps"],
            "return": regatta_returns(record, self.config.environment)}

