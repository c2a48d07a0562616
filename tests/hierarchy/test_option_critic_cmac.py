"""Option-critic over a CMAC on the ship (`hierarchy.kinds.option_critic_cmac`, the
agent `ship_option_critic`): its two paths are one algorithm; one step by hand is
the module's updates; its arrays are saved by the root's name and a run resumes
where it stopped; and what it refuses is named in one line."""
import pathlib

import gymnasium
import numba
import numpy as np
import pytest

import hpg_mj  # noqa: F401
from hpg_mj import agents
from hpg_mj.agents import ship_option_critic as soc
from hpg_mj.hierarchy import blocks
from hpg_mj.hierarchy.graph import GraphError, Primitive, Subtask, TaskGraph
from hpg_mj.hierarchy.kinds import option_critic_cmac as oc
from hpg_mj.hierarchy.program import Program
from hpg_mj.learners import rng
from hpg_mj.taskfile import updated
from hpg_mj.worlds import ship_core as core

FIELDS = ("q_omega", "theta", "vartheta")


def _agent(seed, max_steps=400, **options):
  return soc.ShipOptionCritic(updated(soc.Config(), environment={"max_steps": max_steps},
                                      options=options), seed=seed)


def test_stepwise_and_compiled_agree_bit_for_bit():
  a, b = _agent(4), _agent(4)
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic", max_steps=400)
  ra = a.train_stepwise(env, 10)
  rb = b.train(10, "analytic")
  np.testing.assert_array_equal(ra, rb)
  assert ra["steps"].sum() > 1000 and rb["calls"].sum() > 2 * len(rb)   # options end inside
  for name, value in a.state().items():
    np.testing.assert_array_equal(value, b.state()[name])
  assert all(np.any(a.state()[f"root.{k}"] != 0) for k in FIELDS)


def test_one_step_by_hand():
  """One primitive step of an option, in an episode truncated after it: the critic's,
  the policy's and the termination's updates, as the module's docstring writes them
  (option 1 chosen greedily; s' read back from the termination's weights that moved,
  u - m_w(s) from the policy's: one amount on every tile of s)."""
  agent = _agent(2, max_steps=1, n_options=2, alpha_critic=0.5, alpha_policy=0.25,
                 alpha_termination=0.25, gamma=0.9, xi=0.01, epsilon=0.0)
  size = agent.oc.coder.size
  start = np.array([100.0, 200.0, 30.0, 2.0])
  s = agent.coder.active(start)
  state = agent.state()
  state["root.q_omega"][:] = np.arange(2 * size) % 7 * 0.5
  state["root.q_omega"][size + s] = 10.0                    # option 1 is chosen
  state["root.theta"][size + s] = 0.3
  state["root.vartheta"][:] = np.arange(2 * size) % 5 * 0.1
  before = {key: value.copy() for key, value in state.items()}
  record = agent.as_record(agent.compiled(1, True, True, start=start))
  assert record["steps"][0] == 1 and record["return"][0] == -1.0
  got = agent.state()
  w = size
  changed_q = np.flatnonzero(got["root.q_omega"] != before["root.q_omega"])
  np.testing.assert_array_equal(np.sort(changed_q), np.sort(w + s))
  changed_v = np.flatnonzero(got["root.vartheta"] != before["root.vartheta"])
  assert len(changed_v) and np.all(changed_v >= w)           # option 1's, at s'
  s2 = changed_v - w
  q0, v0 = before["root.q_omega"], before["root.vartheta"]
  beta = 1 / (1 + np.exp(-v0[w + s2].mean()))
  q_next = (q0[s2].mean(), q0[w + s2].mean())
  target = -1.0 + 0.9 * ((1 - beta) * q_next[1] + beta * max(q_next))
  delta = target - q0[w + s].mean()
  np.testing.assert_allclose(got["root.q_omega"][w + s], q0[w + s] + 0.5 * delta, rtol=1e-13)
  # theta moved by alpha_policy delta (u - m) on the tiles of s: (u - m) read back
  step = got["root.theta"][w + s] - before["root.theta"][w + s]
  np.testing.assert_allclose(step, step[0], rtol=1e-12)
  q_after = got["root.q_omega"]
  advantage = q_after[w + s2].mean() - max(q_after[s2].mean(), q_after[w + s2].mean()) + 0.01
  np.testing.assert_allclose(got["root.vartheta"][w + s2],
                             v0[w + s2] - 0.25 * beta * (1 - beta) * advantage, rtol=1e-12)
  changed = {key for key in got if np.any(got[key] != before[key])}
  assert changed <= {"rng_state", "root.q_omega", "root.theta", "root.vartheta"}


