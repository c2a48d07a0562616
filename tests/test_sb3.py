"""The Stable-Baselines3 adapter and reference agents (issue 21), against the real
library with tiny budgets: the native VecEnv against SB3's own DummyVecEnv over the
single environment, and each agent trained, saved, loaded, resumed (bit for bit)
and evaluated, through the Python API, the run machinery and the command line."""
import json
import pathlib
import subprocess
import sys
import tempfile

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from hpg_mj import agents  # noqa: E402
from hpg_mj import cli  # noqa: E402
from hpg_mj.envs import sb3 as sb3_env  # noqa: E402
from hpg_mj.experiments import runs  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[1]

# Each shipped task file with a tiny network and budget (the keys it changes).
TINY = {
    "ship_ppo": {"n_envs = 8": "n_envs = 2", "n_steps = 256": "n_steps = 100",
                 "batch_size = 256": "batch_size = 50", "n_epochs = 10": "n_epochs = 2",
                 "net_arch = [64, 64]": "net_arch = [8, 8]"},
    "ship_sac": {"learning_starts = 10000": "learning_starts = 300",
                 "buffer_size = 1000000": "buffer_size = 5000", "batch_size = 256": "batch_size = 32",
                 "gradient_steps = 4": "gradient_steps = 1",
                 "net_arch = [256, 256]": "net_arch = [8, 8]"},
    "taxi_fuel_ppo": {"n_envs = 8": "n_envs = 2", "n_steps = 256": "n_steps = 100",
                      "batch_size = 256": "batch_size = 50", "n_epochs = 10": "n_epochs = 2",
                      "net_arch = [64, 64]": "net_arch = [8, 8]"},
    "taxi_fuel_dqn": {"learning_starts = 5000": "learning_starts = 300",
                      "buffer_size = 200000": "buffer_size = 5000",
                      "exploration_steps = 20000": "exploration_steps = 1500",
                      "target_update_interval = 2000": "target_update_interval = 200",
                      "net_arch = [64, 64]": "net_arch = [8, 8]"},
}


def tiny_task(tmp_path, name):
  text = agents.shipped_tasks()[name].read_text()
  for old, new in TINY[name].items():
    assert old in text, (name, old)
    text = text.replace(old, new)
  path = tmp_path / f"{name}.toml"
  path.write_text(text)
  return path


# ---- the adapter --------------------------------------------------------------------

@pytest.mark.parametrize("env_id, kwargs", [
    ("hpg_mj/ShipSteering-v0", {"backend": "analytic", "max_steps": 7}),
    ("hpg_mj/TaxiFuel-v0", {"max_steps": 9}),
])
def test_native_vec_env_steps_as_sb3s_dummy_vec_env_over_the_single_env(env_id, kwargs):
  """Same seeds, same actions: observations, rewards, ends, terminal observations
  and time-limit flags equal SB3's own vectorisation of the single environment,
  through several autoresets (short time limits)."""
  import gymnasium
  from stable_baselines3.common.vec_env import DummyVecEnv
  n = 3
  native = sb3_env.make_vec_env(env_id, n, seed=5, **kwargs)
  dummy = DummyVecEnv([lambda: gymnasium.make(env_id, **kwargs) for _ in range(n)])
  dummy._seeds = sb3_env.copy_seeds(5, n)
  np.testing.assert_array_equal(native.reset(), dummy.reset())
  rng = np.random.default_rng(0)
  ends = 0
  for _ in range(30):
    actions = np.stack([native.action_space.sample() for _ in range(n)]) if \
        env_id.startswith("hpg_mj/Ship") else rng.integers(0, 7, n)
    a, b = native.step(actions), dummy.step(actions)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    np.testing.assert_array_equal(a[2], b[2])
    for i in np.flatnonzero(b[2]):
      ends += 1
      np.testing.assert_array_equal(a[3][i]["terminal_observation"],
                                    b[3][i]["terminal_observation"])
      assert a[3][i]["TimeLimit.truncated"] == b[3][i]["TimeLimit.truncated"]
  assert ends >= n * 3                    # every copy reset at least three times
  finished = native.finished()
  assert len(finished) == ends
  assert all(length <= kwargs["max_steps"] for _, _, _, length, *_ in finished)


