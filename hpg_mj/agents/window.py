"""The window a record's online metrics are over, named (issue 23): every agent's
`metrics(record)` measures its last `metric_window` record rows (an episodic
agent: the last 1,000 episodes; ship_patrol, continuing: the last 125 hours), and
`hpg-mj train --json` says which beside the numbers."""
from hpg_mj import taskfile


def unit(agent):
  """What one record row of `agent` (an agent or its class) is."""
  steps = agent.record_steps
  if steps is None:
    return "episodes"
  if steps == taskfile.CONTROL_STEPS_PER_HOUR:
    return "hours"
  return f"rows of {steps:,} control steps"


def phrase(agent):
  """"last 1,000 episodes", "last 125 hours": the window in the README's words."""
  return f"last {agent.metric_window:,} {unit(agent)}"


def described(agent):
  """The keys `hpg-mj train --json` adds: the window, in words and in rows."""
  return {"online_window": f"{phrase(agent)} of training",
          "online_window_rows": int(agent.metric_window)}
