"""The task ladder's bounds (SPEC sections 7.1 and 11): the fixed starts are the
environments' seeded resets, `benchmark.evaluate` scores and normalizes any policy on
every ladder task and level, the planners' published episodes are what they sail (and
what the environments sail from their turning rates), and bad names are refused in one
line."""
import json
import pathlib
import re

import gymnasium
import numpy as np
import pytest

import hpg_mj  # noqa: F401  (registers the ids)
from hpg_mj import benchmark
from hpg_mj import cli
from hpg_mj import planners

SPEC = pathlib.Path(__file__).resolve().parents[1] / "docs" / "SPEC.md"
LADDER_KEYS = benchmark.bounds_mod.LADDER_KEYS


def _done(record):
  return record["finished" if "finished" in record.dtype.names else "passed"] > 0


@pytest.mark.parametrize("name", benchmark.LADDER)
def test_a_fixed_start_is_the_environments_reset_with_its_seed(name):
  starts = benchmark.fixed_starts(f"{name}/hard", 3)
  again = benchmark.fixed_starts(name, 3, level="hard")     # evaluate's two spellings
  assert starts.keys() == again.keys() and all(np.array_equal(starts[k], again[k]) for k in starts)
  env = gymnasium.make(benchmark.ENV_IDS[name], level="hard", backend="analytic")
  for i in range(3):
    obs, info = env.reset(seed=benchmark.base.GREEDY_SEED + i)
    state = obs["observation"] if name == "ship_goal" else obs[:4]
    np.testing.assert_array_equal(state, starts["state"][i])
    if name == "ship_goal":
      np.testing.assert_array_equal(
          obs["desired_goal"], planners.goal_core.check_gate(starts["gate"][i], "x"))
    if name == "ship_regatta":
      np.testing.assert_array_equal(info["course"], starts["course"][i])


def test_evaluate_normalizes_every_ladder_task_against_the_published_bounds():
  published = benchmark.bounds()
  assert set(LADDER_KEYS) <= set(published["tasks"])
  for key in LADDER_KEYS:
    result = benchmark.evaluate(benchmark.RandomPolicy(key), key, 2, max_steps=20,
                                progress=False)
    name, level = key.split("/")
    assert (result.metrics["task"], result.metrics["level"]) == (name, level)
    assert not result.metrics["official"]
    entry = published["tasks"][key]
    for score in benchmark.SCORES[key]:
      low, high = entry["random"][score], entry["best"][score]
      expected = 100.0 * (result.metrics[score] - low) / (high - low)
      assert result.metrics[f"{score}_normalized"] == pytest.approx(expected)


def test_the_planners_sail_their_published_first_starts_and_the_environments_agree():
  """Each planner from the first fixed starts: its published episodes exactly, never
  worse than the scripted helmsman's, and its turning rates replayed on the batch
  environment end each episode alike (a copy that ends is reset by the next step, its
  rewards no longer counted)."""
  n = benchmark.CHECKED_STARTS
  for key in LADDER_KEYS:
    task = benchmark.task_of(key)
    starts = benchmark.fixed_starts(task, n)
    record, _, rates = benchmark.best_known(task, starts, actions=True)
    published = benchmark.bounds()["tasks"][key]["best_of_first_starts"]
    assert [list(row) for row in record.tolist()] == published, key
    helm = benchmark.evaluate(benchmark.ladder_helmsman(task), task, n, progress=False).record
    better = _done(record) > _done(helm)
    same = _done(record) == _done(helm)
    if task.world == "regatta":
      assert np.all(better | (same & (record["return"] >= helm["return"]))), key
    else:
      assert np.all(better | (same & (record["steps"] <= helm["steps"]))), key
    env = gymnasium.make_vec(task.env_id, num_envs=n, autoreset_mode="NextStep",
                             **task.env_kwargs())
    env.reset(options=starts)
    steps, total, ended = np.zeros(n, int), np.zeros(n), np.zeros(n, bool)
    for t in range(int(record["steps"].max())):
      _, reward, terminated, truncated, _ = env.step(np.where(ended, 0.0, rates[:, t]))
      total[~ended] += reward[~ended]
      steps[~ended] += 1
      ended |= terminated | truncated
    np.testing.assert_array_equal(steps, record["steps"], err_msg=key)
    np.testing.assert_array_equal(total, record["return"], err_msg=key)


def test_the_scripted_helmsmen_score_between_the_bounds():
  """Published on the 1,000 starts (`evaluate` of the helmsman): random < the scripted
  helmsman <= the best known, each normalized score of the helmsman in (0, 100]; and
  evaluated here on a few starts, above the random policy's."""
  for key in LADDER_KEYS:
    entry = benchmark.bounds()["tasks"][key]
    normalized = benchmark.normalized(key, entry["helmsman"])
    for score in benchmark.SCORES[key]:
      assert entry["random"][score] < entry["helmsman"][score] <= entry["best"][score], key
      assert 0.0 < normalized[f"{score}_normalized"] <= 100.0, key
    result = benchmark.evaluate(benchmark.ladder_helmsman(key), key, 6, progress=False)
    for score in benchmark.SCORES[key]:
      assert result.metrics[f"{score}_normalized"] > 0.0, (key, score)


