"""Steps per second of the JAX worlds against the native (numba) vector environments,
or of the MuJoCo ship through MJX against MuJoCo and the analytic ship.

```bash
python -m hpg_mj.jax.bench [--envs 4096] [--steps 1000] [--x64] [--task current/hard ...]
python -m hpg_mj.jax.bench --mjx [--ships 1,64,1024,4096] [--steps 100] [--x64]
```

For each task (the ship, the taxi with fuel, the regatta and the harbour at their hard
level; or those `--task` names, any ladder world at any level among them), the same batch of `--envs` episodes under uniform random actions:
the JAX environment's `step` (gymnax's, with its auto-reset) vmapped over the batch
and scanned over `--steps` steps in one jitted call, timed after its compilation
(reported apart); and `gymnasium.make_vec(id, num_envs, ...)` stepped `--steps`
times from Python (hpg_mj.envs.vector: one compiled call a step). Both on the
devices JAX and numba find (the CPU here; JAX takes a GPU where jaxlib has one).

With `--mjx`, the ship's physics alone, no task, for each batch of `--ships` ships
sailing `--steps` controls (0.6 s) under uniform turning rates from random starts,
in ships x controls per second: `hpg_mj.jax.mjx_ship` (the steps scanned, the ships
vmapped, one jitted call, timed after its compilation); MuJoCo's C step on the same
model (`mujoco.rollout`, one thread, the profiler's clock stopped as the MuJoCo
backend stops it); and the analytic ship (`ship_core.euler_batch`, numba, one
thread).
"""
import argparse
import time

import numpy as np

# name -> (id, the native vector environment's arguments; a `level` goes to both).
TASKS = {"ship": ("hpg_mj/ShipSteering-v0", {"backend": "analytic"}),
         "taxi_fuel": ("hpg_mj/TaxiFuel-v0", {}),
         "regatta/hard": ("hpg_mj/ShipRegatta-v0", {"backend": "analytic", "level": "hard"}),
         "harbour/hard": ("hpg_mj/ShipHarbour-v0", {"backend": "analytic", "level": "hard"})}


def task(name):
  """(id, the native vector environment's arguments) of `--task NAME`: a name of
  TASKS, or a ladder world and level (`current/medium`, or as the scorer names it,
  `ship_current/medium`); a ValueError names what is allowed."""
  if name in TASKS:
    return TASKS[name]
  from hpg_mj.worlds.ship_ladder import ENV_IDS, LEVELS
  world, _, level = name.partition("/")
  # The short names (`current`) beside the scorer's (`ship_current`), one table.
  ids = {**{scorers.partition("_")[2]: env_id for scorers, env_id in ENV_IDS.items()},
         **ENV_IDS}
  if world not in ids or level not in LEVELS:
    raise ValueError(f"--task {name!r}: allowed ship, taxi_fuel, or WORLD/LEVEL with WORLD "
                     f"one of {', '.join(ids)} and LEVEL one of {', '.join(LEVELS)}")
  return ids[world], {"backend": "analytic", "level": level}


def jax_steps_per_second(env_id, n_envs, n_steps, seed=0, level=None):
  """(steps/s, compile seconds) of the vmapped, scanned JAX environment (at `level`,
  for the task ladder's)."""
  import jax

  from hpg_mj import jax as hpg_jax
  env, params = hpg_jax.make(env_id, level=level)
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
  envs = gymnasium.make_vec(env_id, num_envs=n_envs, **kwargs)
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


def _ship_batch(n_ships, n_steps, seed):
  """Starts (n_ships, 4) uniform over the field and turning rates (n_steps, n_ships)
  uniform in [-15, 15] deg/s."""
  from hpg_mj.worlds import ship_core as core
  rng = np.random.default_rng(seed)
  starts = np.column_stack([rng.uniform(0, 1000, n_ships), rng.uniform(0, 1000, n_ships),
                            rng.uniform(-180, 180, n_ships), rng.uniform(-15, 15, n_ships)])
  return starts, rng.uniform(-core.MAX_TURN_RATE, core.MAX_TURN_RATE, (n_steps, n_ships))


