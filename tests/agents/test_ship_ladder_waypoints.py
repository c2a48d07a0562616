"""The waypoints (`agents.ship_ladder_waypoints`): each task's next gate is seen as the
regatta's observation gives it; on the harbour the root reads the map and the approach
the water ahead; its root's states and its metrics are what its docstring says."""
import math
import collections

import numba
import numpy as np
import pytest

from hpg_mj import agents
from hpg_mj import taskfile
from hpg_mj.agents import ship_ladder_waypoints as waypoints
from hpg_mj.hierarchy.kinds import gate_point
from hpg_mj.worlds import ship_regatta_core as regatta_core


@numba.njit
def _ship_point(P, obs):
  return gate_point.bind_ship(P, obs, 0)


def test_the_harbours_root_reads_the_map_and_its_approach_the_water_ahead():
  """On the harbour the root's state is the ship's 50 m cell x heading quadrant, its
  styles add the detours (`blocks.ShipPoint`, bound where the ship is), the approach also
  reads the nearest forward range, and its G is -200 aground as off the field."""
  config = taskfile.updated(waypoints.Config(), environment={"world": "ship_harbour",
                                                             "level": "easy"})
  agent = waypoints.ShipLadderWaypoints(config, seed=0)
  graph = agent.graph()
  styles = graph.nodes["root"].children
  assert [(c.args.get("px"), c.args.get("py")) for c in styles[:3]] == [
      (400.0, 400.0), (400.0, 320.0), (400.0, 480.0)]
  assert [(c.bind.ahead_m, c.bind.starboard_m) for c in styles[3:]] == list(waypoints.DETOURS)
  assert agent.root.n_states == waypoints.N_HARBOUR_STATES == 1600
  obs = np.array([120.0, 980.0, 90.0, 3.0, 150.0, 150.0, 80.0, 45.0, 60.0, 150.0, 150.0])
  assert waypoints.harbour_state(obs, None) == (2 * 20 + 19) * 4 + 3   # heading east
  call = collections.namedtuple("Call", ("px", "py"))(120.0, 1080.0)  # due north
  assert waypoints.aim_clear(obs, call) == (90.0, 3.0, 45.0)
  assert [c.bind.within_m for c in styles[3:]] == [60.0] * 3    # [root] detour_within_m
  # ShipPoint: 100 m ahead (east) and 100 m to port (north) of a ship heading east; kept
  # 60 m inside the field, the point moves in to y = 940.
  np.testing.assert_allclose(_ship_point(gate_point.ShipPointSettings(100.0, -100.0, 0.0), obs),
                             (220.0, 1080.0))
  np.testing.assert_allclose(_ship_point(gate_point.ShipPointSettings(100.0, -100.0, 60.0), obs),
                             (220.0, 940.0))
  west = np.array([30.0, 20.0, -90.0, 0.0])          # 30 m from the west edge, heading west
  np.testing.assert_allclose(_ship_point(gate_point.ShipPointSettings(150.0, 0.0, 60.0), west),
                             (60.0, 60.0))
  g = waypoints.HARBOUR_PSEUDO["easy"]
  assert g(np.array([400.0, 620.0, 0.0, 0.0]), None, 0) == waypoints.LEFT_G      # an island
  assert g(np.array([400.0, -1.0, 0.0, 0.0]), None, 0) == waypoints.LEFT_G       # off the field
  assert g(np.array([100.0, 100.0, 0.0, 0.0]), None, 1) == waypoints.SUCCESS_G
  assert g(np.array([100.0, 100.0, 0.0, 0.0]), None, 0) == 0.0


