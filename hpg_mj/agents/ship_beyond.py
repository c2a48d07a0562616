"""A route past the paper's (SPEC section 8; issue 12, item 4): a root that sees
its cell and the ship's coarse heading, and chooses a point to steer to; one
low-level subtask, *aim*, that steers straight to a continuous target.

Why: the paper's root can only chain whole 100 / 141 m legs along eight compass
directions, and each leg begins by turning onto its direction (SPEC section 2:
~265-270 control steps against the ~205-step straight line). Here the root has
four choices: *gate*, steer to the point of the gate nearest the ship (a
continuous target, followed as the ship moves), or one of three *approach*
points before the gate line on the ship's side (for starts from which the
straight line to the gate runs along its line or past its posts). One call sails
the whole way from most starts. The root sees its cell and the heading's sector,
through several offset tilings of them (Q(lambda) linear in the tiles,
`qlambda.tiled_update`): why, see `tasks/ship_hybrid_beyond.toml` (with a table of
cells, the value of a choice the root had stopped making stayed where a few early
returns had put it, far below what it would now earn).

The *aim* subtask's state is the heading error to its target (wrapped), the
turning rate and the distance (clipped), over a CMAC, with errors beyond
`reflect_deg` on one side reflected onto the other (the turning rate negated, and
the policy's r with it), so that one set of tiles learns every large turn and the
ship turns the short way round; its policy is the paper's
Gaussian with sigmoid, learned by Eq. 3 with R + G (G the paper's heading shaping
towards the target, +100 within `radius` of it or through the gate, -100 off the
field or after `max_steps`), the discounted trace and the learned baseline b(s)
of `ship_hybrid`, and optionally the learned exploration width
(`policies.gaussian_choose` with a width). The map from the world to this state is an
isometry of Equation 1 (a translation and a rotation, and for the reflected
errors a reflection with r -> -r), as SPEC section 3 asks of the paper's local
frames. Only the -1s, the gate's reward and the field's penalty
reach the root (Watkins's Q(lambda) over the SMDP of calls, as the hybrid's).

Its compiled rules and fused loop are `hpg_mj.hierarchy.route`.
"""
import dataclasses

import numpy as np

from hpg_mj.agents import _ship
from hpg_mj.taskfile import param
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy import route
from hpg_mj.hierarchy.graph import Child, Primitive, Subtask, TaskGraph
# Settings is read here too: a numba cache written before the route's rules moved to
# hierarchy.route names it at this module, and must still load to be found stale.
from hpg_mj.hierarchy.route import (AIM_RUNS, AIM_SUCCESS, CALLS, N_RECORD, RootTable, Settings,
                                    aim_coder, aim_outcome, aim_view, n_targets, offered,
                                    root_coder, root_tiles, settings, side_of, target_of, train)
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import schedules
from hpg_mj.learners import stepwise as learners
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core as core


# ---- the task file's schema --------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Root:
  """[root]: Watkins's Q(lambda) over tiles of (position, heading), choosing a target."""
  learner: str = param("q_lambda", "the root's learner", choices=("q_lambda",))
  alpha: float = param(0.1, "Q(lambda) step size", low=0, low_open=True)
  trace_decay: float = param(0.9, "Q(lambda)'s lambda", low=0, high=1)
  epsilon: float = param(0.3, "exploration, held until the aim subtask passes "
                         "epsilon_threshold", low=0, high=1)
  epsilon_threshold: float = param(0.8, "aim success rate over epsilon_window runs that "
                                   "starts the decay", low=0, high=1)
  epsilon_window: int = param(1000, "aim runs the threshold looks at", low=1)
  epsilon_every: int = param(50, "episodes between divisions of epsilon", low=1)
  epsilon_divisor: float = param(1.01, "epsilon is divided by this", low=1)
  cell_m: float = param(50.0, "side of the root's square cells (m)", low=10, high=1000)
  headings: int = param(8, "sectors of the heading the root sees (1: none)", low=1, high=72)
  tilings: int = param(1, "tilings of the cells and sectors, each offset by k/tilings of a "
                       "tile (1: the table; more: Q generalises between neighbours and "
                       "resolves finer)", low=1, high=64)
  inset_m: float = param(route.INSET_M, "the gate action aims at the gate with its posts moved in "
                         "by this (m)", low=0, high=49)
  approach_m: float = param(route.APPROACH_M, "how far before the gate line the approach points lie (m)",
                            low=0, low_open=True, high=300)
  approach_within_m: float = param(1000.0, "the approach points are offered only within "
                                   "this distance of the gate line (1000: everywhere); "
                                   "beyond it the root's one choice is the gate", low=0,
                                   high=1000)


