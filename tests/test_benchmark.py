"""hpg_mj.benchmark: any policy scored on the reports' fixed starts and metrics (SPEC
section 7), its refusals, the bounds and normalized scores (SPEC section 7.1), and
`hpg-mj evaluate --policy`, all on the real environments."""
import dataclasses
import json
import math

import numpy as np
import pytest

from hpg_mj import agents
from hpg_mj import benchmark
from hpg_mj import cli
from hpg_mj.agents import base
from hpg_mj.learners import eligibility as el
from hpg_mj.learners import policies
from hpg_mj.learners import tiles as tiles_mod
from hpg_mj.worlds import ship_core
from hpg_mj.worlds import taxi_values

GAMMA = 0.99


def _flat_pg(max_steps=400, episodes=60, seed=3):
  """A briefly trained flat PGRL agent with a short step limit."""
  task = agents.load_task("ship_flat_pg")
  config = dataclasses.replace(task.config, environment=dataclasses.replace(
      task.config.environment, max_steps=max_steps))
  agent = agents.lookup("ship_flat_pg")(config, seed=seed)
  agent.train(episodes)
  return agent


def _greedy_steering(agent):
  """The flat agent's greedy policy as a plain function of one observation."""
  tiling = agent.coder.arrays()
  state = agent.state()                    # the policy's trace, by name
  trace = el.Trace(*[state[f"policy.{field}"] for field in el.Trace._fields])
  active = np.empty(tiling.offsets.shape[0], dtype=np.int64)

  def steer(obs):
    tiles_mod.active_tiles(np.asarray(obs, dtype=np.float64), tiling, active)
    return policies.gaussian_greedy(trace, active, ship_core.MAX_TURN_RATE)
  return steer


class Predictor:
  """An object with Stable-Baselines3's predict: a batch of observations in,
  (actions, state) out."""

  def __init__(self, steer):
    self.steer = steer
    self.calls = []

  def predict(self, obs, state=None, episode_start=None, deterministic=False):
    self.calls.append((np.shape(obs), deterministic))
    return np.array([[self.steer(o)] for o in obs]), None


# ---- the fixed starts and the agents' own numbers -------------------------------------

def test_the_fixed_starts_are_every_agents():
  ship = agents.build(agents.load_task("ship_hybrid"), seed=7)
  np.testing.assert_array_equal(benchmark.fixed_starts("ship", 25), ship.fixed_starts(25))
  taxi = agents.build(agents.load_task("taxi_fuel_hpg"), seed=7)
  np.testing.assert_array_equal(benchmark.fixed_starts("taxi_fuel", 25), taxi.fixed_starts(25))
  assert benchmark.fixed_starts("taxi", 3).shape == (3, 4)
  assert base.seeded_starts(lambda g: [1.0], 0).shape == (0,)


def test_a_function_an_object_with_predict_and_the_agent_score_alike():
  """The flat agent's greedy policy, scored as a function (one observation), as a
  batched function and as an object with predict, equals the agent's own greedy
  episodes (its compiled loop) start for start."""
  agent = _flat_pg()
  steer = _greedy_steering(agent)
  own = benchmark.evaluate(agent, episodes=40, progress=False)
  task = benchmark.task_of(agent)                 # its rewards (leaving: -300), 400 steps
  assert (task.max_steps, task.out_of_bounds_reward) == (400, -300.0)
  single = benchmark.evaluate(steer, task, 40, num_envs=7, progress=False)

  def batch(obs):
    return np.array([steer(o) for o in obs])
  batched = benchmark.evaluate(batch, "ship_flat_pg", 40, max_steps=400, batched=True,
                               progress=False)
  predictor = Predictor(steer)
  predicted = benchmark.evaluate(predictor, task, 40, num_envs=16, progress=False)
  assert predictor.calls[0] == ((16, 4), True)          # batches, deterministic=True
  direct = agent.evaluate_fixed(40)
  for result in (own, single, batched, predicted):
    for field in ("passed", "steps", "return"):
      np.testing.assert_array_equal(result.record[field], direct[field])
    np.testing.assert_array_equal(result.record["J"], agent.j(direct))
  assert 0 < own.metrics["gate_pass_rate"] < 1            # passes and misses: a real check
  assert single.metrics == {**own.metrics, "official": False}


