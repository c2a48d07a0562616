"""Control steps per second of Stable-Baselines3 on hpg_mj's native vector
environments (`hpg_mj.envs.sb3.make_vec_env`) against SB3's own `make_vec_env`
over the single environment (a DummyVecEnv of Monitor-wrapped copies), in one run,
interleaved round by round so that both see the same machine load (issue 21, item 5).

    python scripts/sb3_speed.py [--n-envs 8 64] [--rounds 5] [--steps 40000]

Two measures per world (ship: the analytic ShipSteering-v0; taxi: TaxiFuel-v0):
stepping alone (uniform random actions drawn beforehand, the VecEnv API
`step_async`/`step_wait`), and PPO learning (SB3's defaults but n_steps = 256,
an MLP of 64 x 64, one torch thread). Prints the median over rounds and the
ratio native / SB3. Needs the extra: pip install 'hpg_mj[sb3]'.
"""
import argparse
import statistics
import time

import numpy as np

WORLDS = {"ship": ("hpg_mj/ShipSteering-v0", {"backend": "analytic"}),
          "taxi": ("hpg_mj/TaxiFuel-v0", {})}


def envs(world, n_envs, seed):
  from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env

  from hpg_mj.envs import sb3
  env_id, kwargs = WORLDS[world]
  return {"native": sb3.make_vec_env(env_id, n_envs, seed=seed, **kwargs),
          "sb3 make_vec_env": sb3_make_vec_env(env_id, n_envs, seed=seed, env_kwargs=kwargs)}


def stepping(env, steps, seed):
  """Control steps per second of `steps` (all copies) random actions."""
  n = env.num_envs
  env.action_space.seed(seed)
  actions = np.array([[env.action_space.sample() for _ in range(n)]
                      for _ in range(steps // n)])
  env.reset()
  start = time.perf_counter()
  for a in actions:
    env.step_async(a)
    env.step_wait()
  return len(actions) * n / (time.perf_counter() - start)


def learning(env, steps, seed):
  """Control steps per second of PPO learning `steps` control steps."""
  from stable_baselines3 import PPO
  model = PPO("MlpPolicy", env, n_steps=256, batch_size=256, seed=seed, device="cpu", verbose=0)
  start = time.perf_counter()
  model.learn(steps)
  return model.num_timesteps / (time.perf_counter() - start)


def main(argv=None):
  parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
  parser.add_argument("--n-envs", type=int, nargs="+", default=[8, 64])
  parser.add_argument("--rounds", type=int, default=5)
  parser.add_argument("--steps", type=int, default=40_000,
                      help="control steps stepped per measurement (PPO: a quarter)")
  args = parser.parse_args(argv)
  import torch
  torch.set_num_threads(1)
  print(f"{args.rounds} interleaved rounds, median control steps/s (all copies together)")
  print(f"{'world':<6} {'copies':>6} {'measure':<10} {'native':>12} {'sb3 make_vec_env':>18} "
        f"{'ratio':>7}")
  for world, n_envs in ((w, n) for w in WORLDS for n in args.n_envs):
    for measure, fn, steps in (("stepping", stepping, args.steps),
                               ("PPO", learning, args.steps // 4)):
      rates = {"native": [], "sb3 make_vec_env": []}
      for r in range(args.rounds):
        made = envs(world, n_envs, seed=r)
        order = list(made) if r % 2 == 0 else list(made)[::-1]   # alternate who goes first
        for name in order:
          rates[name].append(fn(made[name], steps, r))
      native = statistics.median(rates["native"])
      theirs = statistics.median(rates["sb3 make_vec_env"])
      print(f"{world:<6} {n_envs:>6} {measure:<10} {native:>12,.0f} {theirs:>18,.0f} {native / theirs:>6.1f}x",
            flush=True)


if __name__ == "__main__":
  main()