def mjx_ship_steps_per_second(n_ships, n_steps, seed=0):
  """(control steps/s, compile seconds) of the MJX ship, `n_ships` vmapped."""
  import jax

  from hpg_mj.jax import mjx_ship
  ship = mjx_ship.MjxShip()
  dtype = ship.model.opt.timestep.dtype
  starts, controls = (a.astype(dtype) for a in _ship_batch(n_ships, n_steps, seed))
  begin = time.perf_counter()
  compiled = jax.jit(ship.sail).lower(starts, controls).compile()
  compile_s = time.perf_counter() - begin
  jax.block_until_ready(compiled(starts, controls))      # warm
  starts, controls = (a.astype(dtype) for a in _ship_batch(n_ships, n_steps, seed + 1))
  begin = time.perf_counter()
  jax.block_until_ready(compiled(starts, controls))
  return n_ships * n_steps / (time.perf_counter() - begin), compile_s


# MuJoCo's thread steps the ships one after another, at a rate that a larger batch
# does not change: batches beyond this many are timed on this many (memory and time).
MUJOCO_MAX_SHIPS = 4096


def mujoco_ship_steps_per_second(n_ships, n_steps, seed=0, chunk=50):
  """Control steps/s of the MuJoCo ship's model under `mujoco.rollout` (one thread),
  `chunk` controls a call (its output holds every MuJoCo step's state), on at most
  MUJOCO_MAX_SHIPS of the ships."""
  import mujoco
  from mujoco import rollout

  from hpg_mj.worlds import ship_core as core
  from hpg_mj.worlds import ship_model
  physics = ship_model.ShipPhysics.from_xml_string(*ship_model.get_model_and_assets())
  model, data = physics.model.ptr, mujoco.MjData(physics.model.ptr)
  ship_model.stop_profiler_clock()      # after MjData's creation, as ShipPhysics does
  substeps = core.SAMPLES_PER_CONTROL * physics._substeps_per_sample()
  spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
  n_ships = min(n_ships, MUJOCO_MAX_SHIPS)
  starts, controls = _ship_batch(n_ships, n_steps, seed)
  state = np.empty((n_ships, mujoco.mj_stateSize(model, spec)))
  for i, start in enumerate(starts):          # as the MuJoCo backend sets a ship
    physics.set_ship_state(start)
    mujoco.mj_getState(model, physics.data.ptr, state[i], spec)
  # (controls, the states out) of each chunk's length, whole arrays: rollout writes
  # into no slice of a larger one.
  buffers = {}
  seconds = 0.0
  for k in range(0, n_steps, chunk):
    steps = min(chunk, n_steps - k) * substeps
    if steps not in buffers:              # the engine's control is unused
      buffers[steps] = (np.zeros((n_ships, steps, model.nu)),
                        np.empty((n_ships, steps, state.shape[1])))
    ctrl, out = buffers[steps]
    # Each control held for its MuJoCo steps on both rudders.
    ctrl[:, :, :2] = np.repeat(controls[k:k + chunk].T, substeps, axis=1)[:, :, None]
    begin = time.perf_counter()
    rollout.rollout(model, data, state, ctrl, state=out)
    seconds += time.perf_counter() - begin
    state = out[:, -1].copy()
  return n_ships * n_steps / seconds


def analytic_ship_steps_per_second(n_ships, n_steps, seed=0):
  """Control steps/s of the analytic ship (`ship_core.euler_batch`)."""
  from hpg_mj.worlds import ship_core as core
  starts, controls = _ship_batch(n_ships, n_steps, seed)
  samples = np.empty((n_ships, core.SAMPLES_PER_CONTROL + 1, 2))
  core.euler_batch(starts.copy(), controls[0], samples)   # compiled or loaded from the cache
  begin = time.perf_counter()
  for k in range(n_steps):
    core.euler_batch(starts, controls[k], samples)
  return n_ships * n_steps / (time.perf_counter() - begin)