def test_the_scorer_on_a_saved_agent_equals_hpg_mj_evaluate(tmp_path, capsys):
  agent = agents.build(agents.load_task("ship_flat_pg"), seed=101)
  agents.save(agent, tmp_path / "agent", agent.train(5))
  assert cli.main(["evaluate", str(tmp_path / "agent"), "--episodes", "12", "--json"]) == 0
  printed = json.loads(capsys.readouterr().out)
  loaded, _, _ = agents.load(tmp_path / "agent")
  scored = benchmark.evaluate(loaded, episodes=12, progress=False).metrics
  for key in ("gate_pass_rate", "steps_to_gate", "mean_return", "J", "control_steps",
              "J_normalized", "gate_pass_rate_normalized"):
    assert printed[key] == scored[key], key
  assert printed["J_normalized"] is not None


def test_a_taxi_agent_scores_as_its_own_greedy_episodes():
  agent = agents.build(agents.load_task("taxi_fuel_flat_q"), seed=5)
  agent.train(300)
  result = benchmark.evaluate(agent, episodes=30, progress=False)
  direct = agent.evaluate_fixed(30)
  np.testing.assert_array_equal(result.record["return"], direct["return"])
  np.testing.assert_array_equal(result.record["delivered"], direct["outcome"] == 1)
  m = result.metrics
  assert m["mean_return"] == direct["return"].mean()
  assert m["fraction_of_optimum"] == m["mean_return"] / m["optimum"]


# ---- taxi: the exact optimum ---------------------------------------------------------

@pytest.mark.parametrize("task", ["taxi_fuel", "taxi"])
def test_the_optimal_taxi_earns_the_optimum_of_every_start(task):
  result = benchmark.evaluate(benchmark.OptimalTaxiPolicy(task), task, progress=False)
  record, m = result.record, result.metrics
  np.testing.assert_array_equal(record["return"], record["optimal_return"])
  assert m["fraction_of_optimum"] == 1.0 and m["delivery_rate"] == 1.0
  assert m["mean_return_normalized"] == pytest.approx(100.0, abs=1e-12)
  # The fixed starts' mean optimum, near the start distribution's exact mean.
  assert m["optimum"] == pytest.approx(taxi_values.optimal_mean_return(task == "taxi_fuel"),
                                       abs=0.15)
  assert m["official"]


@pytest.mark.parametrize("max_steps, official", [(200, True), (100, False)])
def test_hpg_mj_evaluate_says_official_only_under_the_task_s_own_rules(max_steps, official,
                                                                      tmp_path, capsys):
  # An agent trained with another step limit is scored under it: not official (as
  # benchmark.evaluate(agent) says), though every fixed start is sailed.
  out = tmp_path / "agent"
  assert cli.main(["train", "taxi_fuel_flat_q", "--episodes", "5", "--quiet", "--out", str(out),
                   "--set", f"environment.max_steps={max_steps}"]) == 0
  capsys.readouterr()
  assert cli.main(["evaluate", str(out), "--json", "--quiet"]) == 0
  printed = json.loads(capsys.readouterr().out)
  agent = agents.load(out)[0]
  assert printed["official"] is official
  assert benchmark.evaluate(agent, progress=False).metrics["official"] is official


def test_a_taxi_policy_of_one_observation():
  def always_fill_up(obs):          # one observation of 5 -> Fillup, forever
    assert np.shape(obs) == (5,)
    return 6
  result = benchmark.evaluate(always_fill_up, "taxi_fuel", 20, progress=False)
  # Fillup away from F is a -1 no-op that burns fuel: the tank runs dry (-20) or
  # the taxi, parked at F, refuels until truncated at 200 steps.
  at_f = np.all(benchmark.fixed_starts("taxi_fuel", 20)[:, :2] == (2, 1), axis=1)
  fuel = benchmark.fixed_starts("taxi_fuel", 20)[:, 4]
  expected = np.where(at_f, -200.0, -(fuel + 0.0) - 20.0)
  np.testing.assert_array_equal(result.record["return"], expected)
  assert result.metrics["delivery_rate"] == 0.0


# ---- the step cap, the task's rewards, progress ----------------------------------------

def test_a_step_cap_truncates_and_j_counts_it():
  result = benchmark.evaluate(lambda obs: 15.0, "ship", 30, max_steps=50, progress=False)
  record = result.record
  assert record["steps"].max() == 50
  truncated = (record["steps"] == 50) & (record["passed"] == 0)
  assert truncated.sum() >= 20        # circling at full rudder (radius ~11 m) stays put
  np.testing.assert_allclose(record["J"][truncated], -(1 - GAMMA ** 50) / (1 - GAMMA))
  np.testing.assert_array_equal(record["return"][truncated], -50.0)
  assert not result.metrics["official"] and result.metrics["max_steps"] == 50