def test_the_harbours_distance_field_goes_round_the_obstacles():
  """The harbour's reference field (no margin, `planners_harbour`): 100 m due north of
  the gate's centre in open water, nothing on an island, never shorter than the
  straight line to the gate, and from (205, 480) at the hard level within 1% below and
  4% above the continuous shortest path: up the side of its western pier (x 214 to
  226 m, up to y = 560 m), across its end, to the east end of the northern pocket's wall
  (x 270 to 530 m, y 444 to 456 m), round it and down the pocket to the gate's eastern
  post (moved in by 2 m)."""
  from hpg_mj import planners_harbour
  node = lambda field, x, y: field[int(x / 5.0), int(y / 5.0)]
  easy = planners_harbour._reference_field("easy")
  assert node(easy, 400.0, 500.0) == 100.0 and np.isinf(node(easy, 400.0, 620.0))
  grid = np.arange(easy.shape[0]) * planners_harbour.GRID_M
  x, y = np.meshgrid(grid, grid, indexing="ij")
  straight = np.hypot(np.clip(x, 350.0, 450.0) - x, 400.0 - y)
  for level in benchmark.LEVELS:
    field = planners_harbour._reference_field(level)
    finite = np.isfinite(field)
    assert np.all(field[finite] >= straight[finite])
  shortest = (np.hypot(214.0 - 205.0, 560.0 - 480.0) + 12.0
              + np.hypot(530.0 - 226.0, 560.0 - 456.0) + 12.0 + np.hypot(530.0 - 448.0, 444.0 - 400.0))
  hard = node(planners_harbour._reference_field("hard"), 205.0, 480.0)
  assert 0.99 * shortest <= hard <= 1.04 * shortest


@pytest.mark.parametrize("kwargs, message", [
    ({"task": "ship_goal", "level": "extreme"},
     "level 'extreme' of task 'ship_goal' is not known; allowed levels: "
     "['easy', 'medium', 'hard']"),
    ({"task": "ship_regatta/extreme"},
     "level 'extreme' of task 'ship_regatta' is not known; allowed levels: "
     "['easy', 'medium', 'hard']"),
    ({"task": "ship", "level": "hard"},
     "level='hard' is for the ladder's tasks ['ship_current', 'ship_goal', 'ship_regatta', "
     "'ship_harbour']; task 'ship' has no levels"),
    ({"task": "ship_currents"}, "task 'ship_currents' is not known; allowed: ship, taxi_fuel, "
     "taxi, ship_current, ship_goal, ship_regatta, ship_harbour (at a level: easy, medium, "
     "hard;"),
])
def test_a_bad_task_or_level_is_refused_in_one_line(kwargs, message):
  with pytest.raises(ValueError) as err:
    benchmark.evaluate(lambda obs: 0.0, episodes=1, progress=False, **kwargs)
  assert str(err.value).startswith(message) and "\n" not in str(err.value)


@pytest.mark.parametrize("argv, message", [
    (["--task", "ship_goal", "--level", "extreme"],
     "--level 'extreme' is not a level; allowed: easy, medium, hard"),
    (["--task", "ship_goals"], "--task 'ship_goals' is not a task; allowed: ship, taxi_fuel, "
     "taxi, ship_current, ship_goal, ship_regatta, ship_harbour"),
    (["--level", "hard"], "--level is for the ladder's tasks (ship_current, ship_goal, "
     "ship_regatta, ship_harbour), not the default task, ship"),
    (["--task", "taxi", "--level", "hard"], "--level is for the ladder's tasks (ship_current, "
     "ship_goal, ship_regatta, ship_harbour), not --task taxi"),
])
def test_hpg_mj_evaluate_refuses_a_bad_task_or_level_in_one_line(argv, message, capsys):
  assert cli.main(["evaluate", "--policy", "math:sin", *argv]) == 2
  err = capsys.readouterr().err
  assert err == f"hpg-mj evaluate: error: {message}\n"


def test_hpg_mj_evaluate_scores_a_ladder_task(tmp_path, capsys, monkeypatch):
  (tmp_path / "my_goal.py").write_text(
      "def steer(obs):\n"
      "  return 5.0 if obs['desired_goal'][0] > obs['observation'][0] else -5.0\n")
  monkeypatch.chdir(tmp_path)
  assert cli.main(["evaluate", "--policy", "my_goal:steer", "--task", "ship_goal/medium",
                   "--episodes", "3", "--max-steps", "30", "--json"]) == 0
  out = json.loads(capsys.readouterr().out)
  assert (out["task"], out["level"], out["episodes"]) == ("ship_goal", "medium", 3)
  assert "reset(seed=1000000 + i)" in out["starts"] and "J_normalized" in out


def _spec_rows():
  """SPEC section 7.1's ladder table: {(task/level, score): (random, helmsman, best)}."""
  section = SPEC.read_text().split("### 7.1 ", 1)[1].split("\n## ", 1)[0]
  rows = {}
  for line in section.splitlines():
    cells = [c.strip() for c in line.strip().strip("|").split("|")]
    if len(cells) == 6 and cells[0].startswith("ship_"):
      rows[(f"{cells[0]}/{cells[1]}", cells[2])] = tuple(
          float(re.match(r"-?[\d.]+", c).group()) for c in cells[3:6])
  return rows


def test_the_spec_table_is_the_published_bounds():
  rows = _spec_rows()
  shown = {"J": "J (gamma 0.99)", "gate_pass_rate": "gate pass rate",
           "mean_return": "mean return", "finish_rate": "finish rate"}
  published = benchmark.bounds()["tasks"]
  expected = set()
  for key in LADDER_KEYS:
    for score in benchmark.SCORES[key]:
      expected.add((key, shown[score]))
      values = rows[(key, shown[score])]
      entry = published[key]
      for value, row in zip(values, ("random", "helmsman", "best")):
        assert value == pytest.approx(entry[row][score], abs=0.0015 if "rate" in score
                                      else 0.015), (key, score, row)
  assert set(rows) == expected