def test_native_vec_env_rescales_and_refuses_what_it_cannot_adapt():
  import gymnasium
  env = sb3_env.make_vec_env("hpg_mj/ShipSteering-v0", 2, seed=0, rescale=True,
                             reward_scale=0.01, backend="analytic")
  assert env.action_space.low.tolist() == [-1.0] and env.action_space.high.tolist() == [1.0]
  obs = env.reset()
  raw = env.venv._observations()
  margin = 1.8                                  # one control step past the field
  np.testing.assert_allclose(obs[:, 0], (raw[:, 0] + margin) / (500 + margin) - 1, rtol=1e-6)
  np.testing.assert_allclose(obs[:, 2], raw[:, 2] / 180.0, rtol=1e-6)
  np.testing.assert_array_equal(env.act(np.array([[1.0], [-0.5]])), [[15.0], [-7.5]])
  _, reward, _, _ = env.step(np.zeros((2, 1)))
  np.testing.assert_allclose(reward, [-0.01, -0.01])
  plain = gymnasium.make_vec("hpg_mj/ShipSteering-v0", num_envs=2, backend="analytic",
                             vectorization_mode="vector_entry_point")
  with pytest.raises(ValueError, match="autoreset_mode='SameStep'"):
    sb3_env.NativeVecEnv(plain)
  with pytest.raises(TypeError, match="native vector environment"):
    sb3_env.NativeVecEnv(gymnasium.make("hpg_mj/TaxiFuel-v0"))


# ---- the agents -----------------------------------------------------------------------

@pytest.mark.parametrize("name", sorted(TINY))
def test_agent_trains_saves_resumes_bit_for_bit_and_evaluates(tmp_path, monkeypatch, name):
  temporary = tmp_path / "temporary"                # where SB3 would make its log folders
  temporary.mkdir()
  monkeypatch.setattr(tempfile, "tempdir", str(temporary))
  task = agents.load_task(tiny_task(tmp_path, name))
  agent = agents.build(task, seed=4)
  record = agent.train(2)
  assert record["steps"].tolist() == [1000.0, 1000.0]
  assert record["episodes"].sum() >= 1
  assert agent.env.control_steps >= 2000
  agents.save(agent, tmp_path / "agent", record)
  # The run goes on; a copy loaded from the save (the process's generators put back
  # as they were) goes on the same way: same record, same network, bit for bit.
  ahead = agent.train(2)
  loaded, saved_record, _ = agents.load(tmp_path / "agent")
  np.testing.assert_array_equal(saved_record, record)
  np.testing.assert_array_equal(loaded.train(2), ahead)
  mine, theirs = agent.model.policy.state_dict(), loaded.model.policy.state_dict()
  assert all(np.array_equal(mine[k].numpy(), theirs[k].numpy()) for k in mine)
  # Greedy on the fixed starts: one row per episode, from exactly those starts.
  greedy = loaded.evaluate_fixed(5)
  assert greedy["episodes"].tolist() == [1.0] * 5
  metrics = loaded.metrics(greedy)
  assert metrics["episodes_measured"] == 5
  world = task.section("environment")["world"]
  assert (greedy["steps"] <= task.section("environment")["max_steps"]).all()
  if world == "ship":
    assert 0.0 <= metrics["gate_pass_rate"] <= 1.0 and metrics["J"] < 0
  else:
    assert metrics["optimal_mean_return"] > metrics["mean_return"]
  assert not list(temporary.glob("SB3-*"))         # trained, resumed: no log folder left


def test_ship_greedy_episode_is_the_single_environments(tmp_path):
  """`evaluate_fixed` sails all starts at once; each row equals the episode of the
  single Gymnasium environment from that start under the model's greedy action."""
  task = agents.load_task(tiny_task(tmp_path, "ship_ppo"))
  agent = agents.build(task, seed=1)
  agent.train(1)
  starts = agent.fixed_starts(3)
  greedy = agent.evaluate_fixed(3)
  env = agent.make_env("gymnasium", "analytic")
  scale = agent.env                      # its rescaling of observations and actions
  for start, row in zip(starts, greedy):
    obs, _ = env.reset(options={"state": start})
    total, steps, done = 0.0, 0, False
    while not done:
      action, _ = agent.model.predict(scale.observe(obs[None]), deterministic=True)
      obs, reward, terminated, truncated, info = env.step(scale.act(action)[0])
      total += reward
      steps += 1
      done = terminated or truncated
    assert (row["steps"], row["return_sum"], row["gates"]) == (
        steps, total, float(info.get("event") == "gate"))


def test_training_does_not_depend_on_how_it_is_cut_nor_on_evaluations(tmp_path):
  task = agents.load_task(tiny_task(tmp_path, "taxi_fuel_dqn"))
  whole = agents.build(task, seed=3).train(3)
  cut = agents.build(task, seed=3)
  first = cut.train(1)
  cut.evaluate(4, policy="sampled")        # draws from SB3's generators, then puts them back
  np.testing.assert_array_equal(np.concatenate([first, cut.train(2)]), whole)


