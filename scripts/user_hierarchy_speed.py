"""Training speed of the README's and the open-machine tutorial's hierarchies against the
shipped hybrid, in one process: after 300 learning episodes each (the compiles done),
3 rounds of 2,000 learning episodes each, in turn; control steps a second, their
medians and their ratio to the hybrid's.

    python scripts/user_hierarchy_speed.py
"""
import pathlib
import re
import time

import numpy as np

from hpg_mj import agents

REPO = pathlib.Path(__file__).resolve().parents[1]


def _blocks(path, after=None):
  text = path.read_text()
  if after is not None:
    text = text.split(after, 1)[1]
  return re.findall(r"^```python\n(.*?)^```", text, re.M | re.S)


def main(rounds=3, episodes=2000):
  readme = {"__name__": "readme"}
  code = _blocks(REPO / "README.md", "## Write your own hierarchy\n")[0]
  exec(code.split("agent = Waypoints")[0], readme)
  tutorial = {"__name__": "tutorial"}
  for code in _blocks(REPO / "docs" / "tutorial_open_machine.md"):
    exec(code.split("agent = BoltzmannWaypoints")[0], tutorial)
  learners = {"hybrid": agents.build(agents.load_task("ship_hybrid"), seed=0),
              "readme": readme["Waypoints"](seed=0),
              "tutorial": tutorial["BoltzmannWaypoints"](seed=0)}
  for agent in learners.values():
    agent.train(300)
  rates = {name: [] for name in learners}
  for _ in range(rounds):
    for name, agent in learners.items():
      start = time.perf_counter()
      steps = agent.train(episodes)["steps"].sum()
      rates[name].append(steps / (time.perf_counter() - start))
  hybrid = np.median(rates["hybrid"])
  for name, values in rates.items():
    print(f"{name:9s} {' '.join(f'{v:,.0f}' for v in values)}  median {np.median(values):,.0f}"
          f"  x{np.median(values) / hybrid:.2f} of the hybrid")


if __name__ == "__main__":
  main()
