"""The regatta's waypoints (`agents.ship_ladder_waypoints`): the agent names the regatta
only, refused in one line from a task file or in Python; its root's states and its
metrics are what its docstring says."""
import math

import numpy as np
import pytest

from hpg_mj import agents
from hpg_mj import taskfile
from hpg_mj.agents import ship_ladder_waypoints as waypoints


def test_the_waypoints_name_the_regatta_only(tmp_path):
  with pytest.raises(taskfile.TaskFileError, match=r"^RegattaEnvironment: \[RegattaEnvironment\] "
                     r"world = 'ship_goal' is not allowed; allowed: \['ship_regatta'\]$"):
    taskfile.updated(waypoints.Config(), environment={"world": "ship_goal"})
  path = tmp_path / "goal.toml"
  path.write_text(agents.shipped_tasks()["ship_regatta_waypoints"].read_text().replace(
      'world = "ship_regatta"', 'world = "ship_goal"'))
  with pytest.raises(taskfile.TaskFileError, match=r"goal.toml.*world.*\['ship_regatta'\]") \
      as err:
    agents.load_task(path)
  assert "\n" not in str(err.value)


def test_the_roots_states_are_its_96():
  """Every (bearing sector, distance band, heading quadrant) is one state of [0, 96)."""
  seen = set()
  for bearing in np.arange(-179.0, 180.0, 15.0):
    for d in (30.0, 100.0, 400.0):
      for rel in np.arange(-179.0, 180.0, 30.0):
        b = math.radians(bearing)
        obs = np.zeros(11)
        obs[4], obs[5], obs[6] = d * math.cos(b), d * math.sin(b), rel
        seen.add(waypoints.root_state(obs, None))
  assert seen == set(range(waypoints.N_ROOT_STATES))


def test_its_metrics_read_the_approachs_runs():
  agent = agents.build(agents.load_task("ship_regatta_waypoints"), seed=0)
  record = agent.train(40)
  metrics = agent.metrics(record)
  assert metrics["calls_per_episode"] == pytest.approx(record["calls"].mean())
  assert 0.0 < metrics["approach_success_rate"] <= 1.0
  # Each call is a run of the approach, but the one the episode's end cuts short.
  assert 0 <= (record["calls"] - record["approach_runs"]).min()
  assert (record["calls"] - record["approach_runs"]).max() <= 1
  assert {"finish_rate", "gates_passed", "mean_return"} <= set(metrics)
