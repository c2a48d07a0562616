"""Steps per second of the JAX worlds against the native (numba) vector environments.

```bash
python -m hpg_mj.jax.bench [--envs 4096] [--steps 1000] [--x64]
```

For each task, the same batch of `--envs` episodes under uniform random actions:
the JAX environment's `step` (gymnax's, with its auto-reset) vmapped over the batch
and scanned over `--steps` steps in one jitted call, timed after its compilation
(reported apart); and `gymnasium.make_vec(id, num_envs, ...)` stepped `--steps`
times from Python (hpg_mj.envs.vector: one compiled call a step). Both on the
devices JAX and numba find (the CPU here; JAX takes a GPU where jaxlib has one).
"""
import argparse
import time

import numpy as np

TASKS = {"ship": ("ShipSteering-v0", {"backend": "analytic"}),
         "taxi_fuel": ("TaxiFuel-v0", {})}


def jax_steps_per_second(env_id, n_envs, n_steps, seed=0):
  """(steps/s, compile seconds) of the vmapped, scanned JAX environment."""
  import jax

  from hpg_mj import jax as hpg_jax
  env, params = hpg_jax.make(env_id)
  space = env.action_space(params)
  step = jax.vmap(env.step, in_axes=(0, 0, 0, None))

  @jax.jit
  def run(key):
    keys = jax.random.split(key, n_envs)
    _, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)

    def body(state, key):
      act_key, step_key = jax.random.split(key)
      actions = jax.vmap(space.sample)(jax.random.split(act_key, n_envs))
      _, state, reward, done, _ = step(jax.random.split(step_key, n_envs), state, actions,
                                       params)
      return state, (reward.sum(), done.sum())
    return jax.lax.scan(body, state, jax.random.split(key, n_steps))[1]

  key = jax.random.PRNGKey(seed)
  begin = time.perf_counter()
  compiled = run.lower(key).compile()
  compile_s = time.perf_counter() - begin
  jax.block_until_ready(compiled(key))               # warm
  begin = time.perf_counter()
  jax.block_until_ready(compiled(jax.random.PRNGKey(seed + 1)))
  return n_envs * n_steps / (time.perf_counter() - begin), compile_s


def numba_steps_per_second(env_id, kwargs, n_envs, n_steps, seed=0):
  """Steps/s of the native vector environment (`gymnasium.make_vec`)."""
  import gymnasium

  import hpg_mj  # noqa: F401  (registers the ids)
  envs = gymnasium.make_vec("hpg_mj/" + env_id, num_envs=n_envs, **kwargs)
  envs.reset(seed=seed)
  rng = np.random.default_rng(seed)
  space = envs.action_space
  if hasattr(space, "nvec"):
    actions = rng.integers(0, space.nvec, (n_steps, n_envs))
  else:
    actions = rng.uniform(space.low, space.high, (n_steps, *space.shape))
  envs.step(actions[0])                               # compiled or loaded from the cache
  begin = time.perf_counter()
  for k in range(n_steps):
    envs.step(actions[k])
  return n_envs * n_steps / (time.perf_counter() - begin)


def main(argv=None):
  """Runs the benchmark with the arguments `argv` (the process's when None) and
  prints its table."""
  parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
  parser.add_argument("--envs", type=int, default=4096, help="episodes in the batch")
  parser.add_argument("--steps", type=int, default=1000, help="steps timed")
  parser.add_argument("--x64", action="store_true", help="JAX in float64")
  args = parser.parse_args(argv)
  if args.envs < 1 or args.steps < 1:
    parser.error(f"--envs and --steps must be positive, got {args.envs} and {args.steps}")
  import jax
  jax.config.update("jax_enable_x64", args.x64)
  print(f"{args.envs} environments x {args.steps} steps, JAX on {jax.devices()[0]} "
        f"({'float64' if args.x64 else 'float32'})")
  for task, (env_id, kwargs) in TASKS.items():
    jax_rate, compile_s = jax_steps_per_second(env_id, args.envs, args.steps)
    numba_rate = numba_steps_per_second(env_id, kwargs, args.envs, args.steps)
    print(f"{task:10s} JAX {jax_rate:13,.0f} steps/s (compiled in {compile_s:.1f} s)   "
          f"numba vector env {numba_rate:13,.0f} steps/s   x{jax_rate / numba_rate:.2f}")


if __name__ == "__main__":
  main()