def test_net_arch_gives_sb3_its_hidden_layers_however_many(tmp_path):
  path = tiny_task(tmp_path, "ship_ppo")
  path.write_text(path.read_text().replace("net_arch = [8, 8]", "net_arch = [8, 6, 4]"))
  agent = agents.build(agents.load_task(path), seed=0)
  agent.train(1)
  widths = [layer.out_features for layer in agent.model.policy.mlp_extractor.policy_net
            if hasattr(layer, "out_features")]
  assert widths == [8, 6, 4]


def test_dqn_epsilon_decays_over_the_declared_control_steps(tmp_path):
  """One `learn` call is 4 copies x 1,000 steps; epsilon follows [dqn]
  exploration_steps (8,000 here), not the length of the call."""
  text = tiny_task(tmp_path, "taxi_fuel_dqn").read_text().replace(
      "exploration_steps = 1500", "exploration_steps = 8000")
  path = tmp_path / "eps.toml"
  path.write_text(text)
  agent = agents.build(agents.load_task(path), seed=0)
  agent.train(1)
  assert agent.model.num_timesteps == 4000
  assert agent.model.exploration_rate == pytest.approx(1.0 - 0.5 * (1.0 - 0.05))
  agent.train(4)
  assert agent.model.exploration_rate == pytest.approx(0.05)


@pytest.mark.parametrize("name", ["ship_sac", "taxi_fuel_ppo"])
def test_a_run_killed_after_a_checkpoint_resumes_to_the_same_result(tmp_path, monkeypatch, name):
  from hpg_mj.agents import sb3 as sb3_agents
  # The agent's own cadence (`checkpoint_rows`) wins over the runner's default of
  # 25,000 rows; here one row, so that a 3-row run checkpoints.
  monkeypatch.setattr(sb3_agents._SB3Agent, "checkpoint_rows", 1)
  monkeypatch.setattr(sb3_agents.ShipSAC, "checkpoint_rows", 1)
  # 100 greedy starts, not 1,000: the greedy record is compared whole either way, and
  # the SAC's thousand 5,000-step episodes were most of the test's time.
  monkeypatch.setattr(runs, "GREEDY_STARTS", 100)
  path = tiny_task(tmp_path, name)
  whole = runs.run(path, 7, 3, tmp_path / "whole")
  with pytest.raises(runs.RunInterrupted):
    runs.run(path, 7, 3, tmp_path / "cut", stop_after=2)
  assert (tmp_path / "cut" / "checkpoints" / "ep2").is_dir()
  resumed = runs.run(path, 7, 3, tmp_path / "cut")
  assert "resumed from checkpoint ep2" in (tmp_path / "cut" / "events.log").read_text()
  for name_ in ("record", "greedy"):
    np.testing.assert_array_equal(np.load(tmp_path / "whole" / f"{name_}.npy"),
                                  np.load(tmp_path / "cut" / f"{name_}.npy"))
  assert resumed["greedy"] == whole["greedy"]