def test_a_task_file_brings_its_rewards():
  def straight(obs):
    return 0.0
  plain = benchmark.evaluate(straight, "ship", 100, progress=False)
  shipped = benchmark.evaluate(straight, "ship_hybrid", 100, progress=False)  # leaving: -300
  assert shipped.task.out_of_bounds_reward == -300.0
  left = (plain.record["passed"] == 0) & (plain.record["steps"] < 5000)
  assert left.sum() > 50
  np.testing.assert_array_equal(shipped.record["J"], plain.record["J"])
  np.testing.assert_array_equal(shipped.record["return"] - plain.record["return"],
                                np.where(left, -200.0, 0.0))


def test_a_long_evaluation_shows_progress(capsys):
  benchmark.evaluate(benchmark.helmsman, "ship", 20, progress=True)
  err = capsys.readouterr().err
  assert "evaluate ship" in err and "20/20" in err


# ---- refusals --------------------------------------------------------------------------

def _start(i):
  return benchmark.fixed_starts("ship", 10)[i]


@pytest.mark.parametrize("policy, batched, message", [
    (lambda obs: [1.0, 2.0], False,
     "the policy returned shape (2,) dtype float64 at episode 0, step 0; the ship needs one "
     "turning rate r (deg/s): a number or shape (1,)"),
    (lambda obs: np.zeros((len(obs), 2)), True,
     "the policy returned shape (10, 2) dtype float64 at episode 0, step 0 (a batch of 10 "
     "episodes: 0, 1, 2, 3, 4, ...); the ship needs 10 turning rates r (deg/s): shape (10,) "
     "or (10, 1)"),
    (lambda obs: "left", False, "the policy returned shape () dtype <U4 at episode 0, step 0"),
])
def test_a_wrong_shape_is_refused_with_the_episode_and_step(policy, batched, message):
  with pytest.raises(benchmark.PolicyError) as err:
    benchmark.evaluate(policy, "ship", 10, batched=batched, progress=False)
  assert message in str(err.value)


def test_nan_and_raising_are_refused_with_the_episode_and_step():
  third = _start(3)

  def nan_at_third(obs):
    return math.nan if np.array_equal(obs, third) else 0.0
  with pytest.raises(benchmark.PolicyError, match=r"returned r = nan at episode 3, step 0;"):
    benchmark.evaluate(nan_at_third, "ship", 10, progress=False)

  calls = []

  def fails_on_the_eighth_call(obs):
    calls.append(1)
    if len(calls) == 8:
      raise RuntimeError("rudder jammed")
    return 15.0
  with pytest.raises(benchmark.PolicyError) as err:    # one copy: episode 0, step 7
    benchmark.evaluate(fails_on_the_eighth_call, "ship", 3, num_envs=1, progress=False)
  assert str(err.value) == ("the policy raised at episode 0, step 7: RuntimeError: "
                            "rudder jammed")
  assert isinstance(err.value.__cause__, RuntimeError)

  def batch_with_nan(obs):
    out = np.zeros(len(obs))
    out[2] = np.inf
    return out
  with pytest.raises(benchmark.PolicyError, match=r"returned r = inf at episode 2, step 0;"):
    benchmark.evaluate(batch_with_nan, "ship", 10, batched=True, progress=False)


@pytest.mark.parametrize("batched", [False, True])
def test_a_policy_reading_the_goals_dictionary_as_an_array_is_told_it_is_one(batched):
  with pytest.raises(benchmark.PolicyError) as err:
    benchmark.evaluate(lambda obs: obs[:, 0] if batched else obs[0], "ship_goal", 3,
                       batched=batched, progress=False)
  assert str(err.value).startswith("the policy raised at episode 0, step 0")
  assert str(err.value).endswith("(the observation is a dictionary of 'observation', "
                                 "'achieved_goal', 'desired_goal', 'ranges')")


