"""SAC (Haarnoja et al. 2018, "Soft Actor-Critic Algorithms and Applications") over the
JAX ship, one compiled loop: `n_steps` steps of every copy per call, each step acting
from the policy (uniformly at random for the first `learning_starts` control steps),
storing the copies' transitions in a replay buffer held in the run's state, and
taking `gradient_steps` gradient steps on uniform minibatches every `train_freq`
steps once more than `learning_starts` control steps are stored. A whole run is a
function of a key, so seeds vmap into one compile (`make_train`). The learner of
`hpg_mj.agents.jax_sac`.

SB3's SAC by the same names (the task file's [sac] section,
`hpg_mj.agents.jax_sac.SACSection`), and as SB3 computes it:

- twin Q critics on (observation, action), their targets Polyak-averaged
  (`tau`) after every gradient step; the target is the smaller target Q of the next
  action drawn from the policy, less alpha times its log-probability;
- the actor a tanh-squashed Gaussian: its mean and log standard deviation (clipped
  to [-20, 2]) from one MLP, a = tanh(u), the log-probability u's less
  sum log(1 - a^2 + 1e-6);
- the temperature alpha = exp(log_alpha), 1 at first, learned towards the target
  entropy -1 (minus the action's dimension) by the loss
  -log_alpha (log pi(a|s) + target) (SB3's: log alpha rather than alpha);
- in each gradient step, as SB3's `SAC.train`: the temperature's step (from the
  log-probabilities of the policy's actions at the minibatch), the critics' (with
  the alpha of before that step), then the actor's against the updated critics,
  then the Polyak average;
- ReLU MLPs with torch's default initialisation, torch's Adam (eps 1e-8, no
  gradient clipping), one step size for actor, critics and temperature;
- a time limit is no termination (SB3's handle_timeout_termination): the target of
  a truncated step bootstraps from its last observation.

What the networks see and do (the input contract of SB3's agents, as
`hpg_mj.jax.ppo`'s): the observation `[x, y, theta_deg, theta_dot_deg]` mapped
affinely from its Box onto [-1, 1] (`ppo.ShipIO.observe`); the actor, the buffer
and the critics work in a = tanh(u) in [-1, 1], and the world gets the turning rate
r = 15 a deg/s (`ppo.ShipIO.act`, the only place a is rescaled; SB3's
`unscale_action` over the rescaled action space), so r never leaves [-15, 15];
greedy: r = 15 tanh(mean).

Rows of the record as PPO's (`ppo.ShipRow`); the episodes without learning are
PPO's `sail`. Continuous actions only: the ship.
"""
import dataclasses
import math
from typing import NamedTuple

from hpg_mj.jax import ppo   # first: it sets XLA's CPU runtime before JAX starts

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

key = ppo.key
to_arrays = ppo.to_arrays
from_arrays = ppo.from_arrays

LOG_STD_MIN, LOG_STD_MAX = -20.0, 2.0     # SB3's clip of the actor's log standard deviation
SQUASH_EPS = 1e-6                         # SB3's in log(1 - tanh(u)^2 + eps)


# ---- the networks: ReLU MLPs, torch's default initialisation ----------------------

def init_mlp(key, sizes, copies=()):
  """torch.nn.Linear's default: kernel and bias uniform in +-1/sqrt(fan_in); `copies`
  networks stacked on first axes of that shape. One draw for all the layers (a
  draw a layer made compiling the run's start several times slower)."""
  pairs = list(zip(sizes[:-1], sizes[1:]))
  draw = jax.random.uniform(key, (*copies, sum((n_in + 1) * n_out for n_in, n_out in pairs)),
                            jnp.float32, -1.0, 1.0)
  layers, at = [], 0
  for n_in, n_out in pairs:
    part = draw[..., at:at + (n_in + 1) * n_out] / math.sqrt(n_in)
    layers.append({"kernel": part[..., :n_in * n_out].reshape(*copies, n_in, n_out),
                   "bias": part[..., n_in * n_out:]})
    at += (n_in + 1) * n_out
  return layers


def mlp(layers, x):
  """The MLP `layers` at x: ReLU between layers, linear at the end."""
  for layer in layers[:-1]:
    x = jax.nn.relu(x @ layer["kernel"] + layer["bias"])
  return x @ layers[-1]["kernel"] + layers[-1]["bias"]


