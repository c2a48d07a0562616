"""Stable-Baselines3's `VecEnv` over hpg_mj's native vector environments: an
adapter, not a fork (needs the extra: `pip install 'hpg_mj[sb3]'`).

```python
from hpg_mj.envs import sb3
env = sb3.make_vec_env("hpg_mj/ShipSteering-v0", n_envs=8, seed=0, backend="analytic")
model = stable_baselines3.PPO("MlpPolicy", env).learn(100_000)
```

SB3's own `make_vec_env` steps N single environments one after another in Python
(`DummyVecEnv`, each wrapped in a `Monitor`); `NativeVecEnv` steps all N copies in
one compiled call of the native batch (`hpg_mj.envs.vector`), run in Gymnasium's
"SameStep" autoreset mode, which is SB3's: a copy that ends is reset in the same
step, its last observation in `infos[i]["terminal_observation"]` and
`infos[i]["TimeLimit.truncated"]` set when the time limit (not the task) ended it.

Options, all array operations over the batch:

- `rescale=True`: a bounded Box observation is mapped affinely onto [-1, 1] and
  the policy acts in [-1, 1], mapped onto the action Box (Gymnasium's
  `RescaleAction`), as SB3's SAC and PPO with a Gaussian policy expect.
- `reward_scale`: the rewards SB3 learns from are multiplied by it.

Every finished episode is also counted on the unscaled rewards: its return,
length and how it ended (`finished()`), and `infos[i]["episode"] = {"r", "l"}` as
SB3's `Monitor` writes it (without wall-clock time, so that runs are repeatable).
"""
import gymnasium
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv

import hpg_mj  # noqa: F401  (registers the ids)
from hpg_mj.envs import vector

# How a finished episode ended (the `ending` of `finished()`).
TERMINATED, TRUNCATED = 0, 1


def _unit_box(box):
  return spaces.Box(-1.0, 1.0, box.shape, np.float32)


def _bounded(box):
  return isinstance(box, spaces.Box) and np.all(np.isfinite(box.low)) and \
      np.all(np.isfinite(box.high))


def copy_seeds(seed, n_envs):
  """Per-copy seeds drawn from `seed` by numpy's SeedSequence, so that runs of
  neighbouring seeds share no copy (SB3's `seed + i` would: seed 1's copy 0 is
  seed 0's copy 1)."""
  return [int(s) for s in np.random.SeedSequence(int(seed)).generate_state(n_envs)]


