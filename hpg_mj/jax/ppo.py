"""PPO (Schulman et al. 2017) over the JAX worlds, one compiled loop in the style of
PureJaxRL's `make_train` (Lu et al. 2022): the rollout is a `lax.scan` over the
vmapped environments, then GAE (Schulman et al. 2016) and the minibatch epochs,
all in one jitted update; a whole run is a function of a key, so seeds vmap into
one compile (`make_train`). It is the learner of `hpg_mj.agents.jax_ppo`.

Read top to bottom: the observation as the networks see it, the networks, Adam,
the rollout, GAE, the loss, the update. The hyper-parameters come as one record
(`section`, the task file's [ppo] section, `hpg_mj.agents.jax_ppo.PPOSection`), by
the task file's names: n_envs, n_steps, batch_size, n_epochs, learning_rate, gamma,
gae_lambda, clip_range, ent_coef, vf_coef, max_grad_norm, reward_scale, net_arch.

What the networks see and do (the input contract of SB3's agents, hpg_mj.agents.sb3):
- the ship: the observation `[x, y, theta_deg, theta_dot_deg]` mapped affinely from
  its Box onto [-1, 1]; the policy is a Gaussian over u with a learned state-free
  log standard deviation, and the world gets the turning rate r = 15 u deg/s,
  clipped to [-15, 15] by the world (the log-probability is u's, unclipped, as
  SB3's); greedy: r = 15 mean, clipped.
- the taxi: each of `[row, col, passenger, destination, fuel]` one-hot (SB3's
  MultiDiscrete preprocessing); the policy is a softmax over the actions.

Time limits: a truncated episode's last reward gets `gamma * V(last observation)`
added (SB3's bootstrap on `TimeLimit.truncated`), so that the clock is not read as
an ending of the task; the step is reset as gymnax's `step` resets it.

The record: every step gives, summed over the copies, the episodes that ended in
it and what they add to a record row (`EpisodeRow`: the ship's gates, steps to the
gate, returns and MushroomRL's J; the taxi's returns, lengths and deliveries).
"""
import dataclasses
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from hpg_mj.jax import ship as jax_ship
from hpg_mj.jax import taxi as jax_taxi
from hpg_mj.worlds import ship_core
from hpg_mj.worlds import taxi_rules


# ---- what the networks see, and what they act ------------------------------------

class ShipIO:
  """The ship (the steering tasks, and the task ladder's worlds, which see more): each
  number of the observation onto [-1, 1] from the observation Box, a Gaussian over u,
  the world's turning rate r = 15 u deg/s."""
  discrete = False

  def __init__(self, env, params):
    space = env.observation_space(params)
    self.centre = (space.high + space.low) / 2.0
    self.half = (space.high - space.low) / 2.0
    self.obs_size = int(space.shape[0])   # 4; the ladder's worlds see more (hpg_mj.jax)
    self.n_outputs = 1
    self.scale = ship_core.MAX_TURN_RATE

  def observe(self, obs):
    """The observation as the networks see it: each number onto [-1, 1]."""
    return ((obs - self.centre) / self.half).astype(jnp.float32)

  def act(self, u):
    """The world's turning rate r = 15 u deg/s of the network's u."""
    return self.scale * u           # the world clips r to [-15, 15] (SPEC section 1)


class TaxiIO:
  """The taxi: each component of the observation one-hot, a softmax over actions."""
  discrete = True

  def __init__(self, env, params):
    high = np.asarray(env.observation_space(params).high)
    self.sizes = tuple(int(h) + 1 for h in high)
    self.obs_size = sum(self.sizes)
    self.n_outputs = env.num_actions

  def observe(self, obs):
    """The observation as the networks see it: each number one-hot, concatenated."""
    return jnp.concatenate([jax.nn.one_hot(obs[..., k], n, dtype=jnp.float32)
                            for k, n in enumerate(self.sizes)], axis=-1)

  def act(self, action):
    """The world's action: the network's action index as it is."""
    return action


