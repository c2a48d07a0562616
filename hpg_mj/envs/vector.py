"""Native batched Gymnasium environments: `gymnasium.make_vec(id, num_envs=N)` for the
ship and taxi ids (`vectorization_mode="vector_entry_point"`, the default for them).

Thin siblings of the single environments over the same compiled world rules, as
Gymnasium's `CartPoleVectorEnv` is of `CartPoleEnv`: one numba call steps every
copy (`ship_core.task_step_batch`, `taxi_rules.step_batch`). With the same seeds
and actions, copy i follows exactly the single environment reset with seed
`seed + i` (a list of seeds: its i-th entry), as `SyncVectorEnv` over single
environments does; each copy draws its starts from its own generator.

Autoreset (`autoreset_mode`, declared in `metadata["autoreset_mode"]`), as
Gymnasium's `SyncVectorEnv` defines each mode:

- `"NextStep"` (default): a copy that ended is reset by the next `step()`, which
  ignores its action and returns its start with reward 0 and no end flags.
- `"SameStep"`: a copy that ends is reset in the same `step()`; the observation
  returned is the new start, the last one is in `info["final_obs"]` and its info
  in `info["final_info"]` (masks `_final_obs`, `_final_info`).
- `"Disabled"`: nothing is reset; reset copies with
  `reset(options={"reset_mask": mask})`; stepping a copy that ended is an error.

Infos hold arrays over the batch with a boolean mask `_<key>` saying which copies
the entry is for (Gymnasium's vector info convention).
"""
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from hpg_mj import envs
from hpg_mj.envs import ship as ship_env
from hpg_mj.worlds import ship_core
from hpg_mj.worlds import ship_task
from hpg_mj.worlds import taxi_core
from hpg_mj.worlds import taxi_rules

AUTORESET_MODES = {mode.value: mode for mode in AutoresetMode}


def _autoreset_mode(mode, who):
  if isinstance(mode, AutoresetMode):
    return mode
  if mode in AUTORESET_MODES:
    return AUTORESET_MODES[mode]
  raise ValueError(f"{who}: unknown autoreset_mode {mode!r}; allowed: "
                   f"{sorted(AUTORESET_MODES)} or a gymnasium.vector.AutoresetMode")


def _seeds(seed, num_envs, who):
  """Per-copy seeds, Gymnasium's convention: None, an int s (s, s+1, ...) or a list."""
  if seed is None:
    return [None] * num_envs
  if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
    return [int(seed) + i for i in range(num_envs)]
  if isinstance(seed, (list, tuple)):
    if len(seed) != num_envs:
      raise ValueError(f"{who}: a list of seeds needs one per copy ({num_envs}), got {len(seed)}")
    for s in seed:
      if s is not None and (not isinstance(s, (int, np.integer)) or isinstance(s, bool)):
        raise ValueError(f"{who}: each seed must be an int or None, got {s!r}")
    return list(seed)
  raise ValueError(f"{who}: seed must be None, an int or a list of {num_envs} ints/None, "
                   f"got {seed!r}")