def test_a_fixed_batch_policy_is_called_with_one_size_and_scores_the_same():
  """`fixed_batch`: the shrinking batch of the last episodes padded to `size` (a jitted
  JAX policy compiles once), the padded rows' actions dropped; the goal's dictionary
  too."""
  sizes = []

  def recording(policy):
    def act(obs):
      sizes.append(len(next(iter(obs.values())) if isinstance(obs, dict) else obs))
      return policy(obs)
    return act
  for task in ("ship", "ship_goal"):
    helm = benchmark.helmsman if task == "ship" else benchmark.ladder_helmsman(task)
    plain = benchmark.evaluate(helm, task, 12, progress=False)
    sizes.clear()
    fixed = benchmark.evaluate(benchmark.fixed_batch(recording(helm), size=16), task, 12,
                               progress=False)
    np.testing.assert_array_equal(fixed.record, plain.record)
    assert set(sizes) == {16} and len(sizes) == plain.record["steps"].max()
  with pytest.raises(ValueError, match="a batch of 12 observations, more than its size 8; "
                                       "give evaluate num_envs <= 8"):
    benchmark.evaluate(benchmark.fixed_batch(benchmark.helmsman, size=8), "ship", 12,
                       progress=False)
  with pytest.raises(ValueError, match="fixed_batch: size must be a positive integer, got 0"):
    benchmark.fixed_batch(benchmark.helmsman, size=0)


class Helm:
  """A user's policy with memory, with SB3's recurrent `predict`: each episode turns
  hard left for its first 8 control steps, then holds its course; the state is each
  row's step count, which `episode_start` sets back to 0."""

  def __init__(self):
    self.rows = []

  def predict(self, obs, state=None, episode_start=None, deterministic=True):
    self.rows.append(len(obs))
    count = np.zeros(len(obs), dtype=np.int64) if state is None else state.copy()
    count[np.asarray(episode_start, dtype=bool)] = 0
    return np.where(count < 8, 15.0, 0.0), count + 1


def _one_by_one(predict, task, episodes, memory=True):
  """Each fixed start sailed alone in its own environment, `predict` called as SB3's
  `evaluate_policy` calls a recurrent model (with memory=False: with no state, every
  step); the steps and returns."""
  import gymnasium
  task = benchmark.task_of(task)
  steps, returns = [], []
  for start in benchmark.fixed_starts(task, episodes):
    env = gymnasium.make(task.env_id, **task.env_kwargs("analytic"))
    obs, _ = env.reset(options={"state": start})
    state, begins, done, total, n = None, np.ones(1, dtype=bool), False, 0.0, 0
    while not done:
      action, new = predict(obs[None], state=state, episode_start=begins, deterministic=True)
      if memory:
        state, begins = new, np.zeros(1, dtype=bool)
      obs, reward, terminated, truncated, _ = env.step(np.asarray(action).reshape(-1)[:1])
      total, n, done = total + reward, n + 1, terminated or truncated
    steps.append(n)
    returns.append(total)
  return np.array(steps), np.array(returns)


def test_a_policy_with_memory_gets_its_state_back_and_each_episode_start():
  """A predict that returns a state is called with every copy of the vector
  environment, in order, its state handed back and `episode_start` marking the copies
  that begin an episode: it scores as each episode sailed alone with its memory
  (12 episodes over 5 copies: copies reused, the last ones idle)."""
  helm = Helm()
  task = benchmark.task_of("ship", 300)
  scored = benchmark.evaluate(helm, task, 12, num_envs=5, progress=False)
  assert set(helm.rows) == {5}                         # every copy, every call
  steps, returns = _one_by_one(Helm().predict, task, 12)
  np.testing.assert_array_equal(scored.record["steps"], steps)
  np.testing.assert_array_equal(scored.record["return"], returns)
  forgetting = _one_by_one(Helm().predict, task, 12, memory=False)   # circles for good
  assert not np.array_equal(forgetting[0], steps)
  with pytest.raises(benchmark.PolicyError) as err:     # one observation at a time
    benchmark.evaluate(Helm(), task, 2, batched=False, progress=False)
  assert str(err.value) == (
      "the policy raised at episode 0, step 0: ValueError: Helm.predict returned a state (a "
      "recurrent policy's memory), which one observation at a time would lose; score it "
      "with batched=True (the default for an object with predict)")
  with pytest.raises(ValueError, match=r"^policy is the class Helm, not an object of it; "
                                       r"pass one: Helm\(\)$"):
    benchmark.evaluate(Helm, task, 2, progress=False)

  class Forgetful(Helm):             # takes a state, returns the actions alone
    def predict(self, obs, state=None, episode_start=None, deterministic=True):
      return super().predict(obs, state, episode_start)[0]
  with pytest.warns(UserWarning, match=r"^Forgetful.predict takes a state but returned the "
                                       r"actions alone: it is scored as a policy of the "):
    forgot = benchmark.evaluate(Forgetful(), task, 12, num_envs=5, progress=False)
  np.testing.assert_array_equal(forgot.record["steps"], forgetting[0])


