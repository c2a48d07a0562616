"""The continuing patrol (SPEC section 8): what its agent (`hpg_mj.agents.ship_patrol`,
a graph of blocks on the compiled machine) needs beside the machine: `scripted`, the
figure-eight helmsman on the same task (the reference figure), and `AgentRestarts`,
the step-by-step path's adapter.
"""
import numba
import numpy as np

from hpg_mj.hierarchy import executor
from hpg_mj.hierarchy import ship_rules as rules
from hpg_mj.hierarchy.graph import Step
from hpg_mj.worlds import ship_core as core

# Record columns, one row per hour (`ShipPatrol.record_fields`).
(STEPS, GATES, DEPARTURES, CALLS, DIAG_RUNS, DIAG_SUCCESS, STRAIGHT_RUNS, STRAIGHT_SUCCESS,
 RETURN, GAIN) = range(10)
N_RECORD = 10
NEVER = 1 << 60              # no episode clock: only the subtasks' 300 steps end a call


@numba.njit(cache=True)
def scripted(n_rows, record_steps, rng_state, ship, gate_reward, out_of_bounds_reward, record):
  """The figure-eight helmsman (`ship_core.patrol_pilot_target`) on the continuing
  task: the reference figure, rows as `patrol`'s."""
  samples = np.empty((core.SAMPLES_PER_CONTROL + 1, 2))
  phase = 0
  for i in range(n_rows):
    row = record[i]
    row[:] = 0.0
    while row[STEPS] < record_steps:
      tx, ty, phase = core.patrol_pilot_target(ship, phase)
      core.euler_control(ship, core.pilot_turn_rate(ship, tx, ty), samples, core.SPEED,
                         core.TIME_CONSTANT, core.SAMPLING_INTERVAL)
      event, reward = core.global_outcome(samples, gate_reward, out_of_bounds_reward)
      row[STEPS] += 1
      row[RETURN] += reward
      if event == core.SUCCESS:
        row[GATES] += 1
        phase = 0
      elif event == core.FAILURE:
        row[DEPARTURES] += 1
        rules.sample_start(rng_state, ship)
        phase = 0


class AgentRestarts(executor.GymAdapter):
  """The patrol's step-by-step path's adapter (the executor's `reset` / `step`) over a
  Gymnasium patrol: after a departure the ship is put at a start drawn from the
  agent's generator, as the compiled loop draws it, in place of the
  environment's own; the step's `info["state_before_restart"]` keeps where it
  left. A gate pass or a departure is reported as terminated: it ends the calls
  below the continuing root (`blocks.Clock`), not the root. `gates` and
  `departures` count them since the last reset. A truncated step is refused: a row
  is the agent's hour, not the environment's."""

  def __init__(self, inner, rng_state):
    self.inner, self.env, self.rng_state = inner, inner.env, rng_state
    self.gates = self.departures = 0

  def reset(self, start=None):
    """Starts the patrol (at `start`, if given), its counts at 0; returns the
    observation."""
    self.gates = self.departures = 0
    self.last_obs = self.inner.reset(start)
    return self.last_obs

  def step(self, action):
    """One primitive step; after a departure, the ship restarted at a start drawn
    from the agent's generator. A gate pass or a departure is reported as terminated."""
    step = self.inner.step(action)
    event = step.info.get("event")
    self.gates += event == "gate"
    self.departures += event == "out_of_bounds"
    if step.truncated:
      raise ValueError("ship_patrol's step-by-step rows end between calls; make the patrol "
                       f"environment with max_steps={NEVER} (ShipPatrol.stepwise_env does)")
    if step.info.get("event") == "out_of_bounds":
      if "state_before_restart" not in step.info:
        raise ValueError("ship_patrol's step-by-step path needs the Gymnasium patrol "
                         "(hpg_mj/ShipPatrol-v0), whose info holds state_before_restart")
      start = np.empty(4)
      rules.sample_start(self.rng_state, start)
      step = Step(self.inner.reset(start), step.reward, True, False, step.info)
    else:
      step = Step(step.obs, step.reward, event == "gate", False, step.info)
    self.last_obs = step.obs
    return step