def test_a_run_killed_by_sigkill_resumes_to_the_same_result(tmp_path):
  """`runs.run` (what `hpg-mj run` runs for each seed) in another process, killed
  with SIGKILL once a checkpoint is written, then run again here."""
  import signal
  import time
  path = tiny_task(tmp_path, "taxi_fuel_dqn")
  whole = runs.run(path, 8, 4, tmp_path / "whole", checkpoint_every=2)
  run_dir = tmp_path / "killed"
  code = (f"from hpg_mj.experiments import runs\n"
          f"runs.run({str(path)!r}, 8, 4, {str(run_dir)!r}, checkpoint_every=2)\n")
  proc = subprocess.Popen([sys.executable, "-P", "-c", code], cwd=tmp_path,    # the installed
                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # hpg_mj
  deadline = time.monotonic() + 300
  while not (run_dir / "checkpoints" / "ep2").is_dir() and proc.poll() is None:
    assert time.monotonic() < deadline
    time.sleep(0.01)
  proc.send_signal(signal.SIGKILL)
  proc.wait()
  assert proc.returncode == -signal.SIGKILL and not runs.is_finished(run_dir)
  resumed = runs.run(path, 8, 4, run_dir, checkpoint_every=2)
  assert "resumed from checkpoint ep2" in (run_dir / "events.log").read_text()
  np.testing.assert_array_equal(np.load(tmp_path / "whole" / "record.npy"),
                                np.load(run_dir / "record.npy"))
  assert resumed["greedy"] == whole["greedy"]


def test_cli_trains_and_evaluates_an_sb3_agent(tmp_path, capsys):
  out = tmp_path / "agent"
  assert cli.main(["train", str(tiny_task(tmp_path, "taxi_fuel_ppo")), "--episodes", "2",
                   "--out", str(out), "--quiet", "--json"]) == 0
  trained = json.loads(capsys.readouterr().out)
  assert trained["primitive_steps"] == 2000
  assert cli.main(["evaluate", str(out), "--episodes", "7", "--json"]) == 0
  evaluated = json.loads(capsys.readouterr().out)
  assert evaluated["episodes_measured"] == 7 and evaluated["policy"] == "greedy"
  # measured whole, a row an episode: not "rows of 1,000 control steps", nor "the last 100"
  assert evaluated["evaluation_window"] == "all 7 episodes of the evaluation"


def test_the_task_files_load_without_importing_torch():
  code = ("import sys; from hpg_mj import agents\n"
          "for n in ('ship_ppo', 'ship_sac', 'taxi_fuel_ppo', 'taxi_fuel_dqn'):\n"
          "  agents.load_task(n)\n"
          "print(sorted(m for m in ('torch', 'stable_baselines3') if m in sys.modules))")
  out = subprocess.run([sys.executable, "-P", "-c", code], capture_output=True, text=True,
                       check=True)
  assert out.stdout.strip() == "[]"


# ---- the scorer's input contract (hpg_mj.benchmark_spaces) ----

def test_a_model_on_rescaled_spaces_is_refused_and_scored_through_rescaled():
  """A model trained through RescaleAction acts on [-1, 1]: evaluate refuses it in one
  line rather than take its actions as -1..1 deg/s; `rescaled` scores it as the
  function 15 x its action would be, and maps observations rescaled to [-1, 1] too."""
  import gymnasium
  from gymnasium.wrappers import RescaleAction
  from stable_baselines3 import PPO

  from hpg_mj import benchmark
  env = RescaleAction(gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic"), -1.0, 1.0)
  model = PPO("MlpPolicy", env, seed=0)
  with pytest.raises(ValueError, match=r"^the policy's action_space is Box \[-1, 1\] of shape "
                     r"\(1,\) and the task 'ship' has Box \[-15, 15\] of shape \(1,\): .*"
                     r"benchmark.rescaled\(model, 'ship'\)"):
    benchmark.evaluate(model, "ship", episodes=3)
  ours = benchmark.evaluate(benchmark.rescaled(model, "ship"), "ship", episodes=20, max_steps=60)
  by_hand = benchmark.evaluate(
      lambda obs: 15.0 * model.predict(obs, deterministic=True)[0], "ship", episodes=20,
      max_steps=60, batched=True)
  np.testing.assert_array_equal(ours.record, by_hand.record)
  assert len(np.unique(ours.record["return"])) > 1

  venv = sb3_env.make_vec_env("hpg_mj/ShipSteering-v0", n_envs=2, seed=0, rescale=True,
                              backend="analytic")
  unit = PPO("MlpPolicy", venv, seed=0)
  with pytest.raises(ValueError, match=r"^the policy's observation_space is Box \[-1, 1\] of "
                     r"shape \(4,\) and the task 'ship' has Box low \[-1.8, "):
    benchmark.evaluate(unit, "ship", episodes=3)
  seen, raw = [], []
  policy = benchmark.rescaled(unit, "ship")
  policy.model = type("Spy", (), {"predict": lambda self, obs, deterministic: (
      seen.append(np.array(obs)) or unit.predict(obs, deterministic=deterministic))})()
  benchmark.evaluate(policy, "ship", episodes=5, max_steps=1)
  benchmark.evaluate(lambda obs: raw.append(np.array(obs)) or np.zeros(len(obs)), "ship",
                     episodes=5, max_steps=1, batched=True)
  assert np.abs(seen[0]).max() <= 1.0 and np.abs(raw[0]).max() > 100.0
  np.testing.assert_allclose(seen[0], venv.observe(raw[0]), atol=1e-6)


def test_rescaled_refuses_what_no_affine_map_takes_to_the_task():
  import gymnasium
  from stable_baselines3 import PPO

  from hpg_mj import benchmark
  taxi = PPO("MlpPolicy", gymnasium.make("hpg_mj/TaxiFuel-v0"), seed=0)
  with pytest.raises(ValueError, match=r"^the policy's observation_space is MultiDiscrete"):
    benchmark.evaluate(taxi, "ship", episodes=2)
  with pytest.raises(ValueError, match=r"^benchmark.rescaled: the model's observation_space "
                     r"MultiDiscrete\(\[ 5  5  5  4 13\]\) is no rescaling of the task 'ship'"):
    benchmark.rescaled(taxi, "ship")
  with pytest.raises(ValueError, match=r"^benchmark.rescaled: the model has no action_space"):
    benchmark.rescaled(type("M", (), {"observation_space": taxi.observation_space})(), "ship")
  assert benchmark.evaluate(taxi, "taxi_fuel", episodes=3).metrics["episodes"] == 3


def test_a_model_on_the_goal_s_rescaled_dictionary_is_scored_through_rescaled():
  """A newcomer's HER model on the goal, its dictionary's Boxes each on [-1, 1]:
  `evaluate` named `rescaled`, which then refused the dictionary; it maps each key."""
  import gymnasium

  from hpg_mj import benchmark
  task_space = gymnasium.make("hpg_mj/ShipGoal-v0").observation_space
  unit = gymnasium.spaces.Dict({k: gymnasium.spaces.Box(-1.0, 1.0, box.shape)
                                for k, box in task_space.spaces.items()})
  seen = []

  class Model:                          # SB3's predict and spaces, acting 0
    observation_space = unit
    action_space = gymnasium.spaces.Box(-1.0, 1.0, (1,))

    def predict(self, obs, deterministic=True):
      seen.append(obs)
      return np.zeros((len(obs["observation"]), 1)), None
  with pytest.raises(ValueError, match=r"benchmark.rescaled\(model, 'ship_goal/easy'\)"):
    benchmark.evaluate(Model(), "ship_goal", episodes=2, max_steps=2)
  raw = []
  scored = benchmark.evaluate(benchmark.rescaled(Model(), "ship_goal/easy"), "ship_goal",
                              episodes=4, max_steps=2)
  benchmark.evaluate(lambda obs: raw.append(obs) or np.zeros(4), "ship_goal", episodes=4,
                     max_steps=2, batched=True)
  assert scored.metrics["episodes"] == 4 and set(seen[0]) == set(task_space.spaces)
  for key, box in task_space.spaces.items():
    expected = (raw[0][key] - box.low) / (box.high - box.low) * 2.0 - 1.0
    np.testing.assert_allclose(seen[0][key], expected, atol=1e-12)
    assert np.abs(seen[0][key]).max() <= 1.0 + 1e-12


def test_a_ladder_model_is_refused_naming_its_level_and_scored_at_it():
  """A newcomer's PPO on the current at level medium: the refusal named the task alone,
  and `rescaled(model, 'ship_current')` (easy's spaces) then failed; it names the level.
  A model with another level's spaces is told so."""
  import gymnasium
  from gymnasium.wrappers import RescaleAction
  from stable_baselines3 import PPO

  from hpg_mj import benchmark
  env = RescaleAction(gymnasium.make("hpg_mj/ShipCurrent-v0", level="medium"), -1.0, 1.0)
  model = PPO("MlpPolicy", env, seed=0)
  with pytest.raises(ValueError, match=r"the task 'ship_current/medium' has Box \[-15, 15\].*"
                     r"benchmark.rescaled\(model, 'ship_current/medium'\)"):
    benchmark.evaluate(model, "ship_current", level="medium", episodes=2)
  with pytest.raises(ValueError, match=r"observation_space .* the task 'ship_current/medium' has"
                     r".*benchmark.rescaled\(model, 'ship_current/medium'\)"):
    benchmark.evaluate(benchmark.rescaled(model, "ship_current"), "ship_current/medium",
                       episodes=2)
  scored = benchmark.evaluate(benchmark.rescaled(model, "ship_current/medium"),
                              "ship_current/medium", episodes=3, max_steps=20)
  assert scored.metrics["level"] == "medium" and scored.metrics["episodes"] == 3
  # A model of another level's spaces, nothing rescaled (a newcomer's transfer study):
  # the refusal names the level it learned at, not rescaled, which would squeeze the
  # medium water's [-2, 2] onto the [-1, 1] it learned on.
  easy = PPO("MlpPolicy", gymnasium.make("hpg_mj/ShipCurrent-v0", level="easy"), seed=0)
  with pytest.raises(ValueError, match=r"^the policy's observation_space is ship_current/easy's "
                     r"and the task 'ship_current/medium' has Box .*: a model acts only in the "
                     r"spaces it learned in; score it at easy \(level='easy'\), or train one "
                     r"at medium$"):
    benchmark.evaluate(easy, "ship_current", level="medium", episodes=2)