def io_for(env, params):
  """What the networks see and act in `env`: a `ShipIO` or a `TaxiIO`."""
  if isinstance(env, jax_ship.ShipSteering):
    return ShipIO(env, params)
  if isinstance(env, jax_taxi.Taxi):
    return TaxiIO(env, params)
  raise ValueError(f"PPO knows the ship and the taxi; got {type(env).__name__}")


# ---- what an ended episode adds to a record row ------------------------------------

@dataclasses.dataclass(frozen=True)
class ShipRow:
  """(episodes, gates, gate_steps, return_sum, j_sum) of the episodes that ended;
  J under MushroomRL's rewards (SPEC section 7, `agents._ship.mushroom_j`, whose
  constants the agent passes)."""
  j_gamma: float
  j_step: float
  j_gate: float
  j_out: float
  fields = ("episodes", "gates", "gate_steps", "return_sum", "j_sum")

  def __call__(self, done, info, ep_return, ep_length):
    event = info["event"]
    passed = done & (event == ship_core.SUCCESS)
    left = done & (event == ship_core.FAILURE)
    length = ep_length.astype(jnp.float32)
    discount = self.j_gamma ** (length - 1.0)
    last = jnp.where(passed, self.j_gate, jnp.where(left, self.j_out, self.j_step))
    j = self.j_step * (1.0 - discount) / (1.0 - self.j_gamma) + discount * last
    d = done.astype(jnp.float32)
    return jnp.stack([d, passed * 1.0, passed * length, d * ep_return, d * j], axis=-1)


@dataclasses.dataclass(frozen=True)
class TaxiRow:
  """(episodes, return_sum, episode_steps, deliveries) of the episodes that ended."""
  fields = ("episodes", "return_sum", "episode_steps", "deliveries")

  def __call__(self, done, info, ep_return, ep_length):
    d = done.astype(jnp.float32)
    delivered = done & (info["outcome"] == taxi_rules.DELIVERED)
    return jnp.stack([d, d * ep_return, d * ep_length, delivered * 1.0], axis=-1)


# ---- the networks: CleanRL's and SB3's MLPs, tanh, orthogonal initialisation -----

def _householder_q(a):
  """Q of the thin QR of `a` (m x k, m >= k) with R's diagonal positive, by Householder
  reflections in plain jnp. Not jnp.linalg.qr: vmapped over seeds, that is LAPACK's
  batched QR, whose kernel splits the batch over XLA's intra-op pool and waits for it;
  two such kernels run at once on a 2-core machine hold both of the pool's threads
  waiting on each other, and a test run hung so for good (jaxlib 0.10.2)."""
  m, k = a.shape
  rows = jnp.arange(m)

  def reflect(j, qr):
    q, r = qr
    x = jnp.where(rows >= j, r[:, j], 0.0)
    alpha = jnp.where(r[j, j] >= 0.0, -1.0, 1.0) * jnp.sqrt(jnp.sum(x * x))
    v = x - alpha * (rows == j)
    norm2 = jnp.sum(v * v)
    v = jnp.where(norm2 > 0.0, v / jnp.sqrt(jnp.where(norm2 > 0.0, norm2, 1.0)), 0.0)
    return q - 2.0 * jnp.outer(q @ v, v), r - 2.0 * jnp.outer(v, v @ r)

  q, r = jax.lax.fori_loop(0, k, reflect, (jnp.eye(m, dtype=a.dtype), a))
  return q[:, :k] * jnp.sign(jnp.diagonal(r)[:k])


def orthogonal(key, n_in, n_out, scale):
  """jax.nn.initializers.orthogonal(scale)(key, (n_in, n_out), float32): the same
  normal draw and the same matrix (to rounding), its QR by `_householder_q`."""
  tall = n_in >= n_out
  a = jax.random.normal(key, (n_in, n_out) if tall else (n_out, n_in), jnp.float32)
  q = _householder_q(a)
  return scale * (q if tall else q.T)


def _dense(key, n_in, n_out, scale):
  return {"kernel": orthogonal(key, n_in, n_out, scale), "bias": jnp.zeros(n_out, jnp.float32)}