def test_a_recurrent_sb3_contrib_model_is_scored_with_its_memory():
  """sb3-contrib's RecurrentPPO (an LSTM policy) scores as SB3's own loop sails each
  start with the LSTM's state carried, through `evaluate` and `Pilot` (a video's)."""
  sb3_contrib = pytest.importorskip("sb3_contrib")
  import gymnasium

  import hpg_mj  # noqa: F401
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic")
  model = sb3_contrib.RecurrentPPO("MlpLstmPolicy", env, n_steps=64, batch_size=32, seed=0,
                                   device="cpu")
  scored = benchmark.evaluate(model, "ship", 8, num_envs=3, progress=False)
  steps, returns = _one_by_one(model.predict, "ship", 8)
  np.testing.assert_array_equal(scored.record["steps"], steps)
  np.testing.assert_array_equal(scored.record["return"], returns)
  pilot = benchmark.Pilot(model, "ship")
  obs, _ = env.reset(options={"state": benchmark.fixed_starts("ship", 1)[0]})
  pilot.reset()
  done, n = False, 0
  while not done:
    obs, _, terminated, truncated, _ = env.step(pilot(obs))
    done, n = terminated or truncated, n + 1
  assert n == steps[0]
  # trained on [-1, 1] turning rates: `rescaled` hands the state through both ways
  unit = sb3_contrib.RecurrentPPO("MlpLstmPolicy", gymnasium.wrappers.RescaleAction(env, -1, 1),
                                  n_steps=64, batch_size=32, seed=0, device="cpu")
  mapped = benchmark.rescaled(unit, "ship")
  assert mapped.predict(np.zeros((3, 4)), episode_start=np.ones(3, bool))[1] is not None
  scored = benchmark.evaluate(mapped, "ship", 4, num_envs=3, progress=False)
  np.testing.assert_array_equal(scored.record["steps"], _one_by_one(mapped.predict, "ship", 4)[0])
  with pytest.raises(benchmark.PolicyError, match="RecurrentPPO.predict returned a state"):
    benchmark.evaluate(model, "ship", 2, batched=False, progress=False)


def test_a_taxi_action_outside_the_actions_is_refused():
  with pytest.raises(benchmark.PolicyError) as err:
    benchmark.evaluate(lambda obs: 7, "taxi_fuel", 3, progress=False)
  assert str(err.value) == ("the policy returned action 7 at episode 0, step 0; allowed: "
                            "0 South, 1 North, 2 East, 3 West, 4 Pickup, 5 Dropoff, 6 Fillup")
  with pytest.raises(benchmark.PolicyError, match="returned action 2.5 at episode 1, step 0"):
    benchmark.evaluate(lambda obs: np.where(np.arange(len(obs)) == 1, 2.5, 0.0), "taxi", 3,
                       batched=True, progress=False)


def test_bad_arguments_are_refused():
  with pytest.raises(ValueError, match="task 'boat' is not known|boat"):
    benchmark.evaluate(lambda obs: 0.0, "boat", 1, progress=False)
  with pytest.raises(ValueError, match="max_steps must be a positive integer, got 0"):
    benchmark.evaluate(lambda obs: 0.0, "ship", 1, max_steps=0, progress=False)
  # the arguments the wrong way round: the record is named by its shape, not printed whole
  with pytest.raises(ValueError, match=r"^task an array of shape \(500,\) is not known"):
    benchmark.metrics_of("ship", np.zeros(500, dtype=[("passed", "f8")]))
  with pytest.raises(ValueError, match=r"^episodes must be at least 1 \(no episode has no "
                                       r"score\), got 0$"):
    benchmark.evaluate(lambda obs: 0.0, "ship", 0, progress=False)
  with pytest.raises(ValueError, match="is not a function, an object with predict"):
    benchmark.evaluate(42, "ship", 1, progress=False)
  agent = _flat_pg(episodes=1)
  with pytest.raises(ValueError, match="acts on the task 'ship', not 'taxi_fuel'"):
    benchmark.evaluate(agent, "taxi_fuel", 1, progress=False)
  with pytest.raises(ValueError, match="set \\[environment\\] max_steps there"):
    benchmark.evaluate(agent, episodes=1, max_steps=30, progress=False)


def test_as_record_refuses_a_wrong_number_of_columns():
  cls = agents.lookup("ship_flat_pg")
  with pytest.raises(ValueError) as err:
    cls.as_record(np.zeros((2, 5)))
  assert str(err.value) == ("ShipFlatPG.as_record: rows must have shape (episodes, 3), one "
                            "column per record field ['passed', 'steps', 'return']; got shape "
                            "(2, 5)")
  with pytest.raises(ValueError, match="got shape \\(6,\\)"):
    cls.as_record(np.zeros(6))
  assert cls.as_record(np.zeros((0, 3))).shape == (0,)


