"""DQN (Mnih et al. 2015) over the JAX worlds, one compiled loop: `n_steps` steps of
every copy per call, each step acting epsilon-greedily, storing the copies'
transitions in a replay buffer held in the run's state, and taking
`gradient_steps` Adam steps on sampled minibatches every `train_freq` steps once
`learning_starts` control steps are stored; the target network is copied every
`target_update_interval` control steps. SB3's DQN by the same names (the task
file's [dqn] section, `hpg_mj.agents.jax_dqn.DQNSection`): the Huber loss, the
gradient's global norm clipped to `max_grad_norm`, epsilon decaying linearly over
`exploration_steps` control steps, a time limit bootstrapped (only a termination
ends the target's sum). The learner of `hpg_mj.agents.jax_dqn`.

It shares PPO's pieces (`hpg_mj.jax.ppo`): what the network sees (the taxi's
one-hot), the MLP, Adam, the record rows, the saved arrays, the episodes without
learning. Discrete actions only: the taxi.
"""
import dataclasses
from typing import NamedTuple

from hpg_mj.jax import ppo   # first: it sets XLA's CPU runtime before JAX starts

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

key = ppo.key
to_arrays = ppo.to_arrays
from_arrays = ppo.from_arrays


class Runner(NamedTuple):
  """A run's whole state: what a checkpoint saves."""
  q: list                    # the Q network's layers
  target: list               # its copy for the targets
  opt: dict
  buffer: dict               # x, action, reward, next_x, terminated: (buffer_size, ...)
  stored: jax.Array          # transitions stored so far (the buffer's position is stored % size)
  env_state: object
  obs: jax.Array
  ep_return: jax.Array
  ep_length: jax.Array
  key: jax.Array


