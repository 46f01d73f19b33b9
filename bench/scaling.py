"""Per-step decision time of the controllers as the team grows (seeded random maps).

Usage::

    python bench/scaling.py [--robots 3 6 10 16 24 32] [--seeds 20] [--controllers dmpc-nominal consensus]
    python bench/scaling.py --robots 3 5 8 --seeds 5 --controllers nominal-nmpc dmpc-nominal   # any configuration
    python bench/scaling.py --env KoopNav-Formation-v0 --controllers rl-ppo-set rl-ppo   # the formation task

For each team size N and controller configuration, the task (default target reaching) under
nominal slip on the seeded random maps of seeds 0..SEEDS-1 (4 obstacles; 24 robots and more
start and end in a grid, the default wedge does not fit them), whole episodes: success and
collision-free counts with the 95% Wilson interval of success, the mean final distance to the
target, the median and p95 decision time per step (all robots, one core; the first step of each
episode left out), and the time per robot: for the distributed NMPC the median solve time of one
robot, for the others the median step time divided by N. Koopman-NMPC is calibrated for N on
the env's calibration plant first (cached).
The central NMPCs beyond ~8 robots take seconds per step: give them few seeds (``--seeds``).
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import koopman_envs  # noqa: F401  (registers the envs)
from controllers.calibration import calibrate_controller
from evaluation.run.configs import parse_controller
from evaluation.stats.statistics import wilson_interval
from koopman_envs import run_episode

ENV_ID = "KoopNav-TargetReaching-v0"
ENV_IDS = ("KoopNav-TargetReaching-v0", "KoopNav-Formation-v0")


def run_cell(name: str, n_robots: int, steps: int, seeds: int, env_id: str = ENV_ID) -> dict:
    """``seeds`` episodes (seeds 0..seeds-1) of one controller configuration at team size N.

    Returns successes, collision-free runs, the per-step decision times [ms] of all episodes
    (the first step of each left out: it may build a solver's cold-start variant), the
    per-robot solve times of the distributed NMPC (empty for the others) and the outcomes.
    """
    # the default wedge formation of the random maps does not fit 24 or more robots in the
    # 20 x 20 m workspace: larger teams start and end in a grid
    layout = {"formation": "grid"} if n_robots >= 24 else None
    env = gym.make(env_id, map="random", n_robots=n_robots, max_episode_steps=steps, random_map=layout)
    ctrl = parse_controller(name).build()
    calibrate_controller(ctrl, env)
    won, free, times, robot, outcomes, final = 0, 0, [], [], [], []
    for seed in range(seeds):
        result = run_episode(env, ctrl, seed=seed)
        stats = ctrl.stats()
        won += bool(result.success)
        free += result.collision is None
        times += [1e3 * t for t in stats.solve_times[1:]]
        robot += [1e3 * t for t in stats.extra_times.get("robot", [])]
        outcomes.append(result.outcome)
        final.append(float(np.mean(result.final_distance)))
    return {
        "final": np.asarray(final),
        "won": won,
        "free": free,
        "times": np.asarray(times),
        "robot": np.asarray(robot),
        "outcomes": outcomes,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robots", type=int, nargs="+", default=[3, 6, 10, 16, 24, 32])
    parser.add_argument("--steps", type=int, default=600, help="time limit per episode (default: the env's)")
    parser.add_argument("--seeds", type=int, default=20, help="episodes per cell (seeds 0..SEEDS-1)")
    parser.add_argument("--controllers", nargs="+", default=["dmpc-nominal", "consensus"])
    parser.add_argument("--env", default=ENV_ID, choices=ENV_IDS)
    args = parser.parse_args()
    print(
        f"{args.env}, nominal slip, seeded random maps (seeds 0..{args.seeds - 1}), time limit {args.steps} periods; "
        "success k/n [95% Wilson]; final: mean distance to the target [m]; decision time per step [ms] "
        "(all robots, one core)"
    )
    width = max(14, *(len(name) for name in args.controllers))
    print(
        f"{'controller':{width}s} {'N':>3s} {'success':>18s} {'collision-free':>16s} {'final':>6s} {'median':>8s} "
        f"{'p95':>8s} {'per robot':>9s}"
    )
    for name in args.controllers:
        for n in args.robots:
            cell = run_cell(name, n, args.steps, args.seeds, args.env)
            times, robot = cell["times"], cell["robot"]
            low, high = wilson_interval(cell["won"], args.seeds)
            success = f"{cell['won']}/{args.seeds} [{100 * low:.0f}-{100 * high:.0f}%]"
            per_robot = np.median(robot) if robot.size else np.median(times) / n
            print(
                f"{name:{width}s} {n:3d} {success:>18s} {cell['free']:>8d}/{args.seeds:<7d} "
                f"{cell['final'].mean():6.2f} {np.median(times):8.2f} {np.percentile(times, 95):8.2f} {per_robot:9.2f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
