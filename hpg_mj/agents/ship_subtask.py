"""The paper's two low-level subtasks learned on their own (SPEC sections 3 and 8):
`ship/diagonal` and `ship/straight`, each call a fresh start at the local start
with a uniform heading and turning rate, the CMAC Gaussian-with-sigmoid policy
learned by Eq. 3 with R + G (the discounted trace and the learned baseline b(s)
of `ship_hybrid`), and, as an option, a learned exploration width
(`policies.gaussian_width_act`; `width_alpha = 0` is the paper's sigma = 1).

This is the experiment of issue 12, item 3 (`hpg-mj`-free: `train_subtask` and
`scripts/subtask_width.py`), not a task-file agent: the subtasks are parts of the
hierarchy, and their stand-alone environments are the Gymnasium ids
`hpg_mj/ShipSteeringDiagonal-v0` and `hpg_mj/ShipSteeringStraight-v0`.
"""
import collections
import math

import numba
import numpy as np

from hpg_mj.learners import arrays
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import rng
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core as core

TASKS = {"diagonal": 1, "straight": 2}     # the compass direction whose frame is the global one

# The low level's hyper-parameters, as in ship_hybrid's [low_level], plus the width.
WidthSettings = collections.namedtuple("WidthSettings", (
    "alpha", "trace_gamma", "baseline", "max_steps", "width_alpha", "log_sigma_low",
    "log_sigma_high"))


def check_width(width_alpha, sigma_low, sigma_high, where="[low_level]"):
  """Refuses a width option out of range, naming it and what is allowed."""
  if not (isinstance(width_alpha, (int, float)) and math.isfinite(width_alpha)
          and width_alpha >= 0):
    raise ValueError(f"{where} width_alpha = {width_alpha!r}: must be a finite number >= 0 "
                     "(0: the paper's fixed sigma = 1)")
  if not (0 < sigma_low <= 1.0 <= sigma_high and math.isfinite(sigma_high)):
    raise ValueError(f"{where} sigma_low = {sigma_low!r}, sigma_high = {sigma_high!r}: need "
                     "0 < sigma_low <= 1 <= sigma_high < inf (sigma starts at 1)")


# error_model="numpy" and inlined: less reference counting (learners.policies).
@numba.njit(cache=True, error_model="numpy", inline="always")
def act_and_score(trace, width, values, tiles, s, learn, rng_state, psi, psi_width):
  """The action of a sampled step and its scores on the traces (and, learning with a
  baseline, theta <- theta - alpha b(s) psi for each trace). One rule for every
  ship agent that offers the width: width_alpha = 0 calls the paper's
  `gaussian_act` exactly."""
  if s.width_alpha == 0.0:
    r = policies.gaussian_act(trace, tiles, core.MAX_TURN_RATE, rng_state, psi)
  else:
    r = policies.gaussian_width_act(trace, width, tiles, core.MAX_TURN_RATE, s.log_sigma_low,
                                    s.log_sigma_high, rng_state, psi, psi_width)
  if learn and s.baseline != 0.0:
    policies.subtract_baseline(trace.theta, values, tiles, s.alpha, psi)
    if s.width_alpha != 0.0:
      policies.subtract_baseline(width.theta, values, tiles, s.width_alpha, psi_width)
  return r


# error_model="numpy" and inlined: less reference counting (learners.policies).
@numba.njit(cache=True, error_model="numpy", inline="always")
def learn_step(trace, width, values, tiles, next_tiles, s, signal, ended):
  """Eq. 3 with R + G on both traces, then the baseline's TD(0) step."""
  el.learn(trace, s.alpha, signal, s.trace_gamma)
  if s.width_alpha != 0.0:
    el.learn(width, s.width_alpha, signal, s.trace_gamma)
  if s.baseline != 0.0:
    next_value = 0.0 if ended else policies.tile_mean(values, next_tiles)
    policies.learn_baseline(values, tiles, s.baseline, signal, s.trace_gamma, next_value)