class _BatchedEnv(VectorEnv):
  """Seeding, resets and Gymnasium's autoreset modes; subclasses hold the world.

  A subclass sets the spaces and implements `_start(indices, options)` (puts
  copies `indices` at a start drawn from `self._rngs[i]` or given in `options`),
  `_advance(actions, active)` (steps the `active` copies in one compiled call;
  returns rewards, terminated, truncated), `_observations()`, `_check_actions`,
  `_step_info(active)` and `_reset_info(indices)`.
  """

  RESET_OPTIONS = ("reset_mask",)

  def __init__(self, num_envs, autoreset_mode, who):
    self.who = who
    if (not isinstance(num_envs, (int, np.integer)) or isinstance(num_envs, bool)
        or num_envs < 1):
      raise ValueError(f"{who}: num_envs must be a positive integer, got {num_envs!r}")
    self.num_envs = int(num_envs)
    self.autoreset_mode = _autoreset_mode(autoreset_mode, who)
    self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
    self.render_mode = None
    self._rngs = [None] * self.num_envs
    self._ended = np.zeros(self.num_envs, dtype=np.bool_)   # ended at the last step
    self._started = False

  def _observation_of(self, observations, i):
    """Copy i's observation out of the batch's (a dictionary's subclass says how)."""
    return observations[i]

  def reset(self, *, seed=None, options=None):
    seeds = _seeds(seed, self.num_envs, self.who)
    options = dict(options or {})
    unknown = set(options) - set(self.RESET_OPTIONS)
    if unknown:
      raise ValueError(f"{self.who}: unknown reset options {sorted(unknown)}; allowed: "
                       f"{list(self.RESET_OPTIONS)}")
    mask = options.pop("reset_mask", None)
    if mask is None:
      indices = np.arange(self.num_envs)
    else:
      mask = np.asarray(mask)
      if mask.shape != (self.num_envs,) or mask.dtype != np.bool_ or not mask.any():
        raise ValueError(f"{self.who}: options['reset_mask'] must be a bool array of shape "
                         f"({self.num_envs},) with at least one True, got {mask!r}")
      if not self._started:
        raise RuntimeError(f"{self.who}: the first reset() resets every copy; "
                           "reset_mask is for later resets")
      indices = np.flatnonzero(mask)
    for i in indices.tolist():
      if seeds[i] is not None or self._rngs[i] is None:
        self._rngs[i], _ = seeding.np_random(seeds[i])   # as gymnasium.Env.reset does
    self._start(indices, options)
    self._ended[indices] = False
    self._started = True
    return self._observations(), self._reset_info(indices)

  def step(self, actions):
    if not self._started:
      raise RuntimeError(f"{self.who}: call reset() before step()")
    actions = self._check_actions(actions)
    mode = self.autoreset_mode
    if mode == AutoresetMode.DISABLED and self._ended.any():
      raise RuntimeError(f"{self.who}: copies {np.flatnonzero(self._ended).tolist()} have "
                         "ended and autoreset_mode is Disabled; reset them with "
                         "reset(options={'reset_mask': mask}) before step()")
    active = ~self._ended if mode == AutoresetMode.NEXT_STEP else np.ones(self.num_envs, bool)
    reward, terminated, truncated = self._advance(actions, active)
    info = self._step_info(active)
    if mode == AutoresetMode.NEXT_STEP:
      restart = np.flatnonzero(self._ended)
      if restart.size:
        self._start(restart, {})
        reward[restart] = 0.0
        terminated[restart] = False
        truncated[restart] = False
        _merge_info(info, self._reset_info(restart), restart, self.num_envs)
    elif mode == AutoresetMode.SAME_STEP:
      restart = np.flatnonzero(terminated | truncated)
      if restart.size:
        final_obs = np.full(self.num_envs, None, dtype=object)
        last = self._observations()
        for i in restart.tolist():
          final_obs[i] = self._observation_of(last, i)
        final_info = _select_info(info, restart, self.num_envs)
        self._start(restart, {})
        _drop_info(info, restart)
        _merge_info(info, self._reset_info(restart), restart, self.num_envs)
        mask = np.zeros(self.num_envs, dtype=np.bool_)
        mask[restart] = True
        info.update({"final_obs": final_obs, "_final_obs": mask,
                     "final_info": final_info, "_final_info": mask.copy()})
    # SameStep has already reset the copies that ended.
    self._ended = (terminated | truncated) if mode != AutoresetMode.SAME_STEP else \
        np.zeros(self.num_envs, dtype=np.bool_)
    return self._observations(), reward, terminated, truncated, info


def _select_info(info, indices, num_envs):
  """The entries of `info` for copies `indices` only (the others masked out)."""
  out = {}
  for key, value in info.items():
    if key.startswith("_"):
      continue
    mask = np.zeros(num_envs, dtype=np.bool_)
    mask[indices] = info["_" + key][indices]
    out[key] = value.copy()
    out["_" + key] = mask
  return out


def _drop_info(info, indices):
  for key in list(info):
    if key.startswith("_"):
      info[key][indices] = False


def _merge_info(info, other, indices, num_envs):
  """Writes `other`'s entries for copies `indices` into `info`."""
  for key, value in other.items():
    if key.startswith("_"):
      continue
    if key not in info:
      info[key] = np.zeros_like(value)
      info["_" + key] = np.zeros(num_envs, dtype=np.bool_)
    info[key][indices] = value[indices]
    info["_" + key][indices] = other["_" + key][indices]


def _check_batch(actions, num_envs, shapes, who):
  arr = np.asarray(actions)
  if arr.dtype.kind not in "biuf":
    raise ValueError(f"{who}: actions must be numbers, got dtype {arr.dtype}")
  if arr.shape not in shapes:
    raise ValueError(f"{who}: actions for {num_envs} copies must have shape "
                     f"{' or '.join(str(s) for s in shapes)}, got shape {arr.shape}")
  return arr.reshape(num_envs)


# ---- ship ---------------------------------------------------------------------------

class _AnalyticShips:
  """Equation 1 for the whole batch, inside `task_step_batch` (compiled, one call)."""

  integrate = True

  def __init__(self, num_envs):
    pass

  def set_state(self, states, i, state):
    states[i] = state

  def control(self, states, r, active, samples):
    pass