def gaussian(actor, x):
  """The mean and the clipped log standard deviation of u at x (SB3's two heads on
  one latent: here one last layer of twice the action's size)."""
  mean, log_std = jnp.split(mlp(actor, x), 2, axis=-1)
  return mean, jnp.clip(log_std, LOG_STD_MIN, LOG_STD_MAX)


def sample(actor, x, key):
  """a = tanh(u), u drawn from the Gaussian at x, and log pi(a | x)."""
  mean, log_std = gaussian(actor, x)
  noise = jax.random.normal(key, mean.shape)
  a = jnp.tanh(mean + jnp.exp(log_std) * noise)
  logp = -0.5 * noise * noise - log_std - 0.5 * math.log(2 * math.pi)
  return a, jnp.sum(logp - jnp.log(1.0 - a * a + SQUASH_EPS), axis=-1)


def greedy(actor, x):
  """The greedy action at x: tanh of the Gaussian's mean."""
  return jnp.tanh(gaussian(actor, x)[0])


def q_values(critics, x, a):
  """Both critics' Q(x, a), shape (2, ...): the critics' layers stacked on a first axis."""
  xa = jnp.concatenate([x, a], axis=-1)
  return jax.vmap(lambda c: mlp(c, xa)[..., 0])(critics)


# ---- torch's Adam --------------------------------------------------------------------

def adam_init(params):
  """Adam's fresh state for `params` (`ppo.adam_init`)."""
  return ppo.adam_init(params)


def adam_step(params, grads, opt, learning_rate):
  """torch.optim.Adam's step (beta 0.9, 0.999; eps 1e-8 added to the corrected
  root), as SB3's SAC takes it: no gradient clipping."""
  count = opt["count"] + 1
  mu = jax.tree.map(lambda m, g: 0.9 * m + 0.1 * g, opt["mu"], grads)
  nu = jax.tree.map(lambda v, g: 0.999 * v + 0.001 * g * g, opt["nu"], grads)
  step = learning_rate / (1.0 - 0.9 ** count)
  root = jnp.sqrt(1.0 - 0.999 ** count)
  params = jax.tree.map(lambda p, m, v: p - step * m / (jnp.sqrt(v) / root + 1e-8),
                        params, mu, nu)
  return params, {"count": count, "mu": mu, "nu": nu}


# ---- the run's state -------------------------------------------------------------------

class Nets(NamedTuple):
  """What the gradient steps change."""
  actor: list
  critics: list              # the two critics' layers, stacked on a first axis of 2
  target: list               # their Polyak averages
  log_alpha: jax.Array
  actor_opt: dict
  critic_opt: dict
  alpha_opt: dict


class Runner(NamedTuple):
  """A run's whole state: what a checkpoint saves."""
  nets: Nets
  buffer: dict               # x, action, reward, next_x, terminated: (buffer_size, ...)
  stored: jax.Array          # transitions stored so far (the buffer's position is stored % size)
  losses: jax.Array          # the last call's means: critic loss, actor loss, alpha, entropy
  env_state: object
  obs: jax.Array
  ep_return: jax.Array
  ep_length: jax.Array
  key: jax.Array


LOSSES = ("critic_loss", "actor_loss", "alpha", "entropy")