# ---- bounds and normalized scores ----------------------------------------------------------

def test_the_published_bounds_are_what_the_command_computes():
  """Recomputes every bound but the ship's search (a minute) on the 1,000 fixed
  starts: exactly the published numbers."""
  published = benchmark.bounds()
  assert published["protocol"]["episodes"] == base.GREEDY_STARTS
  assert published["protocol"]["seed"] == base.GREEDY_SEED
  for name in benchmark.TASKS:
    entry = published["tasks"][name]
    task = benchmark.task_of(name)
    random = benchmark.evaluate(benchmark.RandomPolicy(task), task, progress=False)
    assert benchmark.metrics_of(random.record, task) == entry["random"]
    for score in benchmark.SCORES[name]:
      assert random.metrics[f"{score}_normalized"] == 0.0
    if name == "ship":
      helm = benchmark.evaluate(benchmark.helmsman, task, progress=False)
      assert benchmark.metrics_of(helm.record, task) == entry["helmsman"]
      best = entry["best"]
      assert best["J"] >= entry["helmsman"]["J"] > entry["random"]["J"]
      assert best["gate_pass_rate"] >= entry["helmsman"]["gate_pass_rate"]
      assert 0 < helm.metrics["J_normalized"] <= 100.0
    else:
      optimal = benchmark.evaluate(benchmark.OptimalTaxiPolicy(task), task, progress=False)
      assert benchmark.metrics_of(optimal.record, task) == entry["best"]


def test_the_search_over_first_turns_is_never_worse_than_the_helmsman():
  starts = benchmark.fixed_starts("ship", 12)
  best, choice = benchmark.search_first_turns("ship", starts)
  helm = benchmark.evaluate(benchmark.helmsman, "ship", 12, progress=False).record
  assert np.all(best["passed"] >= helm["passed"])
  both = (best["passed"] > 0) & (helm["passed"] > 0)
  assert np.all(best["steps"][both] <= helm["steps"][both])
  plain = np.all(choice == 0, axis=1)     # no first turn found better: the helmsman's episode
  np.testing.assert_array_equal(best["steps"][plain], helm["steps"][plain])
  np.testing.assert_array_equal(best["return"], -best["steps"] + 100.0 * best["passed"])


def test_normalized_scores_are_0_for_random_and_100_for_best():
  published = {"tasks": {"ship": {"random": {"J": -98.0, "gate_pass_rate": 0.05},
                                  "best": {"J": -82.0, "gate_pass_rate": 0.99}}}}
  out = benchmark.normalized("ship", {"J": -90.0, "gate_pass_rate": 0.05}, published)
  assert out == {"J_normalized": 50.0, "gate_pass_rate_normalized": 0.0}
  assert benchmark.normalized("taxi", {"mean_return": 1.0}, published) == {}


def test_one_tasks_bounds_by_its_name_or_its_level():
  every = benchmark.bounds()["tasks"]
  assert benchmark.bounds("ship_goal/easy") == every["ship_goal/easy"]
  assert benchmark.bounds("ship_goal", level="hard") == every["ship_goal/hard"]
  assert benchmark.bounds("taxi_fuel") == every["taxi_fuel"]
  with pytest.raises(ValueError, match=r"^bounds: no task 'ship_goal'; give a level of "
                                       r"\['easy', 'medium', 'hard'\], e.g. ship_goal/easy; "):
    benchmark.bounds("ship_goal")
  with pytest.raises(ValueError, match=r"^bounds: no task 'steer'; allowed: \['ship', "):
    benchmark.bounds("steer")


# ---- the command line ------------------------------------------------------------------------

def test_hpg_mj_evaluate_policy_equals_the_function(tmp_path, capsys, monkeypatch):
  (tmp_path / "my_steering.py").write_text(
      "from hpg_mj import benchmark\n"
      "def steer(obs):\n"
      "  return float(benchmark.helmsman(obs[None])[0])\n"
      "def batch(obs):\n"
      "  return benchmark.helmsman(obs)\n")
  monkeypatch.chdir(tmp_path)
  assert cli.main(["evaluate", "--policy", "my_steering:steer", "--episodes", "15",
                   "--json"]) == 0
  single = json.loads(capsys.readouterr().out)
  assert cli.main(["evaluate", "--policy", str(tmp_path / "my_steering.py") + ":batch",
                   "--batched", "--episodes", "15", "--max-steps", "5000", "--json"]) == 0
  batched = json.loads(capsys.readouterr().out)
  expected = benchmark.evaluate(benchmark.helmsman, "ship", 15, progress=False).metrics
  for out in (single, batched):
    assert {k: out[k] for k in expected} == expected


