"""PPO and SAC in JAX on the task ladder (SPEC section 11): what the loops of
`hpg_mj.jax.ppo` and `hpg_mj.jax.sac` need beyond the steering ship's, for the agents
of `hpg_mj.agents.jax_ppo_ladder` (`ladder_ppo_jax`, `ladder_sac_jax`).

The loops are `ppo.Trainer`'s and `sac.Trainer`'s as they are, over the ladder's JAX
worlds (`hpg_mj.jax.make` by the Gymnasium id and `level`): `ppo.ShipIO` maps every
number of the world's observation Box onto [-1, 1] (the current's six, the goal's
nineteen, the harbour's and the regatta's) and acts r = 15 u deg/s (SAC's a in
[-1, 1] the same way). This module adds

- `LadderRow`: what an ended episode adds to a record row on any ladder task (the
  task's success: the gate, the goal's gate, the regatta's finish, `info["event"]`
  1; any other ending before the clock, leaving the field or touching an obstacle,
  counts as leaving for J; the regatta's gates passed from `info["gates_passed"]`);
- `LadderTrainer` (PPO's) and `LadderSACTrainer`: the greedy (or sampled) episodes
  from the ladder's starts, given as the Gymnasium reset's options (the goal's gate
  with the ship's state);
- `flat`: the Gymnasium observation as the JAX world's one array (the goal's
  dictionary in `GOAL_KEYS` order, `hpg_mj.jax.ship_goal`'s slices);
- `compiled`: the loop's jitted functions, `init` among them, and the policy's;
- `Actor`: the trained networks acting on batches of the Gymnasium environment's
  observations, jitted, for the scorer (`hpg_mj.benchmark`).
"""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from hpg_mj.jax import ppo
from hpg_mj.jax import sac
from hpg_mj.worlds import ship_core
from hpg_mj.worlds import ship_goal_core

# The goal's dictionary flattened, its parts one after the other in this order: the
# JAX world's observation (`hpg_mj.jax.ship_goal.OBSERVATION`, `ACHIEVED_GOAL`,
# `DESIRED_GOAL`, `RANGES`: 0-3, 4-7, 8-11, 12-18), so that training and scoring see the
# same vector.
GOAL_KEYS = ship_goal_core.OBSERVATION_KEYS


@dataclasses.dataclass(frozen=True)
class LadderRow:
  """(episodes, gates, gate_steps, return_sum, j_sum, gates_passed) of the episodes
  that ended: `gates` those that reached the task's end (the gate; the regatta's
  finish), `gate_steps` their lengths, J under MushroomRL's rewards (SPEC section 7,
  `agents._ship.mushroom_j`: the constants the agent passes; an episode that ended
  by anything but its success or the clock left, as the benchmark's J reads it), and
  `gates_passed` the regatta's gates passed (elsewhere the gate, 0 or 1)."""
  j_gamma: float
  j_step: float
  j_gate: float
  j_out: float
  fields = ("episodes", "gates", "gate_steps", "return_sum", "j_sum", "gates_passed")

  def __call__(self, done, info, ep_return, ep_length):
    passed = done & (info["event"] == ship_core.SUCCESS)
    left = done & info["terminated"] & ~passed
    length = ep_length.astype(jnp.float32)
    discount = self.j_gamma ** (length - 1.0)
    last = jnp.where(passed, self.j_gate, jnp.where(left, self.j_out, self.j_step))
    j = self.j_step * (1.0 - discount) / (1.0 - self.j_gamma) + discount * last
    d = done.astype(jnp.float32)
    gates = info["gates_passed"].astype(jnp.float32) if "gates_passed" in info else passed * 1.0
    return jnp.stack([d, passed * 1.0, passed * length, d * ep_return, d * j, d * gates],
                     axis=-1)


def flat(obs):
  """A batch of the Gymnasium environment's observations as the JAX world's arrays
  (n, size): an array as it is, the goal's dictionary its `GOAL_KEYS` one after the
  other."""
  if isinstance(obs, dict):
    return np.concatenate([np.asarray(obs[k], dtype=np.float64) for k in GOAL_KEYS], axis=-1)
  return np.asarray(obs, dtype=np.float64)