def mjx_table(ships, n_steps):
  """Prints, for each batch size in `ships`, the three ships' control steps/s."""
  for n in ships:
    mjx_rate, compile_s = mjx_ship_steps_per_second(n, n_steps)
    mujoco_rate = mujoco_ship_steps_per_second(n, n_steps)
    analytic_rate = analytic_ship_steps_per_second(n, n_steps)
    mujoco_note = "*" if n > MUJOCO_MAX_SHIPS else " "
    print(f"{n:6d} ships  MJX {mjx_rate:12,.0f} (compiled in {compile_s:4.1f} s)   "
          f"MuJoCo {mujoco_rate:12,.0f}{mujoco_note}  analytic {analytic_rate:12,.0f}   "
          f"MJX/MuJoCo x{mjx_rate / mujoco_rate:.2f}", flush=True)
  if max(ships) > MUJOCO_MAX_SHIPS:
    print(f"* MuJoCo timed on {MUJOCO_MAX_SHIPS} of the ships (one thread: the same rate)")


def main(argv=None):
  """Runs the benchmark with the arguments `argv` (the process's when None) and
  prints its table."""
  parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
  parser.add_argument("--envs", type=int, default=4096, help="episodes in the batch")
  parser.add_argument("--steps", type=int, default=None,
                      help="steps timed (1000; with --mjx, 100 controls)")
  parser.add_argument("--x64", action="store_true", help="JAX in float64")
  parser.add_argument("--mjx", action="store_true",
                      help="the MuJoCo ship through MJX, MuJoCo and the analytic ship")
  parser.add_argument("--ships", default="1,64,1024,4096",
                      help="with --mjx: the batch sizes, comma-separated")
  parser.add_argument("--task", action="append", default=None, metavar="TASK",
                      help="only this task (repeatable): ship, taxi_fuel, or a ladder world "
                           "and level, such as current/medium or goal/hard (default: ship, "
                           "taxi_fuel, regatta/hard, harbour/hard)")
  args = parser.parse_args(argv)
  try:
    tasks = {name: task(name) for name in args.task or TASKS}
  except ValueError as error:
    parser.error(str(error))
  if args.mjx and args.task:
    parser.error("--task is for the environments' table; --mjx times the ship's physics alone")
  if args.steps is None:
    args.steps = 100 if args.mjx else 1000
  try:
    ships = [int(n) for n in args.ships.split(",")]
  except ValueError:
    parser.error(f"--ships takes batch sizes separated by commas, got {args.ships!r}")
  if args.envs < 1 or args.steps < 1 or min(ships) < 1:
    parser.error(f"--envs, --steps and --ships must be positive, got {args.envs}, "
                 f"{args.steps} and {args.ships}")
  import jax
  jax.config.update("jax_enable_x64", args.x64)
  if args.mjx:
    print(f"the ship's physics, ships x {args.steps} controls (0.6 s), control steps/s; "
          f"MJX on {jax.devices()[0]} ({'float64' if args.x64 else 'float32'}), MuJoCo "
          "(mujoco.rollout) and the analytic ship (numba) on one CPU thread")
    mjx_table(ships, args.steps)
    return
  print(f"{args.envs} environments x {args.steps} steps, JAX on {jax.devices()[0]} "
        f"({'float64' if args.x64 else 'float32'})")
  width = max(map(len, tasks))
  for name, (env_id, kwargs) in tasks.items():
    jax_rate, compile_s = jax_steps_per_second(env_id, args.envs, args.steps,
                                               level=kwargs.get("level"))
    numba_rate = numba_steps_per_second(env_id, kwargs, args.envs, args.steps)
    print(f"{name:{width}s} JAX {jax_rate:13,.0f} steps/s (compiled in {compile_s:.1f} s)   "
          f"numba vector env {numba_rate:13,.0f} steps/s   x{jax_rate / numba_rate:.2f}")


if __name__ == "__main__":
  main()
