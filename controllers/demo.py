"""Run one episode with a controller, print its outcome and optionally save an animation.

``python -m controllers.demo --env KoopNav-Formation-v0 --map map3 --slip high
--controller koopman-nmpc --gif out.gif``
"""

from __future__ import annotations

import argparse
import json
from typing import TYPE_CHECKING, cast

import gymnasium as gym
import numpy as np

import controllers
import koopman_envs
from controllers.calibration import calibrate_controller
from koopman_envs import run_episode

if TYPE_CHECKING:  # pragma: no cover - typing only
    from koopman_envs import KoopNavEnv


def run_demo(
    env_id: str, map_name: str | None, slip: str, controller: str, seed: int, gif: str | None
) -> dict:
    """One closed-loop episode; returns a summary dict (and writes ``gif`` if given)."""
    env = gym.make(env_id, map=map_name, slip=slip, render_mode="rgb_array" if gif else None)
    ctrl = controllers.make(controller)
    calibrate_controller(ctrl, env)  # learns from the env's robots (slip hidden), cached on disk
    result = run_episode(env, ctrl, seed=seed, render=bool(gif))
    summary = {
        "env": env_id,
        # a KoopNav id's entry point is a KoopNavEnv (gym.make types it as any Env)
        "map": cast("KoopNavEnv", env.unwrapped).scenario.map_name,
        "slip": slip,
        "controller": controller,
        "seed": seed,
        "steps": result.steps,
        "success": result.success,
        "collision": result.collision or "none",
        "final_distance_cm": [round(100 * d, 2) for d in result.final_distance],
        **{k: (round(v, 3) if isinstance(v, float) else v) for k, v in ctrl.stats().summary().items()},
    }
    if gif:
        from koopman_envs import save_episode

        summary["gif"] = save_episode(result.frames, gif)
    return summary


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--env", default="KoopNav-Formation-v0", choices=koopman_envs.ENV_IDS)
    parser.add_argument("--map", default=None, help="map1..map8, random or a .json file")
    parser.add_argument("--slip", default="nominal", choices=list(koopman_envs.SLIP_SETTINGS))
    parser.add_argument("--controller", default="koopman-nmpc", choices=controllers.available())
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--gif", help="save the episode as an animated GIF")
    args = parser.parse_args(argv)
    summary = run_demo(args.env, args.map, args.slip, args.controller, args.seed, args.gif)
    print(json.dumps(summary, indent=1, default=lambda v: float(v) if isinstance(v, np.floating) else str(v)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