def init_mlp(key, sizes, last_scale):
  """A fresh MLP of layer `sizes`, orthogonally initialised (gain sqrt(2), the last
  layer's `last_scale`), biases 0."""
  keys = jax.random.split(key, len(sizes) - 1)
  return [_dense(k, a, b, math.sqrt(2.0) if i < len(sizes) - 2 else last_scale)
          for i, (k, a, b) in enumerate(zip(keys, sizes[:-1], sizes[1:]))]


def mlp(layers, x):
  """The MLP `layers` at x: tanh between layers, linear at the end."""
  for layer in layers[:-1]:
    x = jnp.tanh(x @ layer["kernel"] + layer["bias"])
  return x @ layers[-1]["kernel"] + layers[-1]["bias"]


def init_networks(key, io, net_arch):
  """Fresh actor and critic MLPs with hidden layers `net_arch` (and the Gaussian's
  log_std, 0, for a continuous action)."""
  actor_key, critic_key = jax.random.split(key)
  hidden = list(net_arch)
  networks = {"actor": init_mlp(actor_key, [io.obs_size, *hidden, io.n_outputs], 0.01),
              "critic": init_mlp(critic_key, [io.obs_size, *hidden, 1], 1.0)}
  if not io.discrete:
    networks["log_std"] = jnp.zeros(io.n_outputs, jnp.float32)     # SB3's log_std_init = 0
  return networks


def value(networks, x):
  """The critic's V(x)."""
  return mlp(networks["critic"], x)[..., 0]


def log_prob_entropy(networks, io, x, action):
  """log pi(action | x) and the policy's entropy at x."""
  out = mlp(networks["actor"], x)
  if io.discrete:
    logp_all = jax.nn.log_softmax(out)
    logp = jnp.take_along_axis(logp_all, action[..., None], axis=-1)[..., 0]
    return logp, -jnp.sum(jnp.exp(logp_all) * logp_all, axis=-1)
  log_std = networks["log_std"]
  z = (action - out) / jnp.exp(log_std)
  logp = jnp.sum(-0.5 * z * z - log_std - 0.5 * math.log(2 * math.pi), axis=-1)
  entropy = jnp.sum(log_std + 0.5 * (1.0 + math.log(2 * math.pi)))
  return logp, jnp.broadcast_to(entropy, logp.shape)


def sample_action(networks, io, x, key):
  """An action drawn from the policy at x: an index (softmax) or u (Gaussian)."""
  out = mlp(networks["actor"], x)
  if io.discrete:
    return jax.random.categorical(key, out)
  return out + jnp.exp(networks["log_std"]) * jax.random.normal(key, out.shape)


def greedy_action(networks, io, x):
  """The policy's likeliest action at x: the best index, or the Gaussian's mean."""
  out = mlp(networks["actor"], x)
  return jnp.argmax(out, axis=-1) if io.discrete else out


# ---- Adam (Kingma and Ba 2015) after the gradient's global norm is clipped ------------

def adam_init(params):
  """Adam's fresh state for `params`: the step count and the moments, 0."""
  return {"count": jnp.zeros((), jnp.int32), "mu": jax.tree.map(jnp.zeros_like, params),
          "nu": jax.tree.map(jnp.zeros_like, params)}


def adam_step(params, grads, opt, section):
  """SB3's optimiser: clip the gradient's global norm to max_grad_norm, then
  torch's Adam (beta 0.9, 0.999; eps 1e-5, SB3's for PPO)."""
  norm = jnp.sqrt(sum(jnp.sum(g * g) for g in jax.tree.leaves(grads)))
  grads = jax.tree.map(lambda g: g * jnp.minimum(1.0, section.max_grad_norm / (norm + 1e-6)),
                       grads)
  count = opt["count"] + 1
  mu = jax.tree.map(lambda m, g: 0.9 * m + 0.1 * g, opt["mu"], grads)
  nu = jax.tree.map(lambda v, g: 0.999 * v + 0.001 * g * g, opt["nu"], grads)
  step = section.learning_rate * jnp.sqrt(1.0 - 0.999 ** count) / (1.0 - 0.9 ** count)
  params = jax.tree.map(lambda p, m, v: p - step * m / (jnp.sqrt(v) + 1e-5), params, mu, nu)
  return params, {"count": count, "mu": mu, "nu": nu}