def test_saved_by_the_roots_name_and_resumed(tmp_path):
  agent = agents.build(agents.load_task("ship_option_critic"), seed=3)
  record = agent.train(30)
  assert set(agent.parameters()) == {f"root.{k}" for k in FIELDS}
  agents.save(agent, tmp_path / "a", record)
  ahead = agent.train(20)
  loaded, _, _ = agents.load(tmp_path / "a")
  again = loaded.train(20)
  for field in ahead.dtype.names:
    np.testing.assert_array_equal(ahead[field], again[field])


def _graph(c, k=None, option=lambda w: w, view=None):
  options = [f"option{w}" for w in range(c.n_options if k is None else k)]
  return TaskGraph("root", [
      Subtask("root", children=options, learner=oc.OverOptionsCMAC(c),
              view=view or blocks.StateTiles(c.coder), termination=blocks.Never()),
      *(Subtask(n, children=["turn"], learner=oc.IntraOptionCMAC(c, option(w)),
                view=blocks.StateTiles(c.coder),
                termination=oc.LearnedTerminationCMAC(c, option(w)))
        for w, n in enumerate(options)),
      Primitive("turn")])


@numba.njit
def _end(P, obs, rng):
  return oc.learned_end(P, obs, 0.0, np.zeros((4, 2)), rng)


def test_the_termination_tiles_its_nodes_view():
  """beta_w(s') is drawn on the tiles the option learns on: its node's view's features,
  the observation's first numbers (StateTiles) or the ship in the frame of the
  observation's gate (GateTiles: here the goal's desired goal, obs[8:12])."""
  coder = soc.ship_flat_pg.actor_coder()
  c = oc.OptionCriticCMAC(coder, 2, core.MAX_TURN_RATE)
  heading = np.radians(-131.0)
  obs = np.array([480.0, 310.0, 37.0, -4.0, 0, 0, 0, 0,
                  612.0, 233.0, np.sin(heading), np.cos(heading)])
  dx, dy = obs[0] - obs[8], obs[1] - obs[9]
  framed = [400.0 + dx * obs[11] - dy * obs[10], 400.0 + dx * obs[10] + dy * obs[11],
            (37.0 + 131.0 + 180.0) % 360.0 - 180.0, -4.0]
  kind = oc.LearnedTerminationCMACKind()
  for view, features in ((blocks.StateTiles(coder), obs[:4]),
                         (blocks.GateTiles(blocks.GateFrame(at=8), coder), framed)):
    node = Subtask("option1", children=["turn"], learner=oc.IntraOptionCMAC(c, 1),
                   view=view, termination=oc.LearnedTerminationCMAC(c, 1))
    P = kind.settings("option1", node.termination, node)
    tiles = coder.active(features)
    c.arrays.vartheta[:] = -40.0                    # beta ~ 0 but on these tiles
    c.arrays.vartheta[coder.size + tiles] = 40.0
    assert _end(P, obs, rng.make_state(1))
    np.testing.assert_array_equal(P.tiles, tiles)
  assert not set(coder.active(obs[:4])) & set(coder.active(framed))
  node = Subtask("option1", children=["turn"], learner=oc.IntraOptionCMAC(c, 1),
                 view=blocks.GridCell(50.0, 20), termination=oc.LearnedTerminationCMAC(c, 1))
  with pytest.raises(GraphError, match=r"^subtask 'option1': a LearnedTerminationCMAC tiles "
                                       r"its node's view's features, which must be a "
                                       r"StateTiles or a GateTiles; got GridCell$"):
    kind.settings("option1", node.termination, node)


