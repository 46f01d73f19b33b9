"""Time per control step of the RL policy next to the NMPCs (one closed-loop episode each).

Usage: ``python bench/policy_speed.py [--map map3] [--slip nominal]``
"""

from __future__ import annotations

import argparse

from nmpc_solve import closed_loop, line  # the same closed-loop runner and report line

import controllers
from koopman_envs.tasks.base import env_id_for_map


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--map", default="map3")
    parser.add_argument("--slip", default="nominal")
    args = parser.parse_args()
    env_id = env_id_for_map(args.map)
    print(f"{env_id} {args.map} slip={args.slip}: wall time of act() per control step")
    for name in ("rl-ppo", "koopman-nmpc", "nominal-nmpc", "consensus"):
        try:
            ctrl = controllers.make(name)
        except (ImportError, ValueError) as exc:
            print(f"{name:14s} skipped: {exc}")
            continue
        print(line(name, closed_loop(env_id, args.map, args.slip, lambda c=ctrl: c)))


if __name__ == "__main__":
    main()
