"""The paper's two low-level subtasks learned on their own (SPEC sections 3 and 8):
`ship/diagonal` and `ship/straight`, each call a fresh start at the local start
with a uniform heading and turning rate, the CMAC Gaussian-with-sigmoid policy
learned by Eq. 3 with R + G (the discounted trace and the learned baseline b(s)
of `ship_hybrid`), and, as an option, a learned exploration width
(`policies.gaussian_width_act`; `width_alpha = 0` is the paper's sigma = 1).
The subtask is a one-node graph of blocks that the open machine runs on its own
(`hierarchy.program`, `Program.run_alone`), as it runs it inside the hierarchy.

This is the experiment of a subtask trained on its own (`hpg-mj`-free: `train_subtask` and
`scripts/subtask_width.py`), not a task-file agent: the subtasks are parts of the
hierarchy (so this module lives in its layer, beside the blocks it is made of), and
their stand-alone environments are the Gymnasium ids
`hpg_mj/ShipSteeringDiagonal-v0` and `hpg_mj/ShipSteeringStraight-v0`.
"""
import numpy as np

from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy import program
from hpg_mj.hierarchy.graph import Primitive, Subtask, TaskGraph
from hpg_mj.learners import rng
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core as core

TASKS = {"diagonal": 1, "straight": 2}     # the compass direction whose frame is the global one


def paper_coder(n_tilings=9, n_tiles=(5, 5, 36, 5)):
  """SPEC section 3's CMAC over the local (x, y, theta, theta_dot)."""
  return tiles_mod.TileCoder((0.0, 0.0, -180.0, -core.MAX_TURN_RATE),
                             (core.LOCAL_SIZE, core.LOCAL_SIZE, 180.0, core.MAX_TURN_RATE),
                             tuple(n_tiles), (False, False, True, False), n_tilings)


def graph(task, learner, max_steps):
  """The subtask on its own: its local view, its end and G, -1 a step (SPEC section 3)."""
  return TaskGraph(task, [
      Subtask(task, children=["turn"], learner=learner, view=blocks.LocalTiles(learner.coder),
              termination=blocks.LocalGoal(max_steps), internal_reward=blocks.Shaping(),
              reward=blocks.STEP),
      Primitive("turn")])


def train_subtask(task, episodes, seed, alpha=0.01, trace_gamma=0.99, baseline=0.3,
                  width_alpha=0.0, sigma_low=0.25, sigma_high=4.0, max_steps=300,
                  greedy_every=0, greedy_episodes=0):
  """Learns one stand-alone subtask; returns {"success": per-call 0/1, "steps": ...,
  and, with greedy_every, "greedy": greedy success rates every greedy_every calls
  (the same 1,000 starts for every seed), "sigma": the learned width per tile}.
  The shipped hybrid's low level by default (alpha 0.01, trace_gamma 0.99,
  baseline 0.3); width_alpha > 0 adds the learned width."""
  if task not in TASKS:
    raise ValueError(f"subtask {task!r} is not known; allowed: {sorted(TASKS)}")
  blocks.check_width(width_alpha, sigma_low, sigma_high, "[low_level]")
  learner = blocks.GaussianCMAC(paper_coder(), float(alpha), float(trace_gamma),
                                float(baseline), core.MAX_TURN_RATE, float(width_alpha),
                                float(sigma_low), float(sigma_high))
  m = program.Program(graph(task, learner, int(max_steps)), root_args={"direction": TASKS[task]})
  state = rng.make_state(int(seed))
  rows, greedy = [], []
  chunk = greedy_every or episodes
  for start in range(0, episodes, chunk):
    rows.append(m.run_alone(min(chunk, episodes - start), True, True, state))
    if greedy_every:
      probe = rng.make_state(10_000)
      greedy.append(m.run_alone(greedy_episodes, False, False, probe)[:, 0].mean())
  rows = np.concatenate(rows) if rows else np.zeros((0, 3))
  log_sigma = m.parameters().get(f"{task}.log_sigma")
  sigma = (np.ones(learner.coder.size) if log_sigma is None else
           np.exp(np.clip(log_sigma, np.log(sigma_low), np.log(sigma_high))))
  return {"success": rows[:, 0], "steps": rows[:, 1], "greedy": np.array(greedy),
          "sigma": sigma}