# error_model="numpy": no raising branch on division, less reference counting (learners.policies).
@numba.njit(cache=True, error_model="numpy")
def train(n_episodes, direction, learn, sample, rng_state, trace, width, values, tiling, s,
          success, steps):
  """`n_episodes` stand-alone calls of the subtask of `direction` (1: diagonal, 2:
  straight, whose local frame is the global one); success[i], steps[i] per call."""
  n = tiling.offsets.shape[0]
  tiles = np.empty(n, dtype=np.int64)
  next_tiles = np.empty(n, dtype=np.int64)
  psi = np.empty(n)
  psi_width = np.empty(n)
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  local_samples = np.empty_like(samples)
  local = np.empty(4)
  state = np.empty(4)
  origin = np.empty(2)
  sx, sy = core.local_start(direction)
  for episode in range(n_episodes):
    state[0] = sx
    state[1] = sy
    state[2] = core.wrap_deg(rng.uniform_range(rng_state, -180.0, 180.0))
    state[3] = rng.uniform_range(rng_state, -core.MAX_TURN_RATE, core.MAX_TURN_RATE)
    origin[0] = sx
    origin[1] = sy
    el.reset(trace)                                       # Eq. 3: z <- 0
    el.reset(width)
    k = 0
    core.global_to_local(state, origin, direction, local)
    tiles_mod.active_tiles(local, tiling, tiles)
    while True:
      if sample:
        r = act_and_score(trace, width, values, tiles, s, learn, rng_state, psi, psi_width)
      else:
        r = policies.gaussian_greedy(trace, tiles, core.MAX_TURN_RATE)
      core.euler_control(state, r, samples)
      k += 1
      event, internal = core.low_level_outcome(samples, state, origin, direction, k,
                                               local_samples, local, s.max_steps)
      ended = event != core.NO_EVENT
      if not ended:     # the next state, already local (`low_level_outcome`), and its tiles
        tiles_mod.active_tiles(local, tiling, next_tiles)
      if learn:
        learn_step(trace, width, values, tiles, next_tiles, s, core.STEP_REWARD + internal,
                   ended)
      if ended:
        success[episode] = event == core.SUCCESS
        steps[episode] = k
        break
      arrays.copy_into(tiles, next_tiles)


def paper_coder(n_tilings=9, n_tiles=(5, 5, 36, 5)):
  """SPEC section 3's CMAC over the local (x, y, theta, theta_dot)."""
  return tiles_mod.TileCoder((0.0, 0.0, -180.0, -core.MAX_TURN_RATE),
                             (core.LOCAL_SIZE, core.LOCAL_SIZE, 180.0, core.MAX_TURN_RATE),
                             tuple(n_tiles), (False, False, True, False), n_tilings)


def train_subtask(task, episodes, seed, alpha=0.01, trace_gamma=0.99, baseline=0.3,
                  width_alpha=0.0, sigma_low=0.25, sigma_high=4.0, max_steps=300,
                  greedy_every=0, greedy_episodes=0):
  """Learns one stand-alone subtask; returns {"success": per-call 0/1, "steps": ...,
  and, with greedy_every, "greedy": greedy success rates every greedy_every calls}.
  The shipped hybrid's low level by default (alpha 0.01, trace_gamma 0.99,
  baseline 0.3); width_alpha > 0 adds the learned width."""
  if task not in TASKS:
    raise ValueError(f"subtask {task!r} is not known; allowed: {sorted(TASKS)}")
  check_width(width_alpha, sigma_low, sigma_high)
  direction = TASKS[task]
  coder = paper_coder()
  tiling = coder.arrays()
  trace, width = el.new_trace(coder.size), el.new_trace(coder.size)
  values = np.zeros(coder.size)
  s = WidthSettings(float(alpha), float(trace_gamma), float(baseline), int(max_steps),
                    float(width_alpha), math.log(sigma_low), math.log(sigma_high))
  state = rng.make_state(int(seed))
  success = np.zeros(episodes)
  steps = np.zeros(episodes)
  greedy = []
  chunk = greedy_every or episodes
  for start in range(0, episodes, chunk):
    n = min(chunk, episodes - start)
    train(n, direction, True, True, state, trace, width, values, tiling, s,
          success[start:start + n], steps[start:start + n])
    if greedy_every:
      ok = np.zeros(greedy_episodes)
      probe = rng.make_state(10_000)          # the same 1,000 starts for every seed
      train(greedy_episodes, direction, False, False, probe, trace, width, values, tiling, s,
            ok, np.zeros(greedy_episodes))
      greedy.append(ok.mean())
  return {"success": success, "steps": steps, "greedy": np.array(greedy),
          "sigma": np.exp(np.clip(el.parameters(width), s.log_sigma_low, s.log_sigma_high))}
