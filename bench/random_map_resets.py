"""Random-map resets for every team size: which shape the team takes and the time per reset.

Usage::

    python bench/random_map_resets.py                     # N = 2..64, 20 seeds, both tasks
    python bench/random_map_resets.py --robots 20 21 24 --seeds 50

For each task and team size it makes the env with ``map="random"`` and the default settings, resets
it once (compiles and caches), then times ``--seeds`` resets (seeds 0..S-1) and prints the formation
shape of the layout (:meth:`koopman_envs.sim.maps.generator.RandomMapConfig.shape_for`: the wedge while it
fits the workspace, the grid beyond), the share of the generator's draws that place that shape (the
fit rule's measure: at least 0.2%) and the mean and slowest reset [ms]. Every reset must succeed; a
failure is printed and the script exits 1.
"""

from __future__ import annotations

import argparse
import sys
import time

import gymnasium as gym

import koopman_envs  # noqa: F401 - registers the ids

TASKS = ("KoopNav-TargetReaching-v0", "KoopNav-Formation-v0")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robots", type=int, nargs="+", default=list(range(2, 65)))
    parser.add_argument("--seeds", type=int, default=20)
    args = parser.parse_args()
    print(f"map='random', default settings, seeds 0..{args.seeds - 1}; reset time [ms]: mean / slowest")
    print(f"{'task':26s} {'N':>3s}  {'shape':6s} {'placed':>8s} {'mean':>7s} {'max':>7s}")
    failures = 0
    for env_id in TASKS:
        for n in args.robots:
            env = gym.make(env_id, map="random", n_robots=n)
            config = env.unwrapped.config.random_map  # type: ignore[attr-defined]
            shape = config.shape_for(n)
            share = config.placement_share(shape, n)
            env.reset(seed=0)
            times = []
            for seed in range(args.seeds):
                start = time.perf_counter()
                try:
                    env.reset(seed=seed)
                except RuntimeError as exc:
                    failures += 1
                    print(f"{env_id} N={n} seed {seed}: {exc}")
                    continue
                times.append(time.perf_counter() - start)
            env.close()
            mean = 1e3 * sum(times) / max(len(times), 1)
            print(
                f"{env_id:26s} {n:3d}  {shape:6s} {100 * share:7.2f}% {mean:7.2f} {1e3 * max(times, default=0):7.2f}",
                flush=True,
            )
    print("every reset succeeded" if not failures else f"{failures} reset(s) failed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
