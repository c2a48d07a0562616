"""SPEC section 7: J under MushroomRL's rewards, the fixed greedy start set, the
bootstrap intervals and what a report may call the paper's ordering."""
import numpy as np
import pytest

from hpg_mj import agents
from hpg_mj.agents import _ship
from hpg_mj.experiments import figures, stats


def _ship_record(rows):
  """A record of (passed, steps, return) rows, as the flat ship agents write it."""
  cls = agents.lookup("ship_flat_pg")
  return cls.as_record(np.array(rows, dtype=np.float64))


def test_j_of_a_hand_built_record():
  g = 0.99
  record = _ship_record([
      (1, 1, -1 + 100),          # passes on its first step: that step gives 0
      (1, 3, -3 + 100),          # -1, -1, then 0
      (0, 2, -2 - 300),          # leaves on its second step: -1, then -100
      (0, 3, -3),                # truncated at max_steps = 3: three -1s
      (0, 3, -3 - 300),          # leaves on the step that reaches max_steps
  ])
  j = _ship.mushroom_j(record, max_steps=3, out_of_bounds_reward=-300.0)
  assert j == pytest.approx([0.0, -1 - g, -1 - 100 * g, -1 - g - g * g, -1 - g - 100 * g * g])


def test_j_is_in_every_ship_agents_metrics():
  agent = agents.build(agents.load_task("ship_flat_pg"), seed=0)
  record = _ship_record([(1, 3, 97.0), (0, 2, -302.0)])
  assert agent.metrics(record)["J"] == pytest.approx(np.mean([-1.99, -1 - 99.0]))


def test_straight_line_bound_is_spec_sections_81():
  assert _ship.straight_line_j() == pytest.approx(-81.0, abs=0.3)
  assert _ship.straight_line_j(starts=20_000, seed=1) == pytest.approx(-81.0, abs=0.6)


@pytest.mark.parametrize("task", ["ship_flat_pg", "taxi_fuel_flat_q"])
def test_the_greedy_start_set_is_the_same_for_every_run(task):
  one = agents.build(agents.load_task(task), seed=3)
  two = agents.build(agents.load_task(task), seed=104)
  two.train(20)                                   # another run, trained a little
  before = two.rng_state.copy()
  starts = one.fixed_starts(50)
  assert np.array_equal(starts, two.fixed_starts(50))
  assert len({tuple(s) for s in starts}) > 40     # a set of starts, not one repeated
  assert np.array_equal(two.rng_state, before)    # the agent's generator is left alone
  # Each episode of evaluate_fixed starts from its generator restarted at seed + i.
  two.set_seed(agents.base.GREEDY_SEED + 7)
  assert np.array_equal(two.start_state(), starts[7])
  two.rng_state[:] = before
  first, again = two.evaluate_fixed(50), two.evaluate_fixed(50)
  assert np.array_equal(first, again) and np.array_equal(two.rng_state, before)


def test_greedy_evaluation_refuses_bad_counts():
  agent = agents.build(agents.load_task("taxi_fuel_flat_q"), seed=0)
  with pytest.raises(ValueError, match="episodes must be a non-negative integer, got -1"):
    agent.evaluate_fixed(-1)
  with pytest.raises(ValueError, match="policy 'best' is not known"):
    agent.evaluate_fixed(3, policy="best")


def test_bootstrap_interval_holds_the_mean():
  x = np.random.default_rng(0).normal(5.0, 1.0, 20)
  mean, low, high = stats.mean_ci(x)
  assert mean == pytest.approx(x.mean())
  assert low < mean < high
  # The percentile interval of the mean is about +-1.96 standard errors wide.
  se = x.std(ddof=1) / np.sqrt(len(x))
  assert high - low == pytest.approx(2 * 1.96 * se, rel=0.25)
  assert stats.mean_ci(x) == (mean, low, high)            # seeded: the same when redrawn
  assert stats.mean_ci([2.0, 2.0, 2.0]) == (2.0, 2.0, 2.0)
  assert stats.mean_ci([np.nan, 4.0]) == (4.0, 4.0, 4.0)  # NaNs left out
  assert all(np.isnan(stats.mean_ci([])))


def test_iqm_is_the_mean_of_the_middle_half():
  assert stats.iqm([1, 2, 3, 4, 5, 6, 7, 100]) == pytest.approx(4.5)


def test_ordering_is_the_papers_only_where_intervals_separate():
  fig = {"paper_order": ["a", "b"], "better": "higher"}
  labels = {"a": "A", "b": "B"}
  apart = {"a": {"final": np.array([10.0, 10.5, 11.0, 10.2])},
           "b": {"final": np.array([1.0, 1.5, 2.0, 1.2])}}
  assert "A ahead of B: as the paper (intervals separate). The paper's ordering holds." in \
      figures._ordering(fig, apart, labels, 4)
  close = {"a": {"final": np.array([10.0, 12.0, 8.0, 11.0])},
           "b": {"final": np.array([9.0, 11.0, 7.0, 12.0])}}
  text = figures._ordering(fig, close, labels, 4)
  assert "not distinguishable (95% intervals overlap)" in text
  assert "**not** established here: A and B are not distinguishable." in text
  reversed_ = {"a": apart["b"], "b": apart["a"]}
  text = figures._ordering(fig, reversed_, labels, 4)
  assert "A ahead of B: reversed (intervals separate)" in text
  assert "does **not** hold here: B is ahead of A, with separate 95% intervals." in text


