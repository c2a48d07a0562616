"""The taxi's learners in JAX (`hpg_mj.jax.ppo`, `hpg_mj.jax.dqn`): PPO learns its first
lesson within 0.2 M primitive steps and its greedy episodes are the Gymnasium
environment's; DQN's saved run resumes bit for bit and its epsilon decays; bad DQN
sections are refused in one line; `hpg-mj bench train` measures taxi files in
interleaved rounds."""
import numpy as np
import pytest

pytest.importorskip("jax.numpy")   # not `jax`: tests/ is on sys.path and holds tests/jax

from hpg_mj import agents  # noqa: E402
from hpg_mj.jax import ppo  # noqa: E402
from jax_task_file import task_file  # noqa: E402


@pytest.fixture(scope="module")
def taxi():
  """The shipped taxi-fuel configuration trained 0.2 M primitive steps, and its record."""
  agent = agents.build(agents.load_task("taxi_fuel_ppo_jax"), seed=1)
  return agent, agent.train(200)


def test_the_taxi_learns_within_200_000_steps(taxi):
  """The return of the episodes that end climbs from the random policy's (illegal
  pickups and drop-offs, ~-40) within 0.2 M primitive steps."""
  agent, record = taxi
  assert record["steps"].tolist() == [1000.0] * 200
  first, last = agent.metrics(record[:20]), agent.metrics(record[-20:])
  assert first["mean_return"] < -35.0
  assert last["mean_return"] > first["mean_return"] + 8.0
  # Every episode that ended is in one row: the rows' lengths add up to the steps
  # taken (all 64 copies), less those of the episodes still running or waiting.
  assert record["episode_steps"].sum() <= agent.control_steps
  assert record["episode_steps"].sum() > agent.control_steps - 64 * 200 - 20 * 64


def test_greedy_taxi_episodes_are_the_gymnasium_environments(taxi):
  """`evaluate_fixed` sails all starts at once in the JAX world; each row is the
  single Gymnasium environment's episode from that start under the greedy action."""
  agent, _ = taxi
  starts = agent.fixed_starts(6)
  greedy = agent.evaluate_fixed(6)
  trainer = agent.trainer
  env = agent.make_env("gymnasium")
  for start, row in zip(starts, greedy):
    obs, _ = env.reset(options={"state": start.astype(np.int64)})
    total, steps, done = 0.0, 0, False
    while not done:
      x = trainer.io.observe(np.asarray(obs))
      action = int(ppo.greedy_action(agent.runner.networks, trainer.io, x))
      obs, reward, terminated, truncated, info = env.step(action)
      total += reward
      steps += 1
      done = terminated or truncated
    assert (row["steps"], row["return_sum"]) == (steps, total)


# ---- DQN (hpg_mj.jax.dqn, the agent hpg_mj.agents.jax_dqn) ---------------------------

DQN_SMALL = {"n_envs = 16": "n_envs = 4", "n_steps = 64": "n_steps = 32",
             "learning_starts = 5000": "learning_starts = 200",
             "buffer_size = 200000": "buffer_size = 3000",
             "target_update_interval = 2000": "target_update_interval = 256"}


def test_a_saved_dqn_run_resumes_bit_for_bit_and_its_epsilon_decays(tmp_path):
  task = agents.load_task(task_file(tmp_path, "taxi_fuel_dqn_jax", DQN_SMALL))
  agent = agents.build(task, seed=3)
  record = agent.train(2)
  assert agent.control_steps == 2048 and record["episodes"].sum() >= 1
  agents.save(agent, tmp_path / "agent", record)
  ahead = agent.train(2)
  loaded, _, _ = agents.load(tmp_path / "agent")
  np.testing.assert_array_equal(loaded.train(2), ahead)
  for name, value in agent.state().items():
    np.testing.assert_array_equal(loaded.state()[name], value, err_msg=name)
  # The buffer holds every transition stored (3,000 at most), epsilon follows the
  # file's exploration_steps (600,000, tuned): 1 - 4,096 / 600,000 x 0.95.
  runner = agent.runner
  assert int(runner.stored) == 4096
  steps = agent.section.exploration_steps
  assert steps == 600_000
  assert float(agent.trainer.epsilon(runner.stored)) == pytest.approx(1 - 4096 / steps * 0.95)
  assert np.asarray(runner.buffer["x"]).sum(axis=1).min() == 5      # five one-hot components
  greedy = loaded.evaluate_fixed(3)
  assert greedy["episodes"].tolist() == [1.0] * 3


def test_bad_dqn_sections_are_refused_in_one_line(tmp_path):
  bad = task_file(tmp_path, "taxi_fuel_dqn_jax", {"train_freq = 1 ": "train_freq = 3 "})
  with pytest.raises(ValueError, match=r"taxi_fuel_dqn_jax.toml: \[dqn\] train_freq = 3 must "
                                       r"divide n_steps = 64"):
    agents.load_task(bad)


def test_bench_train_measures_task_files_in_interleaved_rounds(tmp_path):
  """`hpg-mj bench train --task A --task B --rounds 2`: a row each, the median of its
  rounds, counted in the control steps the agent trained (whole updates of 8,192)."""
  from hpg_mj import bench
  other = task_file(tmp_path, "taxi_fuel_ppo_jax", {})
  row = bench.bench_task(other, min_seconds=0.05)
  assert row["steps"] % 8192 == 0 and row["steps"] > 0      # whole updates, not rows
  rows = bench.bench_train(0.05, ["taxi_fuel_ppo_jax", str(other)], rounds=2)
  assert [name for name, _, _ in rows] == ["taxi_fuel_ppo_jax, learning, median of 2 rounds"] * 2
  assert all(unit == "primitive steps/s" and rate > 0 for _, unit, rate in rows)
