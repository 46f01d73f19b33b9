"""Per-step decision time of the controllers as the team grows (seeded random maps).

Usage::

    python bench/scaling.py [--robots 3 5 8 12] [--steps 60] [--controllers nominal-nmpc koopman-nmpc consensus]
    python bench/scaling.py --controllers nominal-nmpc nominal-nmpc:solver=fatrop   # any evaluator configuration

For each team size N, target reaching on the seeded random map of seed 0 (4 obstacles, the
random-map generator's defaults) runs ``--steps`` control periods with each controller in its
default setup (NMPCs: IPOPT, compiled and cached unless ``KOOPNAV_NMPC_JIT=0``; a structure not
yet compiled runs uncompiled while it compiles in the background, so run twice for the compiled
figures) and prints the median and p95 decision time per step, how they grow from the smallest
N, and the outcome so far. Koopman-NMPC is calibrated for N on the env's calibration plant first
(the fit is cached on disk; beyond 3 robots it fits the per-robot structure).
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import koopman_envs  # noqa: F401  (registers the envs)
from controllers.calibration import calibrate_controller
from evaluation.configs import parse_controller
from koopman_envs.episode import run_episode

ENV_ID = "KoopNav-TargetReaching-v0"


def step_times(name: str, n_robots: int, steps: int, seed: int = 0) -> tuple[np.ndarray, str]:
    """Decision times [ms] over one episode cut at ``steps`` periods, and its outcome.

    ``name``: a controller configuration as the evaluator takes it (``name:key=value,...``).
    """
    env = gym.make(ENV_ID, map="random", n_robots=n_robots, max_episode_steps=steps)
    ctrl = parse_controller(name).build()
    calibrate_controller(ctrl, env)
    result = run_episode(env, ctrl, seed=seed)
    # the first step may build the solver's cold-start variant: not a steady-state figure
    times = 1e3 * np.asarray(ctrl.stats().solve_times[1:])
    return times, result.outcome


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robots", type=int, nargs="+", default=[3, 5, 8, 12])
    parser.add_argument("--steps", type=int, default=60)
    parser.add_argument("--controllers", nargs="+", default=["nominal-nmpc", "koopman-nmpc", "consensus"])
    args = parser.parse_args()
    print(f"{ENV_ID}, random map of seed 0, {args.steps} steps per run; decision time per step [ms]")
    width = max(14, *(len(name) for name in args.controllers))
    print(
        f"{'controller':{width}s} {'N':>3s} {'median':>8s} {'p95':>8s} {'x median':>9s} {'x p95':>7s}  outcome"
    )
    for name in args.controllers:
        base = None
        for n in args.robots:
            times, outcome = step_times(name, n, args.steps)
            median, p95 = float(np.median(times)), float(np.percentile(times, 95))
            base = base or (median, p95)
            print(
                f"{name:{width}s} {n:3d} {median:8.2f} {p95:8.2f} {median / base[0]:9.1f} {p95 / base[1]:7.1f}  {outcome}",
                flush=True,
            )


if __name__ == "__main__":
    main()