class _MujocoShips:
  """One MJCF ship per copy, stepped in a Python loop (each `mj_step` is MuJoCo's);
  the rules then run compiled over the whole batch."""

  integrate = False

  def __init__(self, num_envs, make_ship=ship_env.MujocoBackend):
    self.ships = [make_ship() for _ in range(num_envs)]

  def set_state(self, states, i, state):
    self.ships[i].set_state(state)
    states[i] = self.ships[i].state()

  def control(self, states, r, active, samples):
    for i in np.flatnonzero(active).tolist():
      samples[i], states[i] = self.ships[i].control(float(r[i]))


class ShipSteeringVectorEnv(_BatchedEnv):
  """A batch of `num_envs` ship steering environments (`ShipSteeringEnv`'s manual).

  `gymnasium.make_vec("hpg_mj/ShipSteering-v0", num_envs=N, backend="analytic")`
  steps all N ships in one compiled call. `backend="mujoco"` (the default, as for
  the single environment) steps N MJCF ships one after another in Python, then
  applies the rules to all in one call.

  Actions: `Box(-15, 15, (N, 1), float64)` (shape `(N,)` is accepted too);
  clipped to the range, or refused with `strict=True`; NaN and infinity raise a
  `ValueError` naming the copy. Observations: `(N, 4)` float64, rows as the
  single environment's `[x, y, theta_deg, theta_dot_deg]`.

  Infos: `event` (object array of the single environment's event names, None
  for none) and `positions`, an `(N, 4, 2)` float array of the positions sampled
  during the step (masked out for copies that did not step); for the patrol, on
  a step where a copy left the field, `state_before_restart` `(N, 4)`, masked to
  the copies that did.

  Arguments: `num_envs`, `task`, `backend`, `strict`, `max_steps`,
  `gate_reward`, `out_of_bounds_reward`, `level` as for `ShipSteeringEnv`, and
  `autoreset_mode` ("NextStep", "SameStep" or "Disabled"). Reset options:
  `state` (an `(N, 4)` array of exact starts, or one state for every copy reset)
  and `reset_mask`. No rendering: render one copy with the single environment.
  """

  metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}
  RESET_OPTIONS = ("reset_mask", "state")

  def __init__(self, num_envs=1, task="steer", backend="mujoco", strict=False, max_steps=None,
               gate_reward=ship_core.GATE_REWARD,
               out_of_bounds_reward=ship_core.OUT_OF_BOUNDS_REWARD,
               autoreset_mode=AutoresetMode.NEXT_STEP, render_mode=None, level=None):
    who = f"ShipSteeringVectorEnv({task}, backend={backend})"
    envs.refuse_level(who, level)
    super().__init__(num_envs, autoreset_mode, who)
    if render_mode is not None:
      raise ValueError(f"{who}: render_mode {render_mode!r} is not supported by the batch; "
                       "allowed: None (render a single ShipSteeringEnv)")
    self.rules = ship_task.ShipRules(task, max_steps, gate_reward, out_of_bounds_reward)
    self._ships = self._make_ships(backend)
    self.task, self.backend, self.strict = task, backend, bool(strict)
    self.single_observation_space, self.single_action_space = ship_env.spaces_of(self.rules)
    self.observation_space = batch_space(self.single_observation_space, self.num_envs)
    self.action_space = batch_space(self.single_action_space, self.num_envs)
    n = self.num_envs
    self._states = np.zeros((n, 4))
    self._samples = np.zeros((n, ship_core.SAMPLES_PER_CONTROL + 1, 2))
    self._steps = np.zeros(n, dtype=np.int64)
    self._event = np.zeros(n, dtype=np.int64)
    self._reward = np.zeros(n)
    self._terminated = np.zeros(n, dtype=np.bool_)
    self._truncated = np.zeros(n, dtype=np.bool_)
    self._left = np.zeros((n, 4))                  # patrol: where a restarted copy left
    self._restarted = np.zeros(n, dtype=np.bool_)
    self._is_steer = self.rules.goal is None
    self._goal = np.zeros(2) if self._is_steer else self.rules.goal.copy()
    self._shapes = ((n, 1), (n,))

  def _make_ships(self, backend):
    """The batch's ships (a task on other water brings its own)."""
    if backend == "analytic":
      return _AnalyticShips(self.num_envs)
    if backend == "mujoco":
      return _MujocoShips(self.num_envs)
    raise ValueError(f"unknown ship backend {backend!r}; valid backends: "
                     f"{list(ship_env.BACKENDS)}")

  def _option_rows(self, options, key, size, what):
    """options[key] as float64: one row (size,) for every copy or one per copy
    (num_envs, size); None where not given; else one line."""
    given = options.get(key)
    if given is None:
      return None
    given = np.asarray(given, dtype=np.float64)
    if given.shape not in ((size,), (self.num_envs, size)):
      raise ValueError(f"{self.who}: options[{key!r}] must be one {what} ({size},) or one per "
                       f"copy ({self.num_envs}, {size}), got shape {given.shape}")
    return given

  def _start(self, indices, options):
    given = self._option_rows(options, "state", 4, "state")
    for i in indices.tolist():
      if given is None:
        state = self.rules.sample_start(self._rngs[i])
      else:
        state = self.rules.check_state(given if given.ndim == 1 else given[i],
                                       f"{self.who} copy {i}")
      self._ships.set_state(self._states, i, state)
    self._steps[indices] = 0

  def _check_actions(self, actions):
    r = _check_batch(actions, self.num_envs, self._shapes, self.who).astype(np.float64)
    finite = np.isfinite(r)
    if not finite.all():
      i = int(np.flatnonzero(~finite)[0])
      raise ValueError(f"{self.who}: turning rate r (deg/s) of copy {i} must be finite, "
                       f"got {float(r[i])!r}")
    low, high = -ship_core.MAX_TURN_RATE, ship_core.MAX_TURN_RATE
    outside = (r < low) | (r > high)
    if outside.any():
      if self.strict:
        i = int(np.flatnonzero(outside)[0])
        raise ValueError(f"{self.who}: turning rate r (deg/s) {float(r[i])!r} of copy {i} is "
                         f"outside the allowed range [{low}, {high}] (strict=True; without "
                         "strict it is clipped)")
      np.clip(r, low, high, out=r)
    return r

  def _advance(self, r, active):
    self._ships.control(self._states, r, active, self._samples)
    ship_core.task_step_batch(
        self._states, r, active, self._samples, self._steps, self._ships.integrate,
        self._is_steer, self._goal, self.rules.size, self.rules.max_steps,
        self.rules.success_reward, self.rules.failure_reward,
        (self._event, self._reward, self._terminated, self._truncated))
    if self.rules.continuing:     # SPEC section 8, as `ShipSteeringEnv.step`
      self._terminated[active] = False
      self._truncated[active] = self._steps[active] >= self.rules.max_steps
      self._restarted[:] = active & (self._event == ship_core.FAILURE)
      for i in np.flatnonzero(self._restarted).tolist():
        self._left[i] = self._states[i]
        self._ships.set_state(self._states, i, self.rules.sample_start(self._rngs[i]))
    return self._reward.copy(), self._terminated.copy(), self._truncated.copy()

  def _observations(self):
    return self._states.copy()

  def _event_names(self, active):
    names = np.full(self.num_envs, None, dtype=object)
    table = self._event_table()
    for i in np.flatnonzero(active & (self._event != ship_core.NO_EVENT)).tolist():
      names[i] = table[int(self._event[i])]
    return names

  def _event_table(self):
    """The events' names by number (the rules')."""
    return self.rules.event_names

  def _step_info(self, active):
    info = {"event": self._event_names(active), "_event": np.ones(self.num_envs, np.bool_),
            "positions": self._samples.copy(), "_positions": active.copy()}
    if self.rules.continuing and (self._restarted & active).any():   # as ShipSteeringEnv
      info["state_before_restart"] = self._left.copy()
      info["_state_before_restart"] = self._restarted & active
    return info

  def _reset_info(self, indices):
    mask = np.zeros(self.num_envs, dtype=np.bool_)
    mask[indices] = True
    return {"event": np.full(self.num_envs, None, dtype=object), "_event": mask}


