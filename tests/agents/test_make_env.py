"""An agent's environments are configured from its task file, through either API."""
import numpy as np

from hpg_mj import agents


def test_ship_environments_carry_the_task_files_rewards():
  agent = agents.build(agents.load_task("ship_hybrid"), seed=0)
  assert agent.config.environment.out_of_bounds_reward == -300.0      # D1, not SPEC's -100
  start = [1.0, 500.0, -90.0, 0.0]           # 1 m from the west edge, heading west
  dm = agent.make_env("dm_control")
  dm.task.initial_state = start
  dm.reset()
  step = dm.step(np.array([0.0]))
  assert step.last() and step.discount == 0.0 and step.reward == -301.0
  gym = agent.make_env("gymnasium", backend="analytic")
  gym.reset(options={"state": start})
  _, reward, terminated, _, _ = gym.step(np.array([0.0]))
  assert terminated and reward == -301.0