# ---- the run's state, and one transition ----------------------------------------------

class Runner(NamedTuple):
  """A run's whole state (`runner_state` in PureJaxRL): what a checkpoint saves."""
  networks: dict
  opt: dict
  env_state: object          # the copies' EnvState
  obs: jax.Array             # the copies' current observations
  ep_return: jax.Array       # the return of each copy's running episode (task rewards)
  ep_length: jax.Array       # its control steps
  key: jax.Array


class Transition(NamedTuple):
  """One step of one copy's rollout, as PPO's update reads it."""
  x: jax.Array               # the observation as the networks see it
  action: jax.Array          # u (the ship) or the action index (the taxi)
  log_prob: jax.Array
  value: jax.Array
  reward: jax.Array          # scaled, with the bootstrap of a truncated step
  done: jax.Array


@dataclasses.dataclass(frozen=True)
class Trainer:
  """PPO on one world (`env`, `params`) with the task file's `section` and the
  record's `row` (ShipRow or TaxiRow). `init(key)` -> Runner; `update(runner)` ->
  (runner, per-step row sums of shape (n_steps, len(row.fields))); `make_train`
  for whole runs vmapped over seeds."""
  env: object
  params: object
  section: object
  row: object

  def __post_init__(self):
    batch = self.section.n_envs * self.section.n_steps
    if batch % self.section.batch_size:
      raise ValueError(f"[ppo] batch_size = {self.section.batch_size} must divide n_envs x "
                       f"n_steps = {batch} (the rollout is cut into whole minibatches)")
    object.__setattr__(self, "io", io_for(self.env, self.params))

  @property
  def steps_per_update(self):
    """Control steps per `update`: n_envs x n_steps."""
    return self.section.n_envs * self.section.n_steps

  def init(self, key):
    """A fresh `Runner`: networks, optimiser and `n_envs` copies started from `key`."""
    net_key, env_key, key = jax.random.split(key, 3)
    networks = init_networks(net_key, self.io, self.section.net_arch)
    keys = jax.random.split(env_key, self.section.n_envs)
    obs, env_state = jax.vmap(self.env.reset, in_axes=(0, None))(keys, self.params)
    zeros = jnp.zeros(self.section.n_envs, jnp.float32)
    return Runner(networks, adam_init(networks), env_state, obs, zeros,
                  zeros.astype(jnp.int32), key)

  # ---- the rollout: n_steps of every copy ------------------------------------------

  def _rollout_step(self, runner, _):
    s = self.section
    key, act_key, step_key = jax.random.split(runner.key, 3)
    x = self.io.observe(runner.obs)
    action = sample_action(runner.networks, self.io, x, act_key)
    log_prob, _ = log_prob_entropy(runner.networks, self.io, x, action)
    v = value(runner.networks, x)
    keys = jax.random.split(step_key, s.n_envs)
    obs, env_state, obs_end, reward, done, info = jax.vmap(
        lambda k, st, a: self.env.step_keeping_end(k, st, a, self.params))(
        keys, runner.env_state, self.io.act(action))
    reward = reward.astype(jnp.float32)
    ep_return = runner.ep_return + reward
    ep_length = runner.ep_length + 1
    row = jnp.sum(self.row(done, info, ep_return, ep_length), axis=0)
    # SB3's bootstrap of a time limit: gamma V(last observation) added to its reward.
    truncated = info["truncated"]
    last_value = value(runner.networks, self.io.observe(obs_end))
    learned = s.reward_scale * reward + jnp.where(truncated, s.gamma * last_value, 0.0)
    transition = Transition(x, action, log_prob, v, learned, done)
    runner = runner._replace(env_state=env_state, obs=obs, key=key,
                             ep_return=jnp.where(done, 0.0, ep_return),
                             ep_length=jnp.where(done, 0, ep_length))
    return runner, (transition, row)

  # ---- GAE -----------------------------------------------------------------------------

  def _advantages(self, transitions, last_value):
    """Generalised advantage estimation (Schulman et al. 2016, Eq. 16), backwards."""
    s = self.section

    def backwards(carry, t):
      gae, next_value = carry
      not_done = 1.0 - t.done
      delta = t.reward + s.gamma * next_value * not_done - t.value
      gae = delta + s.gamma * s.gae_lambda * not_done * gae
      return (gae, t.value), gae
    _, advantages = jax.lax.scan(backwards, (jnp.zeros_like(last_value), last_value),
                                 transitions, reverse=True)
    return advantages, advantages + transitions.value

  # ---- the loss: clipped surrogate (Eq. 7), value, entropy (Eq. 9) -----------------

  def _loss(self, networks, batch, advantages, targets):
    s = self.section
    log_prob, entropy = log_prob_entropy(networks, self.io, batch.x, batch.action)
    ratio = jnp.exp(log_prob - batch.log_prob)
    adv = (advantages - advantages.mean()) / (advantages.std() + 1e-8)   # SB3's normalisation
    surrogate = jnp.minimum(ratio * adv,
                            jnp.clip(ratio, 1.0 - s.clip_range, 1.0 + s.clip_range) * adv)
    value_loss = jnp.mean((value(networks, batch.x) - targets) ** 2)
    return -surrogate.mean() + s.vf_coef * value_loss - s.ent_coef * entropy.mean()

  def _minibatch(self, carry, minibatch):
    networks, opt = carry
    batch, advantages, targets = minibatch
    grads = jax.grad(self._loss)(networks, batch, advantages, targets)
    return adam_step(networks, grads, opt, self.section), None

  def _epoch(self, carry, key):
    networks, opt, data = carry
    s = self.section
    n = self.steps_per_update
    order = jax.random.permutation(key, n)
    shuffled = jax.tree.map(lambda a: a.reshape((n,) + a.shape[2:])[order], data)
    minibatches = jax.tree.map(
        lambda a: a.reshape((n // s.batch_size, s.batch_size) + a.shape[1:]), shuffled)
    (networks, opt), _ = jax.lax.scan(self._minibatch, (networks, opt), minibatches)
    return (networks, opt, data), None

  # ---- one update: a rollout, then n_epochs over its minibatches ---------------------

  def update(self, runner, _=None):
    """One rollout of n_steps and PPO's epochs on it: (runner, per-step row sums of
    shape (n_steps, len(row.fields)))."""
    runner, (transitions, rows) = jax.lax.scan(self._rollout_step, runner, None,
                                               self.section.n_steps)
    last_value = value(runner.networks, self.io.observe(runner.obs))
    advantages, targets = self._advantages(transitions, last_value)
    key, epoch_key = jax.random.split(runner.key)
    (networks, opt, _), _ = jax.lax.scan(
        self._epoch, (runner.networks, runner.opt, (transitions, advantages, targets)),
        jax.random.split(epoch_key, self.section.n_epochs))
    return runner._replace(networks=networks, opt=opt, key=key), rows

  def make_train(self, n_updates):
    """PureJaxRL's `make_train`: a whole run of `n_updates` updates as one function
    of a key, returning (Runner, rows of shape (n_updates, n_steps, fields));
    `jax.jit(jax.vmap(trainer.make_train(n)))(keys)` trains one run a key."""
    def train(key):
      return jax.lax.scan(self.update, self.init(key), None, n_updates)
    return train

  # ---- greedy episodes from given starts ------------------------------------------------

  def acting(self, runner):
    """What `episodes` acts with: the networks."""
    return runner.networks

  def action(self, networks, x, key, sample):
    """The policy's action at x (what `io.act` takes): greedy (the most likely: the
    Gaussian's mean, the softmax's largest) or, with `sample`, drawn with `key`."""
    return (sample_action(networks, self.io, x, key) if sample
            else greedy_action(networks, self.io, x))

  def episodes(self, networks, starts, key, sample):
    """One episode from each start, all at once, without learning (`sail`), each
    action `action`'s."""
    return sail(self, lambda x, key: self.action(networks, x, key, sample), starts, key)


# ---- episodes from given starts, without learning ---------------------------------------

def sail(trainer, act, starts, key, start=None):
  """One episode from each start (its world state vector, as `reset_to` takes it;
  any batch of starts `start(one)` makes an `(obs, state)` of), all at once,
  `act(x, key)` choosing the actions from what the networks see. Returns the rows
  of `trainer.row` (one an episode) and each episode's length."""
  env, io = trainer.env, trainer.io
  obs, state = jax.vmap(start or env._start_at)(starts)
  n = obs.shape[0]

  def cond(carry):
    return ~jnp.all(carry[3])

  def body(carry):
    obs, state, totals, ended, rows, lengths, key = carry
    key, act_key, step_key = jax.random.split(key, 3)
    action = act(io.observe(obs), act_key)
    obs_, state_, reward, done, info = jax.vmap(env.step_env, in_axes=(0, 0, 0, None))(
        jax.random.split(step_key, n), state, io.act(action), trainer.params)
    live = ~ended
    totals = totals + jnp.where(live, reward, 0.0)
    lengths = lengths + live
    now = live & done
    rows = rows + trainer.row(now, info, totals, lengths)
    keep = lambda a, b: jnp.where(live.reshape((-1,) + (1,) * (a.ndim - 1)), a, b)  # noqa: E731
    return (keep(obs_, obs), jax.tree.map(keep, state_, state), totals, ended | done, rows,
            lengths, key)
  carry = (obs, state, jnp.zeros(n, jnp.float32), jnp.zeros(n, bool),
           jnp.zeros((n, len(trainer.row.fields)), jnp.float32), jnp.zeros(n, jnp.int32), key)
  *_, rows, lengths, _ = jax.lax.while_loop(cond, body, carry)
  return rows, lengths


# ---- the run's state as named arrays (a checkpoint), and back ---------------------------

def _name(path):
  return ".".join(str(getattr(p, "name", getattr(p, "key", getattr(p, "idx", p)))) for p in path)


def to_arrays(runner):
  """{name: numpy array} of every leaf of a Runner, named by its path
  ("networks.actor.0.kernel", "env_state.x", "key", ...)."""
  leaves = jax.tree_util.tree_flatten_with_path(runner)[0]
  return {_name(path): np.array(leaf) for path, leaf in leaves}


def from_arrays(template, arrays, where):
  """A Runner shaped as `template` from `to_arrays`' names; ValueError naming
  the first array that is missing or does not fit."""
  leaves, treedef = jax.tree_util.tree_flatten_with_path(template)
  out = []
  for path, leaf in leaves:
    name = _name(path)
    if name not in arrays:
      raise ValueError(f"{where}: the saved run has no array {name!r}")
    saved = np.asarray(arrays[name])
    if saved.shape != leaf.shape or saved.dtype != leaf.dtype:
      raise ValueError(f"{where}: saved {name!r} is {saved.dtype}{list(saved.shape)}, this "
                       f"task file's run needs {leaf.dtype}{list(leaf.shape)}")
    out.append(jnp.asarray(saved))
  return jax.tree_util.tree_unflatten(treedef, out)


def key(seed):
  """The run's key from its seed."""
  return jax.random.PRNGKey(int(seed))


_COMPILED = {}


def compiled(trainer):
  """`init` (run once a run, op by op: compiling it would cost more than it saves),
  and the jitted `update` and `episodes` of a trainer (PPO's or DQN's; `sac.compiled`
  jits SAC's `init` too), compiled once for all trainers of the same kind, world,
  parameters, section and row (each agent makes its own environment object: a saved
  run loaded, or the seeds of one process)."""
  what = (type(trainer), type(trainer.env), trainer.env.name, trainer.params, trainer.section,
          trainer.row)
  if what not in _COMPILED:
    _COMPILED[what] = (trainer.init, jax.jit(trainer.update),
                       jax.jit(trainer.episodes, static_argnums=3))
  return _COMPILED[what]
