"""Run one short episode and print what happened (a smoke test of an install).

``python -m koopman_envs.episodes.demo [--env ID] [--map NAME] [--slip NAME] [--n-robots N] [--formation SHAPE] [--gif PATH]``

The robots are driven by a deliberately naive go-to-target rule (turn toward the target, drive
when roughly facing it), which ignores obstacles and other robots: it shows the environment,
not a controller worth comparing. The controllers live in the ``controllers`` package.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from koopman_envs.episodes.single import run_episode
from koopman_envs.params import PARAMS
from koopman_envs.sim.formations import FORMATION_SHAPES
from koopman_envs.tasks.base import ENV_IDS

if TYPE_CHECKING:  # pragma: no cover - typing only
    from koopman_envs.fronts.gym_env import KoopNavEnv


def naive_command(poses: NDArray[np.float64], targets: NDArray[np.float64]) -> NDArray[np.float64]:
    """Turn toward each target and drive when facing it; (N, 2) commands."""
    delta = targets[:, :2] - poses[:, :2]
    bearing = np.arctan2(delta[:, 1], delta[:, 0]) - poses[:, 2]
    bearing = (bearing + np.pi) % (2 * np.pi) - np.pi
    distance = np.linalg.norm(delta, axis=1)
    v = np.clip(0.8 * distance, 0, PARAMS.v_max) * np.maximum(np.cos(bearing), 0.0)
    return np.column_stack([v, 2.0 * bearing])


class NaiveGoToTarget:
    """The demo's policy: :func:`naive_command` on the true poses in ``info``."""

    def act(self, observation: NDArray[np.float64], info: dict[str, Any]) -> NDArray[np.float64]:
        return naive_command(info["poses"], info["targets"]).reshape(-1)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m koopman_envs.episodes.demo", description=__doc__.split("\n")[0]
    )
    parser.add_argument("--env", default="KoopNav-TargetReaching-v0", choices=ENV_IDS)
    parser.add_argument("--map", default=None, help="map1..map8, random, or a .json file")
    parser.add_argument("--slip", default="nominal", help="nominal, low, high, random or drift")
    parser.add_argument(
        "--n-robots", type=int, default=PARAMS.n_robots, help="team size (6 for map7 and map8)"
    )
    parser.add_argument(
        "--formation", default=None, choices=FORMATION_SHAPES, help="formation shape of the team"
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--gif", help="save the episode as an animated GIF")
    args = parser.parse_args(argv)
    env = gym.make(
        args.env,
        map=args.map,
        slip=args.slip,
        n_robots=args.n_robots,
        formation=args.formation,
        render_mode="rgb_array" if args.gif else None,
    )
    result = run_episode(env, NaiveGoToTarget(), seed=args.seed, render=bool(args.gif))
    scenario = cast("KoopNavEnv", env.unwrapped).scenario  # an id of ENV_IDS makes a KoopNavEnv
    outcome = f"collision ({result.collision})" if result.collision else result.outcome
    print(f"{args.env} map={scenario.map_name} slip={args.slip} seed={args.seed}")
    print(
        f"  {result.steps} steps ({result.steps * scenario.dt:.1f} s), return {result.total_reward:.2f}, "
        f"outcome: {outcome}"
    )
    print("  final distance to target [cm]: " + ", ".join(f"{100 * d:.1f}" for d in result.final_distance))
    if args.gif:
        from koopman_envs.rendering.renderer import save_episode

        print(f"  saved {save_episode(result.frames, args.gif)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