@dataclasses.dataclass(frozen=True)
class LowLevel:
  """[low_level]: the aim subtask, learned by Eq. 3."""
  learner: str = param("policy_gradient", "Eq. 3", choices=("policy_gradient",))
  alpha: float = param(0.01, "Eq. 3 step size", low=0, low_open=True)
  trace_gamma: float = param(0.99, "discount on the Eq. 3 trace (1 = plain Eq. 3)", low=0,
                             high=1, low_open=True)
  baseline: float = param(0.3, "TD(0) step size of a baseline b(s) over the policy's tiles "
                          "(0: none)", low=0, high=1)
  width_alpha: float = param(0.0, "Eq. 3 step size of the learned exploration width "
                             "log sigma(s) (0: the paper's sigma = 1)", low=0)
  sigma_low: float = param(0.25, "the learned width's lower clip", low=0, low_open=True,
                           high=1)
  sigma_high: float = param(1.0, "the learned width's upper clip", low=1, high=100)
  shaping: float = param(1.0, "weight of the heading shaping G (1: SPEC section 3's G, "
                         "0: none)", low=0, high=10)
  radius_m: float = param(route.RADIUS_M, "within this distance of its target a call has succeeded",
                          low=0, low_open=True)
  error_scale: str = param("sqrt", "the heading error's scale on the tiles: sqrt (finer "
                           "near 0) or linear", choices=("sqrt", "linear"))
  tilings: int = param(9, "CMAC tilings", low=1)
  reflect_deg: float = param(180.0, "beyond this heading error (deg) on the ship's negative "
                             "side the aim state is reflected to the positive side (180: "
                             "never)", low=0, high=180)
  tiles: tuple = param((36, 6, 4), "tiles per tiling over heading error (wraps; reflected, "
                       "over [-reflect_deg, 180], not wrapping), turning rate, distance",
                       length=3, low=1)
  max_steps: int = param(600, "control steps, then the call has failed", low=1)


@dataclasses.dataclass(frozen=True)
class Config:
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)
  root: Root = dataclasses.field(default_factory=Root)
  low_level: LowLevel = dataclasses.field(default_factory=LowLevel)


class _Reflected:
  """The aim learner on the step-by-step path: its turning rate times the side of
  the last view (`aim_view`'s reflection)."""

  def __init__(self, learner):
    self.learner = learner
    self.side = 1.0

  def act(self, features, mask, rng_state, sample):
    return self.side * self.learner.act(features, mask, rng_state, sample)

  def __getattr__(self, name):
    return getattr(self.learner, name)