@dataclasses.dataclass(frozen=True)
class Trainer:
  """DQN on one world with the task file's `section` and the record's `row`;
  `init(key)`, `update(runner)` -> (runner, per-step row sums (n_steps, fields))."""
  env: object
  params: object
  section: object
  row: object

  def __post_init__(self):
    io = ppo.io_for(self.env, self.params)
    if not io.discrete:
      raise ValueError(f"DQN needs discrete actions; {self.env.name} has a continuous one")
    object.__setattr__(self, "io", io)

  @property
  def steps_per_update(self):
    """Control steps per `update`: n_envs x n_steps."""
    return self.section.n_envs * self.section.n_steps

  def init(self, key):
    """A fresh `Runner`: Q-network, optimiser, an empty buffer and `n_envs` copies
    started from `key`."""
    s = self.section
    net_key, env_key, key = jax.random.split(key, 3)
    q = ppo.init_mlp(net_key, [self.io.obs_size, *s.net_arch, self.io.n_outputs], 1.0)
    keys = jax.random.split(env_key, s.n_envs)
    obs, env_state = jax.vmap(self.env.reset, in_axes=(0, None))(keys, self.params)
    size = s.buffer_size
    buffer = {"x": jnp.zeros((size, self.io.obs_size), jnp.float32),
              "action": jnp.zeros(size, jnp.int32), "reward": jnp.zeros(size, jnp.float32),
              "next_x": jnp.zeros((size, self.io.obs_size), jnp.float32),
              "terminated": jnp.zeros(size, jnp.float32)}
    zeros = jnp.zeros(s.n_envs, jnp.float32)
    return Runner(q, jax.tree.map(jnp.copy, q), ppo.adam_init(q), buffer,
                  jnp.zeros((), jnp.int32), env_state, obs, zeros, zeros.astype(jnp.int32), key)

  def epsilon(self, stored):
    """Linear from exploration_initial_eps to exploration_final_eps over
    exploration_steps control steps, then held (SB3's schedule)."""
    s = self.section
    done = jnp.minimum(stored / s.exploration_steps, 1.0)
    return s.exploration_initial_eps + done * (s.exploration_final_eps - s.exploration_initial_eps)

  # ---- the loss: Huber on the one-step target, the target network's max ---------------

  def _loss(self, q, target, batch):
    s = self.section
    values = jnp.take_along_axis(ppo.mlp(q, batch["x"]), batch["action"][:, None], axis=1)[:, 0]
    best_next = jnp.max(ppo.mlp(target, batch["next_x"]), axis=1)
    y = batch["reward"] + s.gamma * (1.0 - batch["terminated"]) * best_next
    error = values - jax.lax.stop_gradient(y)
    huber = jnp.where(jnp.abs(error) <= 1.0, 0.5 * error ** 2, jnp.abs(error) - 0.5)
    return huber.mean()

  def _learn(self, q, opt, target, buffer, filled, key):
    """`gradient_steps` Adam steps, each on a minibatch drawn uniformly from the buffer."""
    def gradient_step(carry, key):
      q, opt = carry
      picks = jax.random.randint(key, (self.section.batch_size,), 0, filled)
      batch = jax.tree.map(lambda a: a[picks], buffer)
      grads = jax.grad(self._loss)(q, target, batch)
      return ppo.adam_step(q, grads, opt, self.section), None
    return jax.lax.scan(gradient_step, (q, opt),
                        jax.random.split(key, self.section.gradient_steps))[0]

  # ---- one step of every copy -------------------------------------------------------

  def _step(self, runner, index):
    s = self.section
    key, act_key, explore_key, step_key, learn_key = jax.random.split(runner.key, 5)
    x = self.io.observe(runner.obs)
    greedy = jnp.argmax(ppo.mlp(runner.q, x), axis=-1)
    random = jax.random.randint(act_key, greedy.shape, 0, self.io.n_outputs)
    explore = jax.random.uniform(explore_key, greedy.shape) < self.epsilon(runner.stored)
    action = jnp.where(explore, random, greedy)
    keys = jax.random.split(step_key, s.n_envs)
    obs, env_state, obs_end, reward, done, info = jax.vmap(
        lambda k, st, a: self.env.step_keeping_end(k, st, a, self.params))(
        keys, runner.env_state, action)
    reward = reward.astype(jnp.float32)
    ep_return = runner.ep_return + reward
    ep_length = runner.ep_length + 1
    row = jnp.sum(self.row(done, info, ep_return, ep_length), axis=0)
    # Store the copies' transitions; a time limit is no termination (SB3's
    # handle_timeout_termination): its target bootstraps from the last observation.
    at = (runner.stored + jnp.arange(s.n_envs)) % s.buffer_size
    new = {"x": x, "action": action.astype(jnp.int32), "reward": s.reward_scale * reward,
           "next_x": self.io.observe(obs_end),
           "terminated": info["terminated"].astype(jnp.float32)}
    buffer = jax.tree.map(lambda b, v: b.at[at].set(v), runner.buffer, new)
    stored = runner.stored + s.n_envs
    filled = jnp.minimum(stored, s.buffer_size)

    # (The buffer is read inside the branch, not passed through it: a branch's
    # operands and results may be copied, and the buffer is the run's largest array.)
    ready = (stored >= s.learning_starts) & (index % s.train_freq == s.train_freq - 1)
    q, opt = jax.lax.cond(
        ready, lambda qo: self._learn(*qo, runner.target, buffer, filled, learn_key),
        lambda qo: qo, (runner.q, runner.opt))
    # The target network: copied when a multiple of target_update_interval is passed.
    copy = stored // s.target_update_interval > runner.stored // s.target_update_interval
    target = jax.tree.map(lambda t, w: jnp.where(copy, w, t), runner.target, q)
    runner = Runner(q, target, opt, buffer, stored, env_state, obs,
                    jnp.where(done, 0.0, ep_return), jnp.where(done, 0, ep_length), key)
    return runner, row

  def update(self, runner, _=None):
    """`n_steps` steps of every copy (the step index counts within the call, so
    `train_freq` must divide `n_steps`: checked by the section)."""
    return jax.lax.scan(self._step, runner, jnp.arange(self.section.n_steps))

  def make_train(self, n_updates):
    """A whole run as one function of a key (vmap it over keys for seeds)."""
    def train(key):
      return jax.lax.scan(self.update, self.init(key), None, n_updates)
    return train

  # ---- without learning -------------------------------------------------------------

  def acting(self, runner):
    """What acts without learning: the runner's Q-network."""
    return runner.q

  def action(self, q, x, key, sample):
    """The action at x: greedy (the largest Q) or, with `sample`, epsilon-greedy at
    exploration_final_eps, drawn with `key`."""
    greedy = jnp.argmax(ppo.mlp(q, x), axis=-1)
    if not sample:
      return greedy
    pick, explore = jax.random.split(key)
    random = jax.random.randint(pick, greedy.shape, 0, self.io.n_outputs)
    return jnp.where(jax.random.uniform(explore, greedy.shape) <
                     self.section.exploration_final_eps, random, greedy)

  def episodes(self, q, starts, key, sample):
    """One episode from each start, all at once (`ppo.sail`), each action `action`'s."""
    return ppo.sail(self, lambda x, key: self.action(q, x, key, sample), starts, key)


compiled = ppo.compiled     # `init`, the jitted `update` and `episodes`, once a configuration