class NativeVecEnv(VecEnv):
  """An SB3 `VecEnv` over one hpg_mj native vector environment (see the module).

  `venv`: a `hpg_mj.envs.vector` batch made with `autoreset_mode="SameStep"`.
  `seed(s)` seeds copy i from `copy_seeds(s, n)[i]` at the next `reset()`.
  """

  def __init__(self, venv, rescale=False, reward_scale=1.0):
    if not isinstance(venv, vector._BatchedEnv):
      raise TypeError(f"NativeVecEnv needs an hpg_mj native vector environment "
                      f"(hpg_mj.envs.vector), got {type(venv).__name__}")
    if venv.autoreset_mode != vector.AutoresetMode.SAME_STEP:
      raise ValueError(f"NativeVecEnv needs autoreset_mode='SameStep' (SB3's), got "
                       f"{venv.autoreset_mode.value!r}")
    if not np.isfinite(reward_scale) or reward_scale <= 0:
      raise ValueError(f"reward_scale must be a positive number, got {reward_scale!r}")
    self.venv = venv
    self.render_mode = None
    obs_space, act_space = venv.single_observation_space, venv.single_action_space
    self.rescale = bool(rescale)
    self._obs_affine = self._act_affine = None
    if self.rescale:
      if _bounded(obs_space):
        low, high = obs_space.low, obs_space.high
        self._obs_affine = ((high + low) / 2.0, (high - low) / 2.0)
        obs_space = _unit_box(obs_space)
      if _bounded(act_space):
        low, high = act_space.low, act_space.high
        self._act_affine = ((high + low) / 2.0, (high - low) / 2.0)
        act_space = _unit_box(act_space)
    self.reward_scale = float(reward_scale)
    super().__init__(venv.num_envs, obs_space, act_space)
    n = venv.num_envs
    self._returns = np.zeros(n)
    self._lengths = np.zeros(n, dtype=np.int64)
    self._finished = []          # see finished()
    self.control_steps = 0       # stepped so far, all copies together
    self._actions = None

  # ---- the transformations, shared with evaluation loops ------------------------

  def observe(self, obs):
    """Native observations as the policy sees them."""
    if self._obs_affine is None:
      return obs
    centre, half = self._obs_affine
    return ((obs - centre) / half).astype(np.float32)

  def act(self, actions):
    """The policy's actions as the native batch takes them."""
    actions = np.asarray(actions)
    if self._act_affine is None:
      return actions
    centre, half = self._act_affine
    return centre + half * np.clip(actions, -1.0, 1.0)

  # ---- VecEnv ---------------------------------------------------------------------

  def seed(self, seed=None):
    if seed is None:
      seed = int(np.random.randint(0, np.iinfo(np.uint32).max, dtype=np.uint32))
    self._seeds = copy_seeds(seed, self.num_envs)
    return self._seeds

  def reset(self):
    """Resets every copy; options set by `set_options(dict)` go to the batch (e.g.
    `{"state": starts}`, one start per copy)."""
    seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
    options = self._options[0] if self._options and self._options[0] else None
    obs, info = self.venv.reset(seed=seeds, options=options)
    self._reset_options()
    self._returns[:] = 0.0
    self._lengths[:] = 0
    self._reset_seeds()
    self.reset_infos = [{} for _ in range(self.num_envs)]
    return self.observe(obs)

  def step_async(self, actions):
    self._actions = self.act(actions)

  def step_wait(self):
    obs, reward, terminated, truncated, info = self.venv.step(self._actions)
    self._returns += reward
    self._lengths += 1
    self.control_steps += self.num_envs
    done = terminated | truncated
    infos = [{} for _ in range(self.num_envs)]
    ended = np.flatnonzero(done)
    if ended.size:
      final_obs = self.observe(np.stack([info["final_obs"][i] for i in ended.tolist()]))
      events = info["final_info"].get("event")
      for k, i in enumerate(ended.tolist()):
        late = bool(truncated[i] and not terminated[i])
        event = None if events is None else events[i]
        infos[i] = {"terminal_observation": final_obs[k], "TimeLimit.truncated": late,
                    "episode": {"r": float(self._returns[i]), "l": int(self._lengths[i])}}
        if event is not None:
          infos[i]["event"] = event
        self._finished.append((self.control_steps, i, float(self._returns[i]),
                               int(self._lengths[i]), TRUNCATED if late else TERMINATED, event,
                               float(reward[i])))
      self._returns[ended] = 0.0
      self._lengths[ended] = 0
    return self.observe(obs), (reward * self.reward_scale).astype(np.float32), done, infos

  def finished(self):
    """The episodes finished since the last call, in the order they ended (copy by
    copy within a step): (control steps stepped when it ended, copy, return,
    length, ending, event, last reward) each."""
    out, self._finished = self._finished, []
    return out

  def close(self):
    self.venv.close()

  def get_attr(self, attr_name, indices=None):
    return [getattr(self, attr_name) if attr_name == "render_mode" else
            getattr(self.venv, attr_name)] * len(self._indices(indices))

  def set_attr(self, attr_name, value, indices=None):
    raise AttributeError(f"NativeVecEnv: the copies of a native batch share their "
                         f"attributes; set {attr_name!r} on the batch (`.venv`) instead")

  def env_method(self, method_name, *args, indices=None, **kwargs):
    raise AttributeError(f"NativeVecEnv: the copies of a native batch are not separate "
                         f"environments; call {method_name!r} on the batch (`.venv`)")

  def env_is_wrapped(self, wrapper_class, indices=None):
    return [False] * len(self._indices(indices))

  def _indices(self, indices):
    if indices is None:
      return range(self.num_envs)
    return [indices] if isinstance(indices, int) else list(indices)


def make_vec_env(env_id, n_envs=1, seed=None, rescale=False, reward_scale=1.0, **env_kwargs):
  """SB3's `make_vec_env(env_id, n_envs, seed)` for an hpg_mj id, on its native
  batch (`gymnasium.make_vec(..., vectorization_mode="vector_entry_point")`)."""
  venv = gymnasium.make_vec(env_id, num_envs=n_envs, vectorization_mode="vector_entry_point",
                            autoreset_mode="SameStep", **env_kwargs)
  env = NativeVecEnv(venv.unwrapped if hasattr(venv, "unwrapped") else venv, rescale,
                     reward_scale)
  if seed is not None:
    env.seed(seed)
  return env
