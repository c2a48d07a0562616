"""A shipped JAX task file made small for a test (tests/jax/): its text with some lines
replaced, written under the test's folder."""
from hpg_mj import agents

# Small rollouts (8 copies x 16 steps, 2 epochs of 2 minibatches): quick to compile and run.
SMALL = {"n_envs = 64": "n_envs = 8", "n_steps = 128": "n_steps = 16",
         "batch_size = 2048": "batch_size = 64", "n_epochs = 4": "n_epochs = 2"}


def task_file(tmp_path, name, changes=SMALL):
  """The shipped task file `name` with each of `changes` (old line: new) made, at
  tmp_path/<name>.toml."""
  text = agents.shipped_tasks()[name].read_text()
  for old, new in changes.items():
    assert old in text, (name, old)
    text = text.replace(old, new)
  path = tmp_path / f"{name}.toml"
  path.write_text(text)
  return path
