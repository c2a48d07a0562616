"""The window a record's online metrics are over, named: every agent's
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


def over(agent, rows, of):
  """The window of a record of `rows` rows (`of`: "training", "the evaluation") in
  words: "last 1,000 episodes of training", or, when fewer rows were run than the
  window holds, "all 500 episodes of training (fewer than the window, the last 1,000)"."""
  if rows >= agent.metric_window:
    return f"{phrase(agent)} of {of}"
  return f"all {rows:,} {unit(agent)} of {of} (fewer than the window, the last " \
         f"{agent.metric_window:,})"


def described(agent, rows):
  """The keys `hpg-mj train --json` adds for a training record of `rows` rows: the
  window, in words and in the rows it holds (never more than were run)."""
  return {"online_window": over(agent, rows, "training"),
          "online_window_rows": min(int(agent.metric_window), int(rows))}


def evaluated(agent, rows):
  """The window of an evaluation's record of `rows` rows in words: an agent that
  measures an evaluation whole, a row an episode (`measures_evaluation_whole`: the
  Stable-Baselines3 agents, whose training rows are control steps), says so; any
  other as `over` says."""
  if getattr(agent, "measures_evaluation_whole", False):
    return f"all {rows:,} episodes of the evaluation"
  return over(agent, rows, "the evaluation")