class ShipBeyond(_ship.ShipAgent):
  """A root over (cell, heading) that picks points; an aim subtask that steers there."""

  name = "ship_beyond"
  Config = Config
  record_fields = ("passed", "steps", "calls", "aim_runs", "aim_successes", "return")

  def __init__(self, config=None, seed=0, task=None):
    super().__init__(config, seed, task)
    root, low = self.config.root, self.config.low_level
    blocks.check_width(low.width_alpha, low.sigma_low, low.sigma_high, "[low_level]")
    self.s: Settings = settings(self.config)
    self.coder = aim_coder(low)
    self.tile_arrays = self.coder.arrays()
    self.schedule, self.outcomes, self.counts = schedules.new_schedule(root.epsilon,
                                                                   root.epsilon_window)
    self.root_coder = root_coder(root)
    self.root_tiling = self.root_coder.arrays()
    self.root = learners.TiledQLambda(self.root_coder.size, root.tilings, n_targets(self.s),
                                      root.alpha, root.trace_decay,
                                      epsilon_source=lambda: self.schedule[0])
    self.low = learners.GaussianPolicyGradient(self.coder.size, low.tilings, core.MAX_TURN_RATE,
                                               low.alpha, low.trace_gamma, baseline=low.baseline)
    self.width = el.new_trace(self.coder.size)
    self._learn = True

  def state(self):
    out = {"rng_state": self.rng_state, "root_q": self.root.q,
           "root_trace_index": self.root.index, "root_trace_value": self.root.value,
           "root_trace_count": self.root.count, "epsilon_schedule": self.schedule,
           "subtask_outcomes": self.outcomes, "subtask_counts": self.counts,
           "aim_baseline": self.low.values}
    for key, value in self.low.trace._asdict().items():
      out[f"aim_{key}"] = value
    for key, value in self.width._asdict().items():
      out[f"aim_width_{key}"] = value
    return out

  def parameters(self):
    return {"root_q": self.root.parameters(), "aim_w": self.low.parameters(),
            "aim_log_sigma": el.parameters(self.width)}

  def compiled(self, episodes, learn, sample, start=None):
    rows = np.zeros((episodes, N_RECORD))
    fixed = np.empty(0) if start is None else np.array(start, dtype=np.float64)
    train(episodes, learn, sample, self.rng_state,
          RootTable(self.root.q, self.root.index, self.root.value, self.root.count),
          self.root_tiling, (self.schedule, self.outcomes, self.counts), self.low.trace, self.width,
          self.low.values, self.tile_arrays, self.s, rows, fixed)
    return rows

  # ---- the step-by-step path -----------------------------------------------------

  def graph(self):
    if self.s.width_alpha != 0.0:
      raise ValueError("ship_beyond: [low_level] width_alpha > 0 runs on the compiled path "
                       "only (backend 'analytic'); the step-by-step path (MuJoCo) has the "
                       "paper's sigma = 1 learner. Evaluate greedily there (u = m).")
    s = self.s
    n = self.tile_arrays.offsets.shape[0]
    scratch_tiles = np.empty(n, dtype=np.int64)
    view = np.empty(3)

    def target(call, obs):
      side = call.memo.setdefault("side", side_of(float(call.origin[1])))
      return target_of(call.args["action"], np.asarray(obs, dtype=np.float64), side, s)

    aim_learner = _Reflected(self.low)

    def low_view(call, obs):
      tx, ty = target(call, obs)
      # The executor views the state it acts in last before acting (and the next
      # state after), so the side set here is the one act() applies.
      aim_learner.side = aim_view(np.asarray(obs, dtype=np.float64), tx, ty, view,
                                  s.sqrt_error, s.reflect_at)
      tiles_mod.active_tiles(view, self.tile_arrays, scratch_tiles)
      return scratch_tiles

    def internal_reward(call, step):
      tx, ty = target(call, step.obs)
      info = step.info
      g_event = {"gate": core.SUCCESS, "out_of_bounds": core.FAILURE}.get(info.get("event"),
                                                                          core.NO_EVENT)
      event, internal = aim_outcome(info["positions"], np.asarray(step.obs, dtype=np.float64),
                                    call.args["action"], tx, ty, call.steps, g_event, s)
      call.memo["event"] = event
      call.memo["global"] = g_event
      return internal

    def on_exit(call, step, episode_over):
      self.row[CALLS] += 1
      if episode_over and call.memo.get("global") != core.SUCCESS:
        return
      if step.truncated:
        return
      success = call.memo["event"] == core.SUCCESS
      self.row[AIM_RUNS] += 1
      self.row[AIM_SUCCESS] += success
      if self._learn:
        schedules.record_run(self.outcomes, self.counts, 0, success)
        schedules.record_run(self.outcomes, self.counts, 1, success)

    def on_episode_end(last_step, learn):
      if learn:
        root = self.config.root
        schedules.end_episode(self.schedule, self.outcomes, self.counts, root.epsilon_threshold,
                              root.epsilon_every, root.epsilon_divisor)

    aim = Subtask("aim", children=["turn"], learner=aim_learner, view=low_view,
                  internal_reward=internal_reward,
                  reward=lambda call, step, child_reward: core.STEP_REWARD,
                  termination=lambda call, step: call.memo["event"] != core.NO_EVENT,
                  on_exit=on_exit)
    root_scratch = (np.empty(3), np.empty(self.root_tiling.offsets.shape[0], dtype=np.int64))

    def root_view(call, obs):
      obs = np.asarray(obs, dtype=np.float64)
      root_tiles(obs, self.root_tiling, *root_scratch)
      return root_scratch[1], offered(obs, s)

    root = Subtask("root", learner=self.root,
                   children=[Child("aim", action=a) for a in range(n_targets(s))],
                   view=root_view,
                   termination=lambda call, step: False)
    return TaskGraph("root", [root, aim, Primitive("turn")], on_episode_end=on_episode_end)

  def begin_episode(self, learn):
    self._learn = learn

  def metrics(self, record):
    out = super().metrics(record)
    w = record[-self.metric_window:]
    runs = w["aim_runs"].sum()
    out.update({
        "calls_per_episode": float(w["calls"].mean()) if len(w) else None,
        "aim_success_rate": float(w["aim_successes"].sum() / runs) if runs else None,
    })
    return out
