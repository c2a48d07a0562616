"""A one-curve experiment file for the tests of the run machinery (on the tuning
seeds, which the machinery under test may use)."""

TEMPLATE = """
[experiment]
name = "{name}"
description = "{description}"
tasks = ["{task}"]
runs = {runs}
episodes = {episodes}
quick_runs = 1
quick_episodes = 1000
tuning = true     # the machinery under test, on tuning seeds

[[figure]]
name = "curve"
kind = "curve"
metric = "{metric}"
x = "episodes"
title = "a curve"
ylabel = "{ylabel}"
paper = "nothing"
"""


def experiment_text(name, task, runs, episodes, description="one task", metric=None,
                    ylabel="a metric"):
  """The text of the experiment file; the metric defaults to the task's world's."""
  metric = metric or ("mean_return" if task.startswith("taxi") else "gate_passes")
  return TEMPLATE.format(name=name, description=description, task=task, runs=runs,
                         episodes=episodes, metric=metric, ylabel=ylabel)
