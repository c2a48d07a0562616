"""`hpg-mj train --set SECTION.KEY=VALUE` (`taskfile.assigned`, `agents.load_task(path,
assignments)`): a key of the task file set on the command line, written into the
file's text (so that a saved agent rebuilds it) and checked as the file's own keys
are; a malformed assignment, or a section or key the file lacks, refused in one line."""
import pytest

from hpg_mj import agents
from hpg_mj import cli
from hpg_mj import taskfile


def test_keys_are_set_in_the_text_and_checked_as_the_file_s():
  task = agents.load_task("ship_hybrid", ["root.alpha=0.25", "environment.max_steps=400",
                                          "protocol.seed=3"])
  assert (task.config.root.alpha, task.config.environment.max_steps) == (0.25, 400)
  assert task.protocol.seed == 3
  assert "alpha = 0.25    # set by --set\n" in task.text
  again = taskfile.loads(task.text, task.path, agents._Registry)
  assert again.config == task.config and again.tuning == task.tuning   # the rest kept
  bare = agents.load_task("taxi_fuel_ppo_jax", ["environment.world=taxi", "ppo.net_arch=[8,8]"])
  assert bare.config.ppo.net_arch == (8, 8)
  # Hidden layers: one or more, as SB3's net_arch takes them (a newcomer's trial: the
  # files once took exactly two).
  deep = agents.load_task("ship_sac_jax", ["sac.net_arch=[32,32,16]"])
  assert deep.config.sac.net_arch == (32, 32, 16)
  assert agents.load_task("ship_ppo", ["ppo.net_arch=[8]"]).config.ppo.net_arch == (8,)


@pytest.mark.parametrize("assignment, message", [
    ("alpha=0.3", r"--set 'alpha=0.3': give SECTION.KEY=VALUE, for example "
                  r"environment.level=hard"),
    ("rot.alpha=0.3", r"--set 'rot.alpha=0.3': the file has no \[rot\]; its sections: "
                      r"\['task', 'environment', 'root'"),
    ("root.alfa=0.3", r"--set 'root.alfa=0.3': \[root\] has no key 'alfa'; its keys: "),
    # a value the file's schema refuses names the --set that gave it
    ("root.alpha=fast", r"--set 'root.alpha=fast': \[root\] alpha must be a number, got "
                        r"'fast'"),
    ("environment.backend=gpu", r"--set 'environment.backend=gpu': \[environment\] backend = "
                                r"'gpu' is not allowed; allowed: \['analytic', 'mujoco'\]"),
])
def test_a_bad_assignment_is_refused_in_one_line(assignment, message):
  match = r"ship_hybrid.toml(: |, with )" + message
  with pytest.raises(taskfile.TaskFileError, match=match) as err:
    agents.load_task("ship_hybrid", [assignment])
  assert "\n" not in str(err.value)


@pytest.mark.parametrize("layers", ["[]", "[64, 0]", "[64, 1.5]"])
def test_hidden_layers_are_one_or_more_positive_integers(layers):
  match = (r"ship_ppo.toml, with --set 'ppo.net_arch=.*': \[ppo\] net_arch must be a list "
           r"of one or more positive integers, got \[")
  with pytest.raises(taskfile.TaskFileError, match=match) as err:
    agents.load_task("ship_ppo", [f"ppo.net_arch={layers}"])
  assert "\n" not in str(err.value)


def test_hpg_mj_train_takes_set(capsys):
  assert cli.main(["train", "ship_hybrid", "--set", "root.alpha=fast", "--quiet"]) == 2
  assert "[root] alpha must be a number, got 'fast'" in capsys.readouterr().err