# ---- taxi ---------------------------------------------------------------------------

class TaxiVectorEnv(_BatchedEnv):
  """A batch of `num_envs` taxis (`TaxiEnv`'s manual), stepped in one compiled call.

  `gymnasium.make_vec("hpg_mj/TaxiFuel-v0", num_envs=N)` (or `hpg_mj/Taxi-v0`).
  Actions: `MultiDiscrete([7] * N)` (6 without fuel); a value that is not an
  integer action raises a `ValueError` naming the copy and what is allowed.
  Observations: `(N, 5)` int64 (`(N, 4)` without fuel). Infos: `action_mask`,
  an `(N, 7)` int8 array (`(N, 6)`), as the single environment's.

  Arguments: `num_envs`, `fuel`, `max_steps`, `fuel_station`, `capacity`,
  `start_fuel`, `level` as for `TaxiEnv`, and `autoreset_mode`. Reset options: `state`
  (an `(N, 5)` array, or one state for every copy reset; strict as `TaxiEnv`'s
  default, a passenger waiting at its destination is refused) and `reset_mask`.
  """

  metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}
  RESET_OPTIONS = ("reset_mask", "state")

  def __init__(self, num_envs=1, fuel=True, max_steps=taxi_core.MAX_STEPS,
               fuel_station=taxi_core.FUEL_STATION, capacity=taxi_core.FUEL_CAPACITY,
               start_fuel=(taxi_core.START_FUEL_MIN, taxi_core.START_FUEL_MAX),
               autoreset_mode=AutoresetMode.NEXT_STEP, render_mode=None, level=None):
    who = "TaxiVectorEnv(" + ("hpg_mj/TaxiFuel-v0" if fuel else "hpg_mj/Taxi-v0") + ")"
    envs.refuse_level(who, level)
    super().__init__(num_envs, autoreset_mode, who)
    if render_mode is not None:
      raise ValueError(f"{who}: render_mode {render_mode!r} is not supported by the batch; "
                       "allowed: None (render a single TaxiEnv)")
    self.rules = taxi_core.TaxiRules(fuel, fuel_station=fuel_station, capacity=capacity,
                                     start_fuel=start_fuel, max_steps=max_steps, who=who)
    self._world = taxi_rules.world_config(self.rules)
    nvec = [taxi_core.GRID_SIZE, taxi_core.GRID_SIZE, 5, 4]
    if self.rules.fuel_enabled:
      nvec.append(self.rules.capacity + 1)
    self._n_obs = len(nvec)
    self.single_observation_space = spaces.MultiDiscrete(nvec, dtype=np.int64)
    self.single_action_space = spaces.Discrete(self.rules.num_actions)
    self.observation_space = batch_space(self.single_observation_space, self.num_envs)
    self.action_space = batch_space(self.single_action_space, self.num_envs)
    n = self.num_envs
    self._states = np.zeros((n, 5), dtype=np.int64)
    self._steps = np.zeros(n, dtype=np.int64)
    self._reward = np.zeros(n)
    self._terminated = np.zeros(n, dtype=np.bool_)
    self._truncated = np.zeros(n, dtype=np.bool_)
    self._masks = np.zeros((n, self.rules.num_actions), dtype=np.int8)

  def _start(self, indices, options):
    given = options.get("state")
    if given is not None:
      given = np.asarray(given)
      if given.shape not in ((self._n_obs,), (self.num_envs, self._n_obs)):
        raise ValueError(f"{self.who}: options['state'] must be one state ({self._n_obs},) or "
                         f"one per copy ({self.num_envs}, {self._n_obs}), got shape "
                         f"{given.shape}")
    for i in indices.tolist():
      if given is None:
        self._states[i] = self.rules.sample_start(self._rngs[i])
      else:
        self._states[i] = self.rules.check_state(given if given.ndim == 1 else given[i])
    self._steps[indices] = 0
    taxi_rules.fill_masks(self._states, indices, self._world, self._masks)

  def _check_actions(self, actions):
    arr = _check_batch(actions, self.num_envs, ((self.num_envs,),), self.who)
    n = self.rules.num_actions
    if arr.dtype.kind == "f":
      bad = ~np.isfinite(arr) | (arr != np.round(arr))
      if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{self.who}: action of copy {i} must be an integer in 0..{n - 1}, "
                         f"got {arr[i].item()!r}")
    actions = arr.astype(np.int64)
    bad = (actions < 0) | (actions >= n)
    if bad.any():
      i = int(np.flatnonzero(bad)[0])
      allowed = ", ".join(f"{k} {s}" for k, s in enumerate(self.rules.action_names))
      raise ValueError(f"{self.who}: action {int(actions[i])} of copy {i} is not one of "
                       f"{allowed}")
    return actions

  def _advance(self, actions, active):
    taxi_rules.step_batch(self._states, actions, active, self._steps, self._world,
                          self._reward, self._terminated, self._truncated, self._masks)
    return self._reward.copy(), self._terminated.copy(), self._truncated.copy()

  def _observations(self):
    return self._states[:, :self._n_obs].copy()

  def _step_info(self, active):
    return {"action_mask": self._masks.copy(), "_action_mask": np.ones(self.num_envs, np.bool_)}

  def _reset_info(self, indices):
    mask = np.zeros(self.num_envs, dtype=np.bool_)
    mask[indices] = True
    return {"action_mask": self._masks.copy(), "_action_mask": mask}