def test_what_it_refuses_is_named():
  coder = soc.ship_flat_pg.actor_coder()
  c = oc.OptionCriticCMAC(coder, 2, core.MAX_TURN_RATE)
  with pytest.raises(GraphError, match=r"^subtask 'root': OverOptionsCMAC chooses among 2 "
                                       r"options \(OptionCriticCMAC.n_options\); it has 3"):
    Program(_graph(c, k=3), obs_size=4)
  with pytest.raises(GraphError, match=r"^subtask 'option1': its \w+CMAC.option = 5: "
                                       r"must be an integer in \[0, 2\)"):
    Program(_graph(c, option=lambda w: 5 if w else 0), obs_size=4)
  with pytest.raises(ValueError, match=r"^OptionCriticCMAC.sigma = 0: must be > 0"):
    oc.OptionCriticCMAC(coder, 2, 30.0, sigma=0)
  with pytest.raises(ValueError, match=r"^OptionCriticCMAC.n_options = 0: must be an integer"):
    oc.OptionCriticCMAC(coder, 0, 30.0)


def test_the_options_are_drawn_where_they_began_and_ended(tmp_path):
  from hpg_mj.experiments import options_map
  agent = _agent(6, max_steps=120)
  agent.train(5)
  starts = [(700.0, 700.0, 100.0, 3.65), (200.0, 200.0, 0.0, 0.0)]
  summary = options_map.draw(agent, tmp_path, starts, name="opts")
  assert (tmp_path / "opts.png").stat().st_size > 10_000
  assert [s["start"] for s in summary["starts"]] == [list(s) for s in starts]
  assert sum(s["calls"] for s in summary["options"].values()) == \
      sum(s["calls"] for s in summary["starts"])
  path, calls, row = options_map.sail(agent, starts[0])
  assert len(path) == row["steps"] + 1 == summary["starts"][0]["steps"] + 1
  assert calls[0][1] == 0 and calls[-1][2] == len(path) - 1     # the calls tile the path
  assert all(a[2] == b[1] for a, b in zip(calls, calls[1:]))
  assert {c[0] for c in calls} <= {f"option{w}" for w in range(4)}


def test_an_options_figure_needs_an_option_critic(tmp_path):
  from hpg_mj import taskfile
  from hpg_mj.experiments import runner
  text = (pathlib.Path(__file__).resolve().parents[2] / "tasks" / "experiments" /
          "reference_ship_option_critic.toml").read_text()
  bad = tmp_path / "bad.toml"
  bad.write_text(text.replace('tasks = ["ship_option_critic"]',
                              'tasks = ["ship_option_critic", "ship_hybrid"]')
                 .replace('task = "ship_option_critic"', 'task = "ship_hybrid"'))
  with pytest.raises(taskfile.TaskFileError, match=r"\[\[figure\]\] 'ship_options' \(options\) "
                                                   r"draws a run of ship_option_critic; "
                                                   r"'ship_hybrid' is not one"):
    runner.load_experiment(bad)


def test_the_reference_report_shows_the_options_drawn(tmp_path):
  """`reference.write` copies each options figure its experiments drew beside the
  report and says what it shows."""
  import json

  from hpg_mj.experiments import reference, runner
  experiment = runner.load_experiment("reference_ship_option_critic")
  here = runner.folder(experiment, tmp_path, False)
  here.mkdir(parents=True)
  (here / "ship_options.png").write_bytes(b"png")
  (here / "ship_options.json").write_text(json.dumps({
      "starts": [{"start": [700.0, 700.0, 100.0, 3.65], "passed": True, "steps": 90,
                  "calls": 12}],
      "options": {"option0": {"calls": 12, "mean_steps": 7.5, "began": [650.0, 560.0],
                              "ended": [640.0, 540.0]}}}))
  report = reference.write(tmp_path).read_text()
  assert (tmp_path / "reference" / "ship_options.png").read_bytes() == b"png"
  assert "![Option-critic on the ship: where its learned options begin and end]" \
         "(ship_options.png)" in report
  assert "from (700, 700): passed the gate in 90 control steps, 12 option calls" in report
  assert "option0: 12 calls, 7.5 control steps each; on average begun at (650, 560)" in report