@pytest.mark.parametrize("argv, message", [
    (["evaluate"], "give a saved agent folder, or --policy module:function"),
    (["evaluate", "--policy", "no_such_module_here:f"],
     "cannot import 'no_such_module_here': No module named 'no_such_module_here' (run from "
     "its folder, or give path/file.py:name)"),
    (["evaluate", "--policy", "math"], "give module:attribute"),
    (["evaluate", "--policy", "math:no_such"], "math has no attribute 'no_such'"),
    (["evaluate", "--policy", "math:sin", "--seed", "3"], "--seed is for a saved agent"),
])
def test_hpg_mj_evaluate_refuses(argv, message, capsys):
  assert cli.main(argv) == 2
  assert message in capsys.readouterr().err


def test_a_policy_module_that_raises_on_import_is_named_in_one_line(tmp_path, capsys,
                                                                    monkeypatch):
  """A newcomer's module failing as it loads read as a bad option ("error: boom")."""
  (tmp_path / "broken_policy.py").write_text("x = 1\nraise ValueError('boom at import')\n")
  monkeypatch.chdir(tmp_path)
  for spec in ("broken_policy:steer", str(tmp_path / "broken_policy.py") + ":steer"):
    assert cli.main(["evaluate", "--policy", spec]) == 2
    err = capsys.readouterr().err
    assert f"--policy '{spec}': importing it raised ValueError: boom at import (" in err
    assert "broken_policy.py, line 2)" in err and len(err.strip().splitlines()) == 1


def test_a_real_stable_baselines3_model_is_scored():
  sb3 = pytest.importorskip("stable_baselines3")
  import gymnasium

  import hpg_mj  # noqa: F401
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic")
  model = sb3.PPO("MlpPolicy", env, n_steps=64, batch_size=32, seed=0, device="cpu")
  result = benchmark.evaluate(model, "ship", 8, max_steps=60, progress=False)
  assert result.record.shape == (8,) and np.all(result.record["steps"] <= 60)
  again = benchmark.evaluate(model, "ship", 8, max_steps=60, progress=False)
  np.testing.assert_array_equal(result.record, again.record)     # deterministic=True
  taxi = sb3.DQN("MlpPolicy", gymnasium.make("hpg_mj/TaxiFuel-v0"), seed=0, device="cpu")
  scored = benchmark.evaluate(taxi, "taxi_fuel", 8, progress=False)
  assert scored.record.shape == (8,) and scored.metrics["mean_return_normalized"] is not None


def test_the_readme_block_runs_as_printed(capsys):
  import pathlib
  import re
  readme = (pathlib.Path(__file__).resolve().parents[1] / "README.md").read_text()
  section = readme.split("## Score your own policy\n", 1)[1]
  block = re.search(r"```python\n(.*?)```", section, re.S).group(1)
  exec(compile(block, "README.md: Score your own policy", "exec"), {"__name__": "readme"})
  printed = capsys.readouterr().out
  # r = 5 deg/s holds a circle of ~34 m: from most starts the ship circles until the cap.
  metrics = eval(printed.splitlines()[0], {"__builtins__": {}}, {"None": None})
  assert metrics["max_steps"] == 1000 and not metrics["official"]
  assert metrics["J"] < -99.0 and metrics["J_normalized"] < 0


def test_the_mujoco_ship_scores_like_the_analytic_one():
  """The same helmsman on the MJCF ship (SPEC section 1: within 0.25 m of the ODE,
  Euler within ~0.5 m): the same passes, the steps within one."""
  mujoco = benchmark.evaluate(benchmark.helmsman, "ship", 6, backend="mujoco", progress=False)
  analytic = benchmark.evaluate(benchmark.helmsman, "ship", 6, progress=False)
  np.testing.assert_array_equal(mujoco.record["passed"], analytic.record["passed"])
  assert np.abs(mujoco.record["steps"] - analytic.record["steps"]).max() <= 1


def test_an_interval_normalizes_end_by_end():
  from hpg_mj.experiments import bounds
  ship = bounds.bounds()["tasks"]["ship"]
  low, high = ship["random"]["J"], ship["best"]["J"]
  assert bounds.normalize("ship", "J", low) == 0.0
  assert bounds.normalize("ship", "J", high) == 100.0
  assert bounds.normalize("ship", "J", (low + high) / 2) == pytest.approx(50.0)
  assert bounds.normalize("ship", "J", None) is None
  assert bounds.normalize(None, "J", -90.0) is None


