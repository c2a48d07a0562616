"""Gymnasium environments; `import hpg_mj` registers them."""
import gymnasium

# id -> (entry point, default keyword arguments)
ENV_IDS = {
    "hpg_mj/ShipSteering-v0": ("hpg_mj.envs.ship:ShipSteeringEnv", {"task": "steer"}),
    "hpg_mj/ShipSteeringDiagonal-v0": ("hpg_mj.envs.ship:ShipSteeringEnv", {"task": "diagonal"}),
    "hpg_mj/ShipSteeringStraight-v0": ("hpg_mj.envs.ship:ShipSteeringEnv", {"task": "straight"}),
    "hpg_mj/TaxiFuel-v0": ("hpg_mj.envs.taxi:TaxiEnv", {"fuel": True}),
    "hpg_mj/Taxi-v0": ("hpg_mj.envs.taxi:TaxiEnv", {"fuel": False}),
}


def register_all():
  for env_id, (entry_point, kwargs) in ENV_IDS.items():
    if env_id not in gymnasium.registry:
      gymnasium.register(id=env_id, entry_point=entry_point, kwargs=dict(kwargs))


def make(env_id, **kwargs):
  """`gymnasium.make` for hpg_mj ids, with an error listing the valid ids."""
  if env_id not in ENV_IDS:
    raise ValueError(f"unknown hpg_mj environment id {env_id!r}; valid ids: {sorted(ENV_IDS)}")
  return gymnasium.make(env_id, **kwargs)
