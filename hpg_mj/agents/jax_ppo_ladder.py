"""PPO in JAX on the task ladder (SPEC section 11): `ladder_ppo_jax`, the learner and
loop of `ship_ppo_jax` (`hpg_mj.jax.ppo`: the whole update one jitted function, seeds
vmapped into one compile by `make_train`) over the ladder's JAX worlds, the task and
its level named by the task file's [environment] (`world = "ship_current"`, `level =
"easy"`), with the rewards and step limit of the ladder's Gymnasium environment;
and `ladder_sac_jax`, the same agent with `ship_sac_jax`'s learner (`hpg_mj.jax.sac`)
and [sac] section (`LadderSACJax`). It needs the extra `pip install 'hpg_mj[jax]'`; JAX is imported only when the agent
is built, so hpg_mj without it loads these task files.

The tasks are those of `hpg_mj.benchmark.LADDER` whose Gymnasium id has a JAX
environment in `hpg_mj.jax.ENV_IDS` (`TASKS`: all four today): a
ladder task whose JAX environment is registered there trains here with no change.

What the networks see and do (`hpg_mj.jax.ppo.ShipIO`): every number of the task's
observation mapped affinely from its Box onto [-1, 1], the Box of the level (the
current's water velocity by the level's fastest water); the goal's Gymnasium
dictionary flattened, `observation`, `achieved_goal`, `desired_goal` one after the
other (`hpg_mj.jax.ppo_ladder.GOAL_KEYS`, the JAX world's own layout); a Gaussian over
u, the world getting the turning rate r = 15 u deg/s, clipped to [-15, 15].

The record is ship_ppo_jax's, rows of 1,000 control steps summing the episodes ended
in them (gates: the task's success, the gate reached; gate_steps, return_sum, j_sum),
and `gates_passed` (the regatta's gates; elsewhere equal to gates). The greedy
measure sails the scorer's fixed starts of the task and level (`hpg_mj.benchmark`'s,
`worlds.ship_ladder`: start i the episode the environment lays out at
`reset(seed=1,000,000 + i)`, the goal's gate with it), all at once in the JAX world
(float32), a row an episode; `hpg-mj evaluate` prints its metrics normalized
against the task's bounds, and `hpg-mj train` adds it for the trained policy
("greedy", `final_metrics`). `policy()` is the same policy for the scorer itself
(`benchmark.evaluate(agent.policy(), "ship_goal", level="hard")`: SB3's `predict` on
the Gymnasium observations, the task's spaces, deg/s), which sails the native
vector environment in float64 (tests/jax/test_jax_ppo_ladder.py: both give the same
episodes). Saving, resuming bit for bit and the checkpoints of `hpg-mj run` are
ship_ppo_jax's (`hpg_mj.agents.jax_ppo`).
"""
import dataclasses

import numpy as np

from hpg_mj import jax as jax_registry      # the ids only: it imports no JAX
from hpg_mj.agents import _ladder
from hpg_mj.agents import _ship
from hpg_mj.agents import base
from hpg_mj.agents import jax_ppo
from hpg_mj.agents import jax_sac
from hpg_mj.learners import rng
from hpg_mj.taskfile import param
from hpg_mj.worlds import ship_ladder

# The ladder's tasks with a JAX world (SPEC section 11; their Gymnasium ids, under which
# `hpg_mj.jax` registers the JAX environments).
ENV_IDS, LEVELS = ship_ladder.ENV_IDS, ship_ladder.LEVELS
TASKS = tuple(name for name, env_id in ENV_IDS.items() if env_id in jax_registry.ENV_IDS)


@dataclasses.dataclass(frozen=True)
class LadderEnvironment(_ladder.LadderEnvironment):
  """[environment] of a ladder PPO task file: the ladder's (`agents._ladder`), on a task
  with a JAX world and that world's backend."""
  world: str = param("ship_current", "the ladder's task (one with a JAX world)",
                     choices=TASKS)
  backend: str = param("analytic", "the JAX world: Equation 1's analytic ship, float32",
                       choices=("analytic",))


@dataclasses.dataclass(frozen=True)
class LadderPPOJaxConfig:
  """The task file's schema: its sections [environment] and [ppo]."""
  environment: LadderEnvironment = dataclasses.field(default_factory=LadderEnvironment)
  ppo: jax_ppo.PPOSection = dataclasses.field(default_factory=lambda: jax_ppo.PPOSection(
      n_envs=64, n_steps=128, batch_size=2048, n_epochs=4, reward_scale=0.01))

  def __post_init__(self):
    jax_ppo._check_batch(self.ppo)