def test_evaluate_json_reports_j_on_the_fixed_starts(tmp_path, capsys):
  import json

  from hpg_mj import cli
  agent = agents.build(agents.load_task("ship_flat_pg"), seed=101)
  record = agent.train(5)
  agents.save(agent, tmp_path / "agent", record)
  assert cli.main(["evaluate", str(tmp_path / "agent"), "--episodes", "4", "--json"]) == 0
  out = json.loads(capsys.readouterr().out)
  greedy = agent.evaluate_fixed(4)
  assert out["J"] == pytest.approx(float(np.mean(agent.j(greedy))))
  assert out["starts"].startswith("fixed set")


# ---- one tuning procedure (SPEC section 7) ---------------------------------------

def test_every_learner_of_a_figure_gets_the_same_budget():
  from hpg_mj.experiments import tuning
  for names in (("taxi_fuel_hpg", "taxi_fuel_maxq", "taxi_fuel_flat_q", "taxi_fuel_hpg_eq3"),
                ("ship_hybrid", "ship_flat_pg", "ship_actor_critic", "ship_hybrid_eq3")):
    tasks = [agents.load_task(n) for n in names]
    assert len({t.tuning["budget"] for t in tasks}) == 1
    assert len({t.tuning["episodes"] for t in tasks}) == 1
    assert len({t.tuning["score"] for t in tasks}) == 1
    budget = tasks[0].tuning["budget"]
    assert all(len(tuning.candidates(t, budget)) == budget for t in tasks)
  big = agents.load_task("ship_hybrid_eq3")
  assert tuning.candidates(big, 2) == tuning.candidates(big, 2)     # a seeded draw
  assert len(tuning.candidates(big, 2)) == 2


def test_tune_trains_each_candidate_on_the_tuning_seeds(tmp_path):
  from hpg_mj.experiments import tuning
  text = agents.shipped_tasks()["taxi_fuel_flat_q"].read_text().replace(
      "episodes = 100000\nbudget = 4", "episodes = 300\nbudget = 2").replace(
      "[3000, 10000, 30000, 50000]", "[100, 200, 300]").replace(
      'score = "steps_to_95"', 'score = "mean_return"').replace('better = "lower"',
                                                                 'better = "higher"')
  path = tmp_path / "q.toml"
  path.write_text(text)
  task = agents.load_task(path)
  result = tuning.tune(task, seeds=[0, 1])
  assert len(result["results"]) == 2 and result["seeds"] == [0, 1]
  first = result["results"][0]
  config = tuning.configure(task, first["changes"])
  alone = agents.lookup("taxi_flat_q")(config, seed=1, task=task)
  assert first["scores"][1] == pytest.approx(alone.metrics(alone.train(300))["mean_return"])
  with pytest.raises(ValueError, match=r"seeds \[100\] are not tuning seeds"):
    tuning.tune(task, seeds=[100])
  # Two processes give the same scores, in the same order, as one.
  assert tuning.tune(task, seeds=[0, 1], workers=2)["results"] == result["results"]
  with pytest.raises(ValueError, match="workers must be a positive number"):
    tuning.tune(task, seeds=[0, 1], workers=0)


@pytest.mark.parametrize("old,new,message", [
    ("[tuning.grid]\n", "[tuning.grid]\npolicy.colour = [1]\n",
     r"\[tuning.grid\] policy.colour is not a key of \[policy\]"),
    ("[tuning.grid]\n", "[tuning.grid]\nroots.alpha = [1]\n",
     r"\[tuning.grid\] 'roots' is not a section of this task"),
    ("[3000, 10000, 30000, 50000]", "[]", "must be a non-empty list of values"),
    ("[3000, 10000, 30000, 50000]", "[3000, -1]", r"epsilon_episodes = -1 is out of range"),
    ('better = "lower"', 'better = "less"', r"better = 'less' is not allowed"),
    ("budget = 4\n", "", r"\[tuning\] budget is missing"),
])
def test_bad_tuning_sections_are_refused(tmp_path, old, new, message):
  from hpg_mj import taskfile
  text = agents.shipped_tasks()["taxi_fuel_flat_q"].read_text()
  assert old in text
  path = tmp_path / "q.toml"
  path.write_text(text.replace(old, new, 1))
  with pytest.raises(taskfile.TaskFileError, match=message):
    agents.load_task(path)
