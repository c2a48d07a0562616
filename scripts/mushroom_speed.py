"""Control steps per second of MushroomRL's ShipSteering (the paper's task as
MushroomRL ships it, `ShipSteering(small=False)`: the 1 km field, three 0.2 s
Euler steps a control step) against hpg_mj's analytic ship, stepped the same way,
in one run, interleaved round by round so that both see the same machine load.

    python scripts/mushroom_speed.py [--rounds 5] [--steps 100000]

Three measures, each over uniform random turning rates drawn beforehand, a new
episode whenever one ends: MushroomRL's `step` in a Python loop; hpg_mj's
`gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic")` in a Python loop
(Gymnasium's wrappers included, as a user meets it); and hpg_mj's native vector
environment (`gymnasium.make_vec`, 64 copies, one compiled call a step; counted
over all copies). Prints the median over rounds and each one's ratio to
MushroomRL's. MushroomRL is not a dependency of hpg_mj: `pip install mushroom-rl`
(its environments import OpenCV, pygame and scikit-learn). Its published 1.10.2
fails under numpy 2 at one line, which `mushroom` below works around.
"""
import argparse
import statistics
import time

import numpy as np


def mushroom(steps, seed):
  from mushroom_rl.environments.ship_steering import ShipSteering

  class Ship(ShipSteering):
    """MushroomRL's ship, its turning-rate bound returning a float: as published
    (1.10.2) it returns an array of one element, which numpy 2 refuses to store in
    the state (`ValueError: setting an array element with a sequence`). Nothing
    else differs."""

    @staticmethod
    def _bound(x, min_value, max_value):
      return np.asarray(np.maximum(min_value, np.minimum(x, max_value))).item()

  env = Ship(small=False)
  np.random.seed(seed)                                   # MushroomRL draws its starts here
  rates = np.random.default_rng(seed).uniform(-np.pi / 12, np.pi / 12, (steps, 1))
  env.reset()
  t, start = 0, time.perf_counter()
  for r in rates:
    _, _, absorbing, _ = env.step(r)
    t += 1
    if absorbing or t == env.info.horizon:
      env.reset()
      t = 0
  return steps / (time.perf_counter() - start)


def hpg_single(steps, seed):
  import gymnasium

  import hpg_mj  # noqa: F401
  env = gymnasium.make("hpg_mj/ShipSteering-v0", backend="analytic")
  rates = np.random.default_rng(seed).uniform(-15.0, 15.0, (steps, 1))
  env.reset(seed=seed)
  start = time.perf_counter()
  for r in rates:
    _, _, terminated, truncated, _ = env.step(r)
    if terminated or truncated:
      env.reset()
  return steps / (time.perf_counter() - start)


def hpg_vector(steps, seed, copies=64):
  import gymnasium

  import hpg_mj  # noqa: F401
  env = gymnasium.make_vec("hpg_mj/ShipSteering-v0", num_envs=copies, backend="analytic")
  rates = np.random.default_rng(seed).uniform(-15.0, 15.0, (steps // copies, copies, 1))
  env.reset(seed=seed)
  start = time.perf_counter()
  for r in rates:
    env.step(r)                                          # resets the copies that ended
  return len(rates) * copies / (time.perf_counter() - start)


MEASURES = {"MushroomRL ShipSteering": mushroom,
            "hpg_mj ShipSteering-v0": hpg_single,
            "hpg_mj make_vec, 64 copies": hpg_vector}


def main(argv=None):
  parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
  parser.add_argument("--rounds", type=int, default=5)
  parser.add_argument("--steps", type=int, default=100_000,
                      help="control steps per measurement (all copies together)")
  args = parser.parse_args(argv)
  for fn in MEASURES.values():                           # compiled and imported once first
    fn(2_000, 0)
  rates = {name: [] for name in MEASURES}
  for r in range(args.rounds):
    order = list(MEASURES) if r % 2 == 0 else list(MEASURES)[::-1]
    for name in order:
      rates[name].append(MEASURES[name](args.steps, r))
  base = statistics.median(rates["MushroomRL ShipSteering"])
  print(f"{args.rounds} interleaved rounds of {args.steps:,} control steps, median")
  for name, values in rates.items():
    median = statistics.median(values)
    print(f"{name:<28} {median:>12,.0f} control steps/s {median / base:>7.1f}x")


if __name__ == "__main__":
  main()
