"""Gymnasium environments; `import hpg_mj` registers them."""
import gymnasium

# id -> (entry point, default keyword arguments); the native batch of each id is
# `VECTOR_ENTRY_POINTS`' (`gymnasium.make_vec(id, num_envs=N)`, hpg_mj.envs.vector).
ENV_IDS = {
    "hpg_mj/ShipSteering-v0": ("hpg_mj.envs.ship:ShipSteeringEnv", {"task": "steer"}),
    "hpg_mj/ShipSteeringDiagonal-v0": ("hpg_mj.envs.ship:ShipSteeringEnv", {"task": "diagonal"}),
    "hpg_mj/ShipSteeringStraight-v0": ("hpg_mj.envs.ship:ShipSteeringEnv", {"task": "straight"}),
    "hpg_mj/ShipPatrol-v0": ("hpg_mj.envs.ship:ShipSteeringEnv", {"task": "patrol"}),
    "hpg_mj/ShipCurrent-v0": ("hpg_mj.envs.ship_current:ShipCurrentEnv", {"level": "easy"}),
    "hpg_mj/ShipGoal-v0": ("hpg_mj.envs.ship_goal:ShipGoalEnv", {"level": "easy"}),
    "hpg_mj/ShipRegatta-v0": ("hpg_mj.envs.ship_regatta:ShipRegattaEnv", {"level": "easy"}),
    "hpg_mj/ShipHarbour-v0": ("hpg_mj.envs.ship_harbour:ShipHarbourEnv", {"level": "easy"}),
    "hpg_mj/TaxiFuel-v0": ("hpg_mj.envs.taxi:TaxiEnv", {"fuel": True}),
    "hpg_mj/Taxi-v0": ("hpg_mj.envs.taxi:TaxiEnv", {"fuel": False}),
}

VECTOR_ENTRY_POINTS = {
    "hpg_mj.envs.ship:ShipSteeringEnv": "hpg_mj.envs.vector:ShipSteeringVectorEnv",
    "hpg_mj.envs.taxi:TaxiEnv": "hpg_mj.envs.vector:TaxiVectorEnv",
    "hpg_mj.envs.ship_current:ShipCurrentEnv": "hpg_mj.envs.ship_current:ShipCurrentVectorEnv",
    "hpg_mj.envs.ship_goal:ShipGoalEnv": "hpg_mj.envs.ship_goal:ShipGoalVectorEnv",
    "hpg_mj.envs.ship_regatta:ShipRegattaEnv": "hpg_mj.envs.ship_regatta:ShipRegattaVectorEnv",
    "hpg_mj.envs.ship_harbour:ShipHarbourEnv": "hpg_mj.envs.ship_harbour:ShipHarbourVectorEnv",
}


def refuse_level(who, level):
  """Refuses a `level` for a task without levels, naming the ids that have them."""
  if level is not None:
    raise ValueError(f"{who} has no levels (level={level!r}); the ids with levels: "
                     f"{[i for i, (_, kwargs) in ENV_IDS.items() if 'level' in kwargs]}")


def register_all():
  """Registers every hpg_mj Gymnasium id (and its vector entry point) not yet
  registered; importing hpg_mj calls it."""
  for env_id, (entry_point, kwargs) in ENV_IDS.items():
    if env_id not in gymnasium.registry:
      gymnasium.register(id=env_id, entry_point=entry_point, kwargs=dict(kwargs),
                         vector_entry_point=VECTOR_ENTRY_POINTS[entry_point])


def make(env_id, **kwargs):
  """`gymnasium.make` for hpg_mj ids, with an error listing the valid ids."""
  if env_id not in ENV_IDS:
    raise ValueError(f"unknown hpg_mj environment id {env_id!r}; valid ids: {sorted(ENV_IDS)}")
  return gymnasium.make(env_id, **kwargs)
