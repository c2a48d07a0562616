"""The paper's baselines: flat policy gradient and actor-critic on the ship,
flat Q-learning and MAXQ-Q on taxi-fuel."""
