"""SAC in JAX (`hpg_mj.jax.sac`, the agent `hpg_mj.agents.jax_sac`): its agent loads
from the shipped task file, it trains (small networks, a few thousand control
steps), a saved run resumes bit for bit, seeds vmap into one run, and a bad
[sac] section is refused in one line."""
import numpy as np
import pytest

pytest.importorskip("jax.numpy")   # not `jax`: tests/ is on sys.path and holds tests/jax
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from hpg_mj import agents  # noqa: E402
from hpg_mj.jax import sac  # noqa: E402

# Small networks and batches, learning from the 200th control step: quick to compile and run.
SMALL = {"n_envs = 4": "n_envs = 2", "n_steps = 250": "n_steps = 100",
         "buffer_size = 1000000": "buffer_size = 1500", "learning_starts = 10000":
         "learning_starts = 200", "batch_size = 256": "batch_size = 32",
         "gradient_steps = 4": "gradient_steps = 2", "net_arch = [64, 64] ": "net_arch = [16, 16] "}


def task_file(tmp_path, changes=SMALL):
  text = agents.shipped_tasks()["ship_sac_jax"].read_text()
  for old, new in changes.items():
    assert old in text, old
    text = text.replace(old, new)
  path = tmp_path / "ship_sac_jax.toml"
  path.write_text(text)
  return path


def test_the_shipped_task_file_loads_its_agent():
  task = agents.load_task("ship_sac_jax")
  agent = agents.build(task, seed=0)
  assert type(agent).__name__ == "ShipSACJax" and agent.algorithm == "sac"
  s = task.config.sac
  assert (s.n_envs, s.n_steps, s.gradient_steps, s.buffer_size) == (4, 250, 4, 1_000_000)
  assert task.config.environment.backend == "analytic"
  assert task.control_steps == 1_000_000 and task.protocol.episodes == 1000
  assert agent.checkpoint_rows == 100        # `hpg-mj run` saves a run every 0.1 M steps
  assert task.tuning_seeds == tuple(range(10))
  assert task.tuning["budget"] == 4 and task.tuning["episodes"] == 1000
  assert task.tuning["grid"] == {"sac": {"learning_rate": [0.0001, 0.0003], "gamma": [0.99, 0.995]}}
  # The actor acts in [-1, 1]; the world gets the turning rate in deg/s.
  assert float(agent.trainer.io.act(jnp.ones(1))[0]) == 15.0


def test_a_saved_sac_run_resumes_bit_for_bit(tmp_path):
  task = agents.load_task(task_file(tmp_path))
  agent = agents.build(task, seed=2)
  record = agent.train(2)
  assert record["steps"].tolist() == [1000.0, 1000.0] and agent.control_steps == 2000
  runner = agent.runner
  assert int(runner.stored) == 2000
  actions = np.asarray(runner.buffer["action"])[:1500]
  assert np.abs(actions).max() <= 1.0 and actions.std() > 0.1
  losses = dict(zip(sac.LOSSES, np.asarray(runner.losses)))
  assert np.isfinite(list(losses.values())).all() and losses["critic_loss"] > 0
  assert 0.0 < losses["alpha"] < 1.0          # the temperature has moved from 1
  count = 2 * (2000 - 200) // 2                # gradient_steps a step of both copies, past 200
  assert int(runner.nets.critic_opt["count"]) == count
  agents.save(agent, tmp_path / "agent", record)
  ahead = agent.train(1)
  loaded, saved_record, _ = agents.load(tmp_path / "agent")
  np.testing.assert_array_equal(saved_record, record)
  np.testing.assert_array_equal(loaded.train(1), ahead)
  mine, theirs = agent.state(), loaded.state()
  assert sorted(mine) == sorted(theirs) and "runner.nets.critics.0.kernel" in mine
  for name in mine:
    np.testing.assert_array_equal(mine[name], theirs[name], err_msg=name)
  greedy = loaded.evaluate_fixed(2)
  assert greedy["episodes"].tolist() == [1.0] * 2
  assert (greedy["steps"] >= 1).all() and (greedy["steps"] <= 5000).all()


def test_seeds_vmap_into_one_run():
  """A whole run is a function of a key: vmapped over seeds, it traces into one
  program (traced here, not compiled: the shapes of its state and rows)."""
  trainer = agents.build(agents.load_task("ship_sac_jax")).trainer
  runners, rows = jax.eval_shape(jax.vmap(trainer.make_train(3)),
                                 jax.random.split(jax.random.PRNGKey(0), 10))
  assert rows.shape == (10, 3, 250, len(trainer.row.fields))
  assert runners.nets.critics[1]["kernel"].shape == (10, 2, 64, 64)
  assert runners.buffer["x"].shape == (10, 1_000_000, 4)


def test_a_bad_sac_section_is_refused_in_one_line(tmp_path):
  bad = task_file(tmp_path, {"train_freq = 1 ": "train_freq = 3 "})
  with pytest.raises(ValueError, match=r"ship_sac_jax.toml: \[sac\] train_freq = 3 must divide "
                                       r"n_steps = 250"):
    agents.load_task(bad)