class Policy:
  """A ladder PPO agent's policy as `hpg_mj.benchmark.evaluate` takes any policy:
  `predict(obs, deterministic=True)` on a batch of the task's Gymnasium observations
  (the goal's dictionary) gives `(turning rates in deg/s, None)`; `observation_space`
  and `action_space` are the task's (its Gymnasium environment's at the level), which
  the scorer checks (`hpg_mj.benchmark_spaces`). Not deterministic: drawn from the
  policy with the key of `seed`."""

  def __init__(self, agent, seed=0):
    from hpg_mj.jax import ppo_ladder
    env = agent.make_env("gymnasium")
    self.observation_space, self.action_space = env.observation_space, env.action_space
    env.close()
    self._actor = ppo_ladder.Actor(agent.trainer, agent.trainer.acting(agent.runner), seed)

  def predict(self, obs, deterministic=True):
    """The turning rates (deg/s, shape (n,)) for a batch of n observations."""
    return self._actor(obs, sample=not deterministic), None


class LadderPPOJax(jax_ppo._JaxAgent, _ship.ShipAgent):
  """PPO in JAX on a task of the ladder at a level ([environment] world and level)."""
  name = "ladder_ppo_jax"
  Config = LadderPPOJaxConfig
  record_fields = ("steps", "episodes", "gates", "gate_steps", "return_sum", "j_sum",
                   "gates_passed")

  def __init__(self, config=None, seed=0, task=None):
    _ship.ShipAgent.__init__(self, config, seed, task)
    self._init_jax()
    if self.regatta:
      self.figure = "finish_rate"         # the benchmark's score (and `progress`'s)

  @property
  def regatta(self):
    """Whether the task is the regatta (a course of gates: its finish is the success)."""
    return self.config.environment.world == "ship_regatta"

  def _world(self, ppo):
    from hpg_mj import jax as hpg_jax
    from hpg_mj.jax import ppo_ladder
    env = self.config.environment
    world, params = hpg_jax.make(ENV_IDS[env.world], level=env.level,
                                 max_steps_in_episode=env.episode_steps,
                                 gate_reward=env.gate_reward,
                                 out_of_bounds_reward=env.out_of_bounds_reward,
                                 **({"finish_reward": env.finish_reward} if self.regatta
                                    else {}))
    row = ppo_ladder.LadderRow(_ship.J_GAMMA, _ship.J_STEP_REWARD, _ship.J_GATE_REWARD,
                               _ship.J_OUT_OF_BOUNDS_REWARD)
    return world, params, row

  trainer_class = "LadderTrainer"       # of hpg_mj.jax.ppo_ladder

  @property
  def trainer(self):
    """The learner (`hpg_mj.jax.ppo_ladder`'s `trainer_class`) on the task's JAX world."""
    if self._trainer is None:
      from hpg_mj.jax import ppo_ladder
      env, params, row = self._world(jax_ppo._learner())
      self._trainer = getattr(ppo_ladder, self.trainer_class)(env, params, self.section, row)
    return self._trainer

  def _compiled(self):
    from hpg_mj.jax import ppo_ladder
    return ppo_ladder.compiled(self.trainer)

  def make_env(self, api="gymnasium", backend="analytic", **kwargs):
    return _ladder.make_env(self.config.environment, api, backend, kwargs)

  # ---- the greedy measure: the ladder's fixed starts ----------------------------------

  def policy(self, seed=0):
    """The trained policy for `hpg_mj.benchmark.evaluate` (a `Policy`)."""
    return Policy(self, seed)

  def fixed_starts(self, episodes=base.GREEDY_STARTS, seed=base.GREEDY_SEED):
    """The scorer's fixed starts of the task and level (`worlds.ship_ladder`: start i the
    environment's `reset(seed=seed + i)`): a dictionary of reset options."""
    base._check_count("episodes", episodes)
    base._check_count("seed", seed)
    env = self.config.environment
    return ship_ladder.fixed_starts(env.world, env.level, episodes, seed)

  def evaluate_fixed(self, episodes=None, backend=None, policy="greedy", seed=None):
    """One episode from each of the scorer's fixed starts (`fixed_starts`), a row each."""
    episodes = base.GREEDY_STARTS if episodes is None else episodes
    seed = base.GREEDY_SEED if seed is None else seed
    return self._sail(self.fixed_starts(episodes, seed), backend, policy)

  def evaluate(self, episodes, backend=None, policy="greedy"):
    """`evaluate_fixed` from starts laid out from a seed drawn from the agent's generator."""
    base._check_count("episodes", episodes)
    seed = int(rng.next_u64(self.rng_state)) >> 33
    return self.evaluate_fixed(episodes, backend, policy, seed)

  def _sail(self, starts, backend, policy):
    """One episode from each start (a dictionary of reset options), all at once in the
    JAX world, without learning: greedy (the Gaussian's mean) or sampled (from the
    agent's generator), as ship_ppo_jax's (`ppo_ladder.LadderTrainer.episodes`)."""
    if policy not in base.POLICIES:
      raise ValueError(f"policy {policy!r} is not known; allowed: {list(base.POLICIES)}")
    if (backend or "analytic") != "analytic":
      raise ValueError(f"{self.name} sails the JAX world (backend 'analytic'); got backend "
                       f"{backend!r}")
    if len(starts["state"]) == 0:
      return self.empty_record()
    ppo = jax_ppo._learner()
    seed = None if policy == "greedy" else int(self.rng_state[0] % (2 ** 31))
    rows, lengths = self._compiled()[2](
        self.trainer.acting(self.runner), {k: np.asarray(v) for k, v in starts.items()},
        ppo.key(0 if seed is None else seed), seed is not None)
    return self.as_record(np.column_stack([np.asarray(lengths, np.float64),
                                           np.asarray(rows, np.float64)]))

  def final_metrics(self, record):
    """The greedy measure of the trained policy (`evaluate_fixed`: the scorer's 1,000
    fixed starts), as "greedy"; `hpg-mj train` normalizes it against the task's bounds.
    With the JAX agents' `control_steps_trained`."""
    greedy = {**self.metrics(self.evaluate_fixed()), "starts": base.GREEDY_STARTS,
              "start_seed": base.GREEDY_SEED}
    return {**jax_ppo._JaxAgent.final_metrics(self, record), "greedy": greedy}

  # ---- metrics -----------------------------------------------------------------------

  def scored(self, record):
    """An evaluation's rows (a row an episode) as the benchmark's record
    (`hpg_mj.benchmark`): the gate's passed, steps and return, or the regatta's
    finished, gates, steps and return, each return under SPEC section 11's rewards."""
    return {"passed": record["gates"], "finished": record["gates"],
            "gates": record["gates_passed"], "steps": record["steps"],
            "return": self._task_returns(record)}

  def _task_returns(self, rows):
    """Each episode's return under SPEC section 11's rewards, from an evaluation's rows
    (a row an episode: its length, success, gates and return under the agent's)."""
    env = self.config.environment
    if self.regatta:
      return _ladder.regatta_returns({"passed": rows["gates"], "gates": rows["gates_passed"],
                                      "steps": rows["steps"], "return": rows["return_sum"]}, env)
    return _ladder.gate_returns({"passed": rows["gates"], "steps": rows["steps"],
                                 "return": rows["return_sum"]}, env)

  def metrics(self, record):
    """The benchmark's metrics of the task from the row sums, over the last 100 rows
    of training (or a whole evaluation): the gate's (gate_pass_rate, steps_to_gate,
    mean_return, J) or the regatta's (finish_rate, gates_passed, steps_to_finish,
    mean_return). An evaluation's mean_return (a row an episode: the greedy measure) is
    under SPEC section 11's rewards, as every ladder agent's and any policy's
    (`_ladder.gate_returns`, `regatta_returns`); training's, summed in the JAX world,
    under the rewards it trains with."""
    w = self._window(record)
    episodes, gates = w["episodes"].sum(), w["gates"].sum()
    mean = lambda field: float(w[field].sum() / episodes) if episodes else None  # noqa: E731
    evaluation = len(w) and w is record and np.all(w["episodes"] == 1)   # a row an episode
    mean_return = float(self._task_returns(w).mean()) if evaluation else mean("return_sum")
    steps = float(w["gate_steps"].sum() / gates) if gates else None
    out = {"episodes_measured": int(episodes), "rows_measured": int(len(w))}
    if self.regatta:
      out.update(finish_rate=float(gates / episodes) if episodes else None,
                 gates_passed=mean("gates_passed"), steps_to_finish=steps,
                 mean_return=mean_return)
    else:
      out.update(gate_pass_rate=float(gates / episodes) if episodes else None,
                 steps_to_gate=steps, mean_return=mean_return, J=mean("j_sum"))
    out["control_steps"] = int(record["steps"].sum())
    return out


@dataclasses.dataclass(frozen=True)
class LadderSACJaxConfig:
  """The task file's schema: its sections [environment] and [sac] (ship_sac_jax's)."""
  environment: LadderEnvironment = dataclasses.field(default_factory=LadderEnvironment)
  sac: jax_sac.SACSection = dataclasses.field(default_factory=lambda: jax_sac.SACSection(
      gamma=0.995, net_arch=(64, 64)))

  def __post_init__(self):
    jax_ppo.check_replay("sac", self.sac)


class LadderSACJax(LadderPPOJax):
  """SAC in JAX on a task of the ladder at a level ([environment] world and level):
  ship_sac_jax's learner and loop (`hpg_mj.jax.sac`) where `ladder_ppo_jax` has PPO's,
  everything else (the world, the record, the greedy measure, the scorer's policy,
  saving) the same; the actor's a in [-1, 1] acted as r = 15 a deg/s, greedily 15
  tanh of its mean."""
  name = "ladder_sac_jax"
  algorithm = "sac"
  Config = LadderSACJaxConfig
  trainer_class = "LadderSACTrainer"
  checkpoint_rows = jax_sac.ShipSACJax.checkpoint_rows   # 0.1 M control steps: SAC's pace