def test_hpg_mj_bounds_writes_what_compute_bounds_gives(tmp_path, capsys):
  out = tmp_path / "bounds.json"
  assert cli.main(["bounds", "--episodes", "4", "--out", str(out), "--quiet"]) == 0
  printed = capsys.readouterr().out
  assert "ship (max_steps 5000; normalized: J, gate_pass_rate;" in printed
  assert f"wrote {out}" in printed
  written = json.loads(out.read_text())
  assert list(written["tasks"]) == list(benchmark.KEYS)
  # What it wrote is compute_bounds', checked on one task of each kind (all of them
  # again would double the test's time: the planners, not the writing, take it).
  sample = ["ship", "taxi_fuel", "ship_current/easy", "ship_regatta/hard", "ship_harbour/medium"]
  again = json.loads(json.dumps(benchmark.compute_bounds(4, progress=False, tasks=sample)))
  assert {k: written["tasks"][k] for k in sample} == again["tasks"]
  assert {k: v for k, v in written.items() if k != "tasks"} == \
      {k: v for k, v in again.items() if k != "tasks"}
  assert written["tasks"]["taxi_fuel"]["best"]["fraction_of_optimum"] == 1.0
  # --task: only that task's bounds, replacing its entry in the file
  entry = written["tasks"]["ship_goal/hard"]
  written["tasks"]["ship_goal/hard"] = {"stale": True}
  out.write_text(json.dumps(written))
  assert cli.main(["bounds", "--episodes", "4", "--task", "ship_goal/hard", "--out", str(out),
                   "--quiet"]) == 0
  merged = json.loads(out.read_text())
  assert merged["tasks"]["ship_goal/hard"] == entry and list(merged["tasks"]) == list(
      benchmark.KEYS)
  capsys.readouterr()
  assert cli.main(["bounds", "--episodes", "5", "--task", "ship_goal/hard", "--out", str(out),
                   "--quiet"]) == 2
  assert "computed under another protocol" in capsys.readouterr().err
  assert cli.main(["bounds", "--task", "ship_goal"]) == 2
  assert capsys.readouterr().err.startswith("hpg-mj bounds: error: --task 'ship_goal' has no "
                                            "bounds; allowed: ship, taxi_fuel, taxi, "
                                            "ship_current/easy,")


def test_a_ladder_agent_is_scored_at_its_own_level_under_the_tasks_rewards(tmp_path):
  """An agent on the current trained with -300 for leaving the field is scored as any
  policy is, under the task's -100 (`_ladder.gate_returns`); at another level than its
  task file's, where the current is faster, it acts as it learned (`benchmark.at_level`:
  its rules read the numbers as they are); agents.load's
  whole tuple is refused naming what to pass."""
  task = agents.load_task("ship_current_hybrid")
  assert task.config.environment.out_of_bounds_reward == -300.0
  agent = agents.build(task, seed=0)
  trained = agent.train(20)
  got = benchmark.evaluate(agent, episodes=40, progress=False)
  record = got.record
  left = (record["passed"] == 0) & (record["steps"] < task.config.environment.max_steps)
  assert left.any()
  np.testing.assert_array_equal(record["return"],
                                -record["steps"] + 100.0 * record["passed"] - 100.0 * left)
  assert got.metrics["mean_return"] == record["return"].mean()
  for kw in ({"task": "ship_current", "level": "hard"}, {"task": "ship_current/hard"}):
    there = benchmark.evaluate(agent, episodes=2, progress=False, **kw).metrics
    assert (there["level"], there["trained_level"]) == ("hard", "easy")
  assert benchmark.evaluate(agent, "ship_current/easy", 2, progress=False).metrics["level"] == "easy"
  agents.save(agent, tmp_path / "agent", trained)
  with pytest.raises(ValueError, match=r"^policy is a tuple of 3 \(agents.load returns "
                     r"\(agent, record, metadata\)\); pass its agent, agents.load\(path\)\[0\]$"):
    benchmark.evaluate(agents.load(tmp_path / "agent"), episodes=1, progress=False)
  with pytest.raises(ValueError, match=r"^policy array\(\[0\., .*\.\.\. \(a ndarray\) is not a "
                     "function"):
    benchmark.evaluate(np.zeros(1000), "ship", 1, progress=False)
