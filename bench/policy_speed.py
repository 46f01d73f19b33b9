"""Time per control step of the RL policy next to the NMPCs (one closed-loop episode each).

Usage: ``python bench/policy_speed.py [--map map3] [--slip nominal]``
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import controllers
import koopman_envs  # noqa: F401


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--map", default="map3")
    parser.add_argument("--slip", default="nominal")
    args = parser.parse_args()
    env_id = "KoopNav-Formation-v0" if args.map in ("map3", "map4") else "KoopNav-TargetReaching-v0"
    print(f"{env_id} {args.map} slip={args.slip}: wall time of act() per control step")
    for name in ("rl-ppo", "koopman-nmpc", "nominal-nmpc", "consensus"):
        try:
            ctrl = controllers.make(name, **({"slip": args.slip} if controllers.accepts_option(name, "slip") else {}))
        except (ImportError, ValueError) as exc:
            print(f"{name:14s} skipped: {exc}")
            continue
        env = gym.make(env_id, map=args.map, slip=args.slip)
        obs, info = env.reset(seed=0)
        ctrl.reset(env.unwrapped.scenario, seed=0)
        while True:
            obs, _, terminated, truncated, info = env.step(ctrl.act(obs, info))
            if terminated or truncated:
                break
        t = 1e3 * np.asarray(ctrl.stats().solve_times)
        outcome = "success" if info["is_success"] else info["collision_kind"] if info["collision"] else "time limit"
        print(f"{name:14s} median {np.median(t):8.3f} ms  p95 {np.percentile(t, 95):8.3f} ms  steps {len(t):4d}  {outcome}")


if __name__ == "__main__":
    main()
