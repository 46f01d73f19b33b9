"""Draw the README's picture with the package's own renderer.

``python docs/make_figure.py --out docs/_static/formation_map3.png [--steps 300]``

Koopman-NMPC with widened margins (``koopman-nmpc-robust``) drives the formation task on Map 3
under high slip, seed 0; the env's ``rgb_array`` frame at the end of the episode (or after
``--steps`` control periods) shows the robots, their trails, targets and obstacles, saved as a PNG.
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import matplotlib

matplotlib.use("Agg")
import matplotlib.image

import controllers
import koopman_envs  # noqa: F401  (registers the ids)
from controllers.calibration import calibrate_controller
from evaluation.exit_codes import SUCCESS_EXIT
from koopman_envs.files import write_atomic


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--steps", type=int, default=300, help="at most this many control periods (the episode may end first)"
    )
    parser.add_argument("--controller", default="koopman-nmpc-robust")
    # no default: the picture is a tracked file, written only when named
    parser.add_argument("--out", required=True, help="the PNG to write (docs/_static/formation_map3.png)")
    args = parser.parse_args(argv)
    env = gym.make("KoopNav-Formation-v0", map="map3", slip="high", render_mode="rgb_array")
    ctrl = controllers.make(args.controller)
    calibrate_controller(ctrl, env)
    obs, info = env.reset(seed=0)
    ctrl.reset(env.unwrapped.scenario, seed=0)
    steps = 0
    while steps < args.steps:
        obs, _, terminated, truncated, info = env.step(ctrl.act(obs, info))
        steps += 1
        if terminated or truncated:
            break
    print(f"{args.controller}: {steps} steps, collision={info['collision']}, success={info['is_success']}")
    frame = env.render()
    write_atomic(args.out, lambda temporary: matplotlib.image.imsave(temporary, frame))
    env.close()
    print(args.out)
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