@dataclasses.dataclass(frozen=True)
class Trainer:
  """SAC on one world with the task file's `section` and the record's `row`;
  `init(key)`, `update(runner)` -> (runner, per-step row sums (n_steps, fields))."""
  env: object
  params: object
  section: object
  row: object

  def __post_init__(self):
    io = ppo.io_for(self.env, self.params)
    if io.discrete:
      raise ValueError(f"SAC here needs a continuous action; {self.env.name} has discrete ones")
    object.__setattr__(self, "io", io)

  @property
  def steps_per_update(self):
    """Control steps per `update`: n_envs x n_steps."""
    return self.section.n_envs * self.section.n_steps

  @property
  def target_entropy(self):
    """The entropy the temperature aims at: minus the action's dimension (SB3's
    "auto")."""
    return -float(self.io.n_outputs)       # SB3's "auto": minus the action's dimension

  def init(self, key):
    """A fresh `Runner`: networks, optimisers, an empty buffer and `n_envs` copies
    started from `key`."""
    s, io = self.section, self.io
    actor_key, critic_key, env_key, key = jax.random.split(key, 4)
    actor = init_mlp(actor_key, [io.obs_size, *s.net_arch, 2 * io.n_outputs])
    critics = init_mlp(critic_key, [io.obs_size + io.n_outputs, *s.net_arch, 1], copies=(2,))
    log_alpha = jnp.zeros((), jnp.float32)                      # SB3's ent_coef "auto": 1.0
    nets = Nets(actor, critics, jax.tree.map(jnp.copy, critics), log_alpha, adam_init(actor),
                adam_init(critics), adam_init(log_alpha))
    size = s.buffer_size
    buffer = {"x": jnp.zeros((size, io.obs_size), jnp.float32),
              "action": jnp.zeros((size, io.n_outputs), jnp.float32),
              "reward": jnp.zeros(size, jnp.float32),
              "next_x": jnp.zeros((size, io.obs_size), jnp.float32),
              "terminated": jnp.zeros(size, jnp.float32)}
    obs, env_state = jax.vmap(self.env.reset, in_axes=(0, None))(
        jax.random.split(env_key, s.n_envs), self.params)
    zeros = jnp.zeros(s.n_envs, jnp.float32)
    return Runner(nets, buffer, jnp.zeros((), jnp.int32), jnp.zeros(len(LOSSES), jnp.float32),
                  env_state, obs, zeros, zeros.astype(jnp.int32), key)

  # ---- one gradient step, in SB3's order -------------------------------------------

  def _gradient_step(self, nets, batch, key):
    s = self.section
    noise_key, next_key = jax.random.split(key)
    alpha = jnp.exp(nets.log_alpha)              # before its own step, as SB3's ent_coef

    # The critics: 0.5 x the sum of both squared errors to the soft target.
    next_a, next_logp = sample(nets.actor, batch["next_x"], next_key)
    next_q = jnp.min(q_values(nets.target, batch["next_x"], next_a), axis=0)
    y = batch["reward"] + s.gamma * (1.0 - batch["terminated"]) * (next_q - alpha * next_logp)
    y = jax.lax.stop_gradient(y)

    def critic_loss(critics):
      q = q_values(critics, batch["x"], batch["action"])
      return 0.5 * jnp.sum(jnp.mean((q - y) ** 2, axis=1))
    c_loss, grads = jax.value_and_grad(critic_loss)(nets.critics)
    critics, critic_opt = adam_step(nets.critics, grads, nets.critic_opt, s.learning_rate)

    # The actor, against the critics just updated (its action drawn once, also for alpha).
    def actor_loss(actor):
      a, logp = sample(actor, batch["x"], noise_key)
      return jnp.mean(alpha * logp - jnp.min(q_values(critics, batch["x"], a), axis=0)), logp
    (a_loss, logp), grads = jax.value_and_grad(actor_loss, has_aux=True)(nets.actor)
    actor, actor_opt = adam_step(nets.actor, grads, nets.actor_opt, s.learning_rate)

    # The temperature: d/d log_alpha of -log_alpha (log pi + target entropy).
    alpha_grad = -jnp.mean(logp + self.target_entropy)
    log_alpha, alpha_opt = adam_step(nets.log_alpha, alpha_grad, nets.alpha_opt,
                                     s.learning_rate)

    target = jax.tree.map(lambda t, c: (1.0 - s.tau) * t + s.tau * c, nets.target, critics)
    nets = Nets(actor, critics, target, log_alpha, actor_opt, critic_opt, alpha_opt)
    return nets, jnp.stack([c_loss, a_loss, alpha, -jnp.mean(logp)])

  def _learn(self, nets, buffer, filled, key):
    """`gradient_steps` steps, each on a minibatch drawn uniformly from the buffer;
    their mean losses."""
    def step(nets, key):
      pick, key = jax.random.split(key)
      picks = jax.random.randint(pick, (self.section.batch_size,), 0, filled)
      return self._gradient_step(nets, jax.tree.map(lambda a: a[picks], buffer), key)
    nets, losses = jax.lax.scan(step, nets, jax.random.split(key, self.section.gradient_steps))
    return nets, losses.mean(axis=0)

  # ---- one step of every copy -----------------------------------------------------------

  def _step(self, runner, index):
    s, io = self.section, self.io
    key, act_key, random_key, step_key, learn_key = jax.random.split(runner.key, 5)
    x = io.observe(runner.obs)
    a, _ = sample(runner.nets.actor, x, act_key)
    # SB3's warm-up: uniform actions over [-1, 1] while fewer than learning_starts
    # control steps are stored.
    uniform = jax.random.uniform(random_key, a.shape, jnp.float32, -1.0, 1.0)
    a = jnp.where(runner.stored < s.learning_starts, uniform, a)
    obs, env_state, obs_end, reward, done, info = jax.vmap(
        lambda k, st, r: self.env.step_keeping_end(k, st, r, self.params))(
        jax.random.split(step_key, s.n_envs), runner.env_state, io.act(a))  # r = 15 a deg/s
    reward = reward.astype(jnp.float32)
    ep_return = runner.ep_return + reward
    ep_length = runner.ep_length + 1
    row = jnp.sum(self.row(done, info, ep_return, ep_length), axis=0)
    # A time limit is no termination: its target bootstraps from the last observation.
    at = (runner.stored + jnp.arange(s.n_envs)) % s.buffer_size
    new = {"x": x, "action": a, "reward": s.reward_scale * reward,
           "next_x": io.observe(obs_end), "terminated": info["terminated"].astype(jnp.float32)}
    buffer = jax.tree.map(lambda b, v: b.at[at].set(v), runner.buffer, new)
    stored = runner.stored + s.n_envs
    filled = jnp.minimum(stored, s.buffer_size)
    # SB3 learns once more than learning_starts control steps are stored.
    # (The buffer is read inside the branch, not passed through it: a branch's
    # operands and results may be copied, and the buffer is the run's largest array.)
    ready = (stored > s.learning_starts) & (index % s.train_freq == s.train_freq - 1)
    nets, losses = jax.lax.cond(
        ready, lambda n: self._learn(n, buffer, filled, learn_key),
        lambda n: (n, jnp.zeros(len(LOSSES), jnp.float32)), runner.nets)
    runner = Runner(nets, buffer, stored, runner.losses, env_state, obs,
                    jnp.where(done, 0.0, ep_return), jnp.where(done, 0, ep_length), key)
    return runner, (row, losses, ready)

  def update(self, runner, _=None):
    """`n_steps` steps of every copy (the step index counts within the call, so
    `train_freq` must divide `n_steps`: checked by the section); `runner.losses`
    becomes the means over the call's learning steps (kept where it had none)."""
    runner, (rows, losses, ready) = jax.lax.scan(self._step, runner,
                                                 jnp.arange(self.section.n_steps))
    n = jnp.sum(ready)
    mean = jnp.sum(losses * ready[:, None], axis=0) / jnp.maximum(n, 1)
    return runner._replace(losses=jnp.where(n > 0, mean, runner.losses)), rows

  def make_train(self, n_updates):
    """A whole run as one function of a key, returning (Runner, rows of shape
    (n_updates, n_steps, fields)); `jax.jit(jax.vmap(trainer.make_train(n)))(keys)`
    trains one run a key."""
    def train(key):
      return jax.lax.scan(self.update, self.init(key), None, n_updates)
    return train

  # ---- without learning -------------------------------------------------------------

  def acting(self, runner):
    """What acts without learning: the runner's actor."""
    return runner.nets.actor

  def action(self, actor, x, key, sample_policy):
    """The actor's a in [-1, 1] at x (r = 15 a deg/s): greedy (tanh of the mean) or,
    with `sample_policy`, drawn from the squashed Gaussian with `key`."""
    return sample(actor, x, key)[0] if sample_policy else greedy(actor, x)

  def episodes(self, actor, starts, key, sample_policy):
    """One episode from each start, all at once (`ppo.sail`), each action `action`'s."""
    return ppo.sail(self, lambda x, key: self.action(actor, x, key, sample_policy), starts,
                    key)


_INIT = {}


def compiled(trainer):
  """PPO's (`ppo.compiled`: the jitted `update` and `episodes`, once a configuration)
  but `init` jitted too: SAC's start (five networks, three optimisers, the buffer)
  compiles in less time than it takes op by op (2.0 against 3.1 s of CPU here)."""
  _, update, episodes = ppo.compiled(trainer)
  what = (type(trainer.env), trainer.env.name, trainer.params, trainer.section, trainer.row)
  if what not in _INIT:
    _INIT[what] = jax.jit(trainer.init)
  return _INIT[what], update, episodes
