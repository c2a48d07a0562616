"""PPO in JAX (`hpg_mj.jax.ppo`, the agents of `hpg_mj.agents.jax_ppo`):
it learns (the ship's diagonal subtask, two seeds vmapped into one compile; the
taxi's first lesson), its record rows hold the episodes SB3's would, a saved run
and a stopped `hpg-mj run` resume bit for bit, its greedy episodes are the
Gymnasium environment's, and bad task files are refused in one line."""
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("jax.numpy")   # not `jax`: tests/ is on sys.path and holds tests/jax
import jax  # noqa: E402

from hpg_mj import agents  # noqa: E402
from hpg_mj.jax import ppo  # noqa: E402

# Small rollouts (8 copies x 16 steps, 2 epochs of 2 minibatches): quick to compile and run.
SMALL = {"n_envs = 64": "n_envs = 8", "n_steps = 128": "n_steps = 16",
         "batch_size = 2048": "batch_size = 64", "n_epochs = 4": "n_epochs = 2"}


def task_file(tmp_path, name, changes=SMALL):
  text = agents.shipped_tasks()[name].read_text()
  for old, new in changes.items():
    assert old in text, (name, old)
    text = text.replace(old, new)
  path = tmp_path / f"{name}.toml"
  path.write_text(text)
  return path


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


def test_ppo_learns_the_diagonal_subtask_two_seeds_vmapped_in_one_compile():
  """The Gaussian policy on SPEC section 3's diagonal subtask (its shaped reward, 300
  steps at most), the ship's shipped [ppo] section, two seeds vmapped into one
  compile (`make_train`): each goes from ~12% of the episodes reaching the goal in
  its first 0.25 M control steps to over 80% in the next 0.25 M (measured on seed 0:
  0.12, then 0.88; 0.99 after 0.75 M)."""
  from hpg_mj import jax as hpg_jax
  from hpg_mj.agents import _ship
  section = agents.load_task("ship_ppo_jax").config.ppo
  env, params = hpg_jax.make("ShipSteeringDiagonal-v0")
  row = ppo.ShipRow(_ship.J_GAMMA, _ship.J_STEP_REWARD, _ship.J_GATE_REWARD,
                    _ship.J_OUT_OF_BOUNDS_REWARD)
  trainer = ppo.Trainer(env, params, section, row)
  train = jax.jit(jax.vmap(trainer.make_train(60)))    # 60 updates of 8,192 control steps
  runners, rows = train(jax.random.split(jax.random.PRNGKey(0), 2))
  assert rows.shape == (2, 60, 128, len(ppo.ShipRow.fields))
  rows = np.asarray(rows, dtype=np.float64)
  for seed in range(2):
    rates = [part[..., 1].sum() / part[..., 0].sum() for part in (rows[seed, :30], rows[seed, 30:])]
    assert rates[0] < 0.3 and rates[1] > 0.8, (seed, rates)
  kernels = np.asarray(runners.networks["actor"][0]["kernel"])
  assert kernels.shape == (2, 4, 64) and not np.array_equal(kernels[0], kernels[1])
  assert int(runners.opt["count"][0]) == 60 * 4 * 4     # updates x epochs x minibatches


def test_a_saved_ship_run_resumes_bit_for_bit(tmp_path):
  task = agents.load_task(task_file(tmp_path, "ship_ppo_jax"))
  agent = agents.build(task, seed=4)
  record = agent.train(2)
  assert record["steps"].tolist() == [1000.0, 1000.0]
  assert agent.control_steps == 2048           # whole updates of 128 control steps
  agents.save(agent, tmp_path / "agent", record)
  ahead = agent.train(3)
  loaded, saved_record, _ = agents.load(tmp_path / "agent")
  np.testing.assert_array_equal(saved_record, record)
  np.testing.assert_array_equal(loaded.train(3), ahead)
  mine, theirs = agent.state(), loaded.state()
  assert sorted(mine) == sorted(theirs) and "runner.networks.actor.0.kernel" in mine
  for name in mine:
    np.testing.assert_array_equal(mine[name], theirs[name], err_msg=name)
  # Cut into other calls, the run is the same: 2 + 3 rows = 1 + 4.
  cut = agents.build(task, seed=4)
  np.testing.assert_array_equal(np.concatenate([cut.train(1), cut.train(4)]),
                                np.concatenate([record, ahead]))
  # Greedy on the fixed starts: a row an episode, within the step limit.
  greedy = loaded.evaluate_fixed(4)
  assert greedy["episodes"].tolist() == [1.0] * 4
  assert (greedy["steps"] >= 1).all() and (greedy["steps"] <= 5000).all()
  metrics = loaded.metrics(greedy)
  assert metrics["episodes_measured"] == 4 and metrics["J"] < 0


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


def test_a_run_stopped_after_a_checkpoint_resumes_to_the_same_result(tmp_path, monkeypatch):
  """`hpg-mj run`'s runner (checkpoints every row here), stopped after row 2 and run
  again: the same record and the same greedy scores as the run never stopped."""
  from hpg_mj.agents import jax_ppo
  from hpg_mj.experiments import runs
  monkeypatch.setattr(jax_ppo._JaxAgent, "checkpoint_rows", 1)
  path = task_file(tmp_path, "taxi_fuel_ppo_jax", {})        # the shipped file: compiled already
  whole = runs.run(path, 7, 3, tmp_path / "whole")
  with pytest.raises(runs.RunInterrupted):
    runs.run(path, 7, 3, tmp_path / "cut", stop_after=2)
  resumed = runs.run(path, 7, 3, tmp_path / "cut")
  assert "resumed from checkpoint ep2" in (tmp_path / "cut" / "events.log").read_text()
  for name in ("record", "greedy"):
    np.testing.assert_array_equal(np.load(tmp_path / "whole" / f"{name}.npy"),
                                  np.load(tmp_path / "cut" / f"{name}.npy"))
  assert resumed["greedy"] == whole["greedy"]


def test_bad_task_files_are_refused_in_one_line(tmp_path):
  bad = task_file(tmp_path, "ship_ppo_jax", {**SMALL, "batch_size = 64": "batch_size = 48"})
  with pytest.raises(ValueError, match=r"ship_ppo_jax.toml: \[ppo\] batch_size = 48 must "
                                       r"divide n_envs x n_steps = 128"):
    agents.load_task(bad)
  bad = task_file(tmp_path, "ship_ppo_jax", {'backend = "analytic"': 'backend = "mujoco"'})
  with pytest.raises(ValueError, match=r"ship_ppo_jax.toml: ship_ppo_jax: \[environment\] "
                                       r"backend = 'mujoco'; the JAX agents train on"):
    agents.build(agents.load_task(bad))


def test_the_task_files_load_and_build_without_importing_jax():
  code = ("import sys; from hpg_mj import agents\n"
          "for n in ('ship_ppo_jax', 'taxi_fuel_ppo_jax', 'taxi_fuel_dqn_jax', 'ship_sac_jax'):\n"
          "  agents.build(agents.load_task(n))\n"
          "print(sorted(m for m in ('jax', 'jaxlib') if m in sys.modules))")
  out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
  assert out.stdout.strip() == "[]"


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
  # The buffer holds every transition stored (3,000 at most), epsilon follows
  # exploration_steps (200,000): 1 - 4,096 / 200,000 x 0.95.
  runner = agent.runner
  assert int(runner.stored) == 4096
  assert float(agent.trainer.epsilon(runner.stored)) == pytest.approx(1 - 4096 / 200000 * 0.95)
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