class _LadderStarts:
  """A learner's trainer on a ladder world (mixed in before it), its greedy (or
  sampled) episodes starting from the ladder's starts: a dictionary of arrays, the
  reset options of the Gymnasium environment ("state" (n, 4), and the goal's "gate"
  (n, 3) or the regatta's "course" (n, gates, 3); `hpg_mj.worlds.ship_ladder.
  fixed_starts`), given to the world's `reset_to` in that order."""

  def start(self, one):
    """`(obs, state)` of the world at one start (a dictionary of reset options)."""
    return self.env.reset_to(one["state"], *(v for k, v in one.items() if k != "state"),
                             params=self.params)

  def episodes(self, acting, starts, key, sample):
    """The learner's `episodes` from the ladder's starts (a dictionary, `start`)."""
    return ppo.sail(self, lambda x, key: self.action(acting, x, key, sample), starts, key,
                    self.start)


@dataclasses.dataclass(frozen=True)
class LadderTrainer(_LadderStarts, ppo.Trainer):
  """`ppo.Trainer` on a ladder world, sailing from the ladder's starts."""


@dataclasses.dataclass(frozen=True)
class LadderSACTrainer(_LadderStarts, sac.Trainer):
  """`sac.Trainer` on a ladder world, sailing from the ladder's starts."""


_COMPILED = {}


def compiled(trainer):
  """`ppo.compiled(trainer)`'s `(init, update, episodes)` (any learner's trainer: PPO's or
  SAC's) with `init` jitted too, and `act(acting, obs, key, sample)`, the policy's
  turning rates (deg/s, clipped to [-15, 15]) for a batch of the world's observations,
  jitted; compiled once for all trainers of the same learner, world, parameters,
  section and row. `init` is jitted here, not run op by op as `ppo.compiled` runs it:
  a saved run loaded, a checkpoint resumed and each seed of a process build a runner,
  and op by op each costs what one compile does (measured on this 2-core machine under
  load: 5-11 s a runner op by op, 8 s compiled once)."""
  what = (type(trainer), type(trainer.env), trainer.env.name, trainer.params, trainer.section,
          trainer.row)
  if what not in _COMPILED:
    io = trainer.io
    _, update, episodes = ppo.compiled(trainer)

    def act(acting, obs, key, sample):
      u = trainer.action(acting, io.observe(obs), key, sample)
      return jnp.clip(io.act(u)[..., 0], -ship_core.MAX_TURN_RATE, ship_core.MAX_TURN_RATE)
    _COMPILED[what] = (jax.jit(trainer.init), update, episodes,
                       jax.jit(act, static_argnums=3))
  return _COMPILED[what]


class Actor:
  """The policy of `trainer` (a `LadderTrainer` or `LadderSACTrainer`) with `networks`
  (what it acts with, `trainer.acting(runner)`), on batches of the Gymnasium
  environment's observations: `__call__(obs, sample)` gives the turning rates in
  deg/s, clipped to [-15, 15] as the world clips them: greedy (`trainer.action`'s:
  15 times PPO's Gaussian mean, 15 tanh of SAC's) or, with `sample`, drawn from the
  policy with the actor's own key (`seed`). Every batch is padded to the largest it has seen (a
  power of two, at least 8): an evaluation's batches shrink as its episodes end, and
  each size would be compiled anew."""

  def __init__(self, trainer, networks, seed=0):
    self.networks = networks
    self.key = ppo.key(seed)
    self.size = 8
    self._act = compiled(trainer)[3]

  def __call__(self, obs, sample=False):
    x = flat(obs)
    n = x.shape[0]
    self.size = max(self.size, 1 << (n - 1).bit_length())
    padded = np.zeros((self.size, x.shape[1]), dtype=np.float32)
    padded[:n] = x
    self.key, key = jax.random.split(self.key)
    return np.asarray(self._act(self.networks, padded, key, bool(sample)), np.float64)[:n]
