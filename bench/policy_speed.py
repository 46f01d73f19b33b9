"""Time per control step of the RL policies next to the NMPCs and consensus.

Usage::

    python bench/policy_speed.py                      # paper map 3, one closed-loop episode each
    python bench/policy_speed.py --robots 16 32       # seeded random maps with N robots

The first form plays one episode of each controller on a paper map (``--map``, ``--slip``). The
second plays ``--seeds`` whole episodes of target reaching at nominal slip on the seeded random
maps of :mod:`scaling` (the same cells as the scaling table) for every team size, and prints the
median and p95 wall time of ``act()`` per control step (all robots, first step of an episode
left out) beside the distributed NMPC and consensus. Everything runs on one core: torch and the
BLAS libraries are held to one thread before they load.
"""

from __future__ import annotations

import os
import sys

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402

import numpy as np  # noqa: E402

# the sibling scripts by this file's folder, whatever the working directory or how it is started
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from nmpc_solve import closed_loop, line  # noqa: E402  (the same closed-loop runner and report line)
from scaling import run_cell  # noqa: E402  (the scaling table's cells)

import controllers  # noqa: E402
from koopman_envs import env_id_for_map  # noqa: E402

PAPER_MAP_CONTROLLERS = ("rl-ppo-set", "rl-ppo", "koopman-nmpc", "nominal-nmpc", "consensus")
TEAM_CONTROLLERS = ("rl-ppo-set", "rl-ppo", "consensus", "dmpc-nominal")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--map", default="map3")
    parser.add_argument("--slip", default="nominal")
    parser.add_argument("--robots", type=int, nargs="*", help="team sizes on random maps (second form)")
    parser.add_argument("--seeds", type=int, default=3, help="episodes per team size (second form)")
    parser.add_argument("--controllers", nargs="+", default=None)
    args = parser.parse_args()
    if not args.robots:
        env_id = env_id_for_map(args.map)
        print(f"{env_id} {args.map} slip={args.slip}: wall time of act() per control step")
        for name in args.controllers or PAPER_MAP_CONTROLLERS:
            try:
                ctrl = controllers.make(name)
            except (ImportError, ValueError) as exc:
                print(f"{name:14s} skipped: {exc}")
                continue
            print(line(name, closed_loop(env_id, args.map, args.slip, lambda c=ctrl: c)))
        return
    print(
        f"target reaching, nominal slip, random maps (seeds 0..{args.seeds - 1}): wall time of act() per "
        "control step [ms], all robots, one core"
    )
    print(f"{'controller':14s} {'N':>3s} {'median':>8s} {'p95':>8s} {'per robot':>9s} {'success':>8s}")
    for n in args.robots:
        for name in args.controllers or TEAM_CONTROLLERS:
            try:
                cell = run_cell(name, n, 600, args.seeds)
            except (ImportError, ValueError) as exc:
                print(f"{name:14s} {n:3d} skipped: {exc}")
                continue
            times = cell["times"]
            print(
                f"{name:14s} {n:3d} {np.median(times):8.3f} {np.percentile(times, 95):8.3f} "
                f"{np.median(times) / n:9.4f} {cell['won']:>4d}/{args.seeds:<3d}",
                flush=True,
            )


if __name__ == "__main__":
    main()