@pytest.mark.parametrize("world", ["ship_goal", "ship_current"])
def test_the_gate_is_seen_as_the_regattas_next(world):
  """The goal's desired goal and the current's fixed gate, seen from the ship, are what
  the regatta's observation would say of a gate there (`ship_regatta_core`'s view)."""
  rng = np.random.default_rng(1)
  for _ in range(50):
    ship = np.array([*rng.uniform(0.0, 1000.0, 2), rng.uniform(-180.0, 180.0), 1.0])
    gate = ([*rng.uniform(100.0, 900.0, 2), rng.uniform(-180.0, 180.0)]
            if world == "ship_goal" else [400.0, 400.0, 0.0])
    heading = math.radians(gate[2])
    obs = np.concatenate([ship, np.zeros(4), [gate[0], gate[1], math.sin(heading),
                                              math.cos(heading)]])[:12 if world == "ship_goal" else 6]
    want = np.zeros(11)
    regatta_core._seen(ship, math.sin(math.radians(ship[2])), math.cos(math.radians(ship[2])),
                       np.array(gate), want, 4)
    got = waypoints.SEEN_GATES[world](obs)
    np.testing.assert_allclose(got[:3], want[4:7], rtol=0, atol=1e-9)
    assert got[3] == 1.0                       # the pass ends the episode: one gate left
  regatta = np.arange(11.0)
  assert waypoints.SEEN_GATES["ship_regatta"](regatta) == (4.0, 5.0, 6.0, 10.0)


def test_the_currents_points_are_its_gates():
  """On the current the styles are numbers: the gate's centre (400, 400), 30 m to either
  side across it, 80 m before it (it heads north)."""
  agent = agents.build(agents.load_task("ship_current_waypoints"), seed=0)
  assert [(c.args["px"], c.args["py"]) for c in agent.styles()] == [
      (400.0, 400.0), (370.0, 400.0), (430.0, 400.0), (400.0, 320.0)]


def test_the_roots_states_are_its_96():
  """Every (bearing sector, distance band, heading quadrant) is one state of [0, 96), the
  regatta's read from its observation."""
  seen = set()
  for bearing in np.arange(-179.0, 180.0, 15.0):
    for d in (30.0, 100.0, 400.0):
      for rel in np.arange(-179.0, 180.0, 30.0):
        b = math.radians(bearing)
        obs = np.zeros(11)
        obs[4], obs[5], obs[6] = d * math.cos(b), d * math.sin(b), rel
        state = waypoints.RULES["ship_regatta"].root_state(obs, None)
        assert state == waypoints.gate_state(obs[4], obs[5], obs[6])
        seen.add(state)
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


@pytest.mark.parametrize("within", [-1.0, 500.0, float("nan")])
def test_a_detour_kept_outside_the_field_is_refused_in_one_line(within):
  """`ShipPoint.within_m` below 0 or from half the field up cannot keep a point inside it:
  refused as the graph is built, naming the node and what is allowed; [root]
  detour_within_m is bounded in the task file."""
  from hpg_mj.hierarchy.graph import GraphError
  config = taskfile.updated(waypoints.Config(), environment={"world": "ship_harbour",
                                                             "level": "easy"})
  agent = waypoints.ShipLadderWaypoints(config, seed=0)
  kind = gate_point.ShipPointKind()
  from hpg_mj.hierarchy import blocks
  with pytest.raises(GraphError, match=r"^subtask 'root': ShipPoint.within_m = .*: must be"):
    kind.settings("root", blocks.ShipPoint(100.0, 0.0, within))
  assert agent.styles()[3].bind.within_m == 60.0
  with pytest.raises(ValueError, match="detour_within_m"):
    taskfile.updated(waypoints.Config(), root={"detour_within_m": -5.0})


def test_a_harbour_file_written_before_detour_within_m_keeps_its_detours_where_they_were():
  """[root] detour_within_m came after harbour files (and agents saved with them) without
  it: such a file means 0, the detours unmoved, so that those agents load and run as
  before (`taskfile.param(absent=...)`); the shipped file says 60."""
  shipped = agents.load_task("ship_harbour_waypoints")
  assert shipped.config.root.detour_within_m == 60.0
  text = "\n".join(line for line in shipped.text.splitlines()
                   if not line.startswith("detour_within_m"))
  older = taskfile.loads(text, "older.toml", agents._Registry)
  assert older.config.root.detour_within_m == 0.0
  assert [c.bind.within_m for c in agents.build(older, seed=0).styles()[3:]] == [0.0] * 3
  with pytest.raises(taskfile.TaskFileError, match=r"older.toml: \[root\] alpha is missing"):
    taskfile.loads(text.replace("\nalpha = 0.1\n", "\n", 1), "older.toml", agents._Registry)
