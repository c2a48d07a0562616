"""The ship steering hierarchy (paper, Figure 3 and section 5.2; SPEC section 3).

Root: a learner over the 20 x 20 grid of 50 m cells, choosing one of eight
directions. Each direction calls one of two shared low-level subtasks
(diagonal for NE, SE, SW, NW; straight for N, E, S, W) in its local 150 m frame,
whose learner picks the turning rate from the active CMAC tiles of the local state.

`ship_graph` builds that task graph over given learners; the agent that owns
them (`hpg_mj.agents.ship_hybrid`) runs it step by step through any ship
environment, and its fused compiled loop (`train` there) runs the same rules.
"""
import numpy as np

from hpg_mj.hierarchy import ship_rules as rules
from hpg_mj.hierarchy.graph import Child, Primitive, Subtask, TaskGraph
from hpg_mj.learners import tiles
from hpg_mj.worlds import ship_core as core


def ship_graph(root_learner, low_learners, tile_arrays, subtask_max_steps, on_run=None,
               on_episode_end=None):
  """Figure 3's graph: `root_learner` over cells, `low_learners` = [diagonal, straight]
  over the active tiles of the local state (`tile_arrays` of a `TileCoder`).

  `on_run(subtask, success, episode_over)` is told when a low-level call returns.
  """
  n_tilings = tile_arrays.offsets.shape[0]
  scratch_tiles = np.empty(n_tilings, dtype=np.int64)
  local = np.empty(4)
  local_samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))

  def low_view(call, obs):
    origin = call.memo.setdefault("origin", np.array(call.origin[:2], dtype=np.float64))
    core.global_to_local(obs, origin, call.args["direction"], local)
    tiles.active_tiles(local, tile_arrays, scratch_tiles)
    return scratch_tiles

  def low_internal_reward(call, step):
    event, internal = core.low_level_outcome(
        step.info["positions"], step.obs, call.memo["origin"], call.args["direction"],
        call.steps, local_samples, local, subtask_max_steps)
    call.memo["event"] = event
    return internal

  def low_exit(call, step, episode_over):
    if on_run is not None:
      on_run(rules.subtask_of(call.args["direction"]), call.memo["event"] == core.SUCCESS,
             episode_over)

  def low_level(name, learner):
    return Subtask(
        name, children=["turn"], learner=learner, view=low_view,
        internal_reward=low_internal_reward,
        reward=lambda call, step, child_reward: core.STEP_REWARD,   # only the -1 (SPEC 3)
        termination=lambda call, step: call.memo["event"] != core.NO_EVENT,
        on_exit=low_exit)

  root = Subtask(
      "root", learner=root_learner,
      children=[Child("diagonal" if d % 2 else "straight", direction=d)
                for d in range(rules.N_DIRECTIONS)],
      view=lambda call, obs: rules.root_cell(obs[0], obs[1]),
      termination=lambda call, step: False)   # the root ends with the episode
  return TaskGraph("root", [
      root,
      low_level("diagonal", low_learners[rules.DIAGONAL]),
      low_level("straight", low_learners[rules.STRAIGHT]),
      Primitive("turn"),                     # the turning rate r, chosen by the low level
  ], on_episode_end=on_episode_end)
