"""What moving obstacles cost a step, and how the crowd libraries compare.

Usage::

    python bench/movers_speed.py [--seconds 1] [--repeats 3] [--envs 1024] [--crowd-envs 64] [--json out.json]

Target reaching on map1, 3 robots, random actions, each setting timed against the env without
movers in alternating windows (a change of the machine's load slows both alike):

* 8 ``"constant"`` movers at ``--envs`` environments (target: >= 0.5x the rate without), and
  the same movers observed exactly (``tracking=False``): what the people tracker costs;
* 8 ``"crowd"`` pedestrians (ORCA through pyrvo), oblivious and aware, at ``--crowd-envs``:
  the rate and the share of the step the crowd takes;
* the crowd models side by side on the same pedestrians (8 per environment in map1's arena
  with its obstacles, ``--crowd-envs`` environments, one period each): ORCA through pyrvo (what
  KoopNav uses), a social-force model compiled with numba written for this comparison (Helbing
  and Molnar's driving term and exponential repulsion from people and obstacles, all
  environments in one call) and, when importable, pysocialforce 1.1.2 (one simulator per
  environment; it is kept out of the project's environment: ``python -m venv
  --system-site-packages /tmp/psf && /tmp/psf/bin/pip install pysocialforce`` and run this
  script with ``/tmp/psf/bin/python``).

Each figure is the best of ``--repeats`` windows of ``--seconds``.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import sys
from pathlib import Path

import numpy as np
from numba import njit

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the sibling script's timing helpers
from env_throughput import REPEATS, _timed_pair, vector_runner  # noqa: E402

import koopman_envs  # noqa: E402
from koopman_envs import load_map  # noqa: E402
from koopman_envs.params import PARAMS  # noqa: E402
from koopman_envs.settings import MoverConfig  # noqa: E402
from koopman_envs.sim.movers.field import MoverField  # noqa: E402

ENV = "KoopNav-TargetReaching-v0"
PEDESTRIANS = 8


def _crowd_field(num_envs: int) -> MoverField:
    """``num_envs`` environments of map1 with 8 oblivious pedestrians each, after their reset."""
    spec = load_map("map1")
    field = MoverField(
        num_envs, MoverConfig(count=PEDESTRIANS, behaviour="crowd", speed=0.4), 3, PARAMS.dt, PARAMS.workspace
    )
    for k in range(num_envs):
        field.reset_env(k, np.random.default_rng(k), spec.obstacles, spec.starts, spec.targets, 0.2)
    return field


def orca_runner(num_envs: int) -> tuple:
    """``(step, reset)`` of KoopNav's crowd (the waypoint kernel's goals, then ORCA per env)."""
    field = _crowd_field(num_envs)
    rows = np.arange(num_envs, dtype=np.int64)
    robots = np.zeros((num_envs, 3, 3))

    def step(i: int) -> None:
        field.step(robots, robots, rows)

    return step, lambda: None


@njit(cache=True)
def _social_force_step(position, velocity, goal, speed, radius, obstacles, dt):  # pragma: no cover - compiled
    """One period of Helbing and Molnar's social force for every pedestrian of every environment:
    relaxation to the preferred velocity (tau 0.5 s), exponential repulsion from the others
    (A 2.1 m/s^2, B 0.3 m) and from the obstacles' surfaces (A 10 m/s^2, B 0.2 m), speed capped."""
    tau, a_people, b_people, a_wall, b_wall = 0.5, 2.1, 0.3, 10.0, 0.2
    n_envs, count = position.shape[0], position.shape[1]
    for k in range(n_envs):
        for c in range(count):
            x, y = position[k, c, 0], position[k, c, 1]
            dx, dy = goal[k, c, 0] - x, goal[k, c, 1] - y
            d = math.sqrt(dx * dx + dy * dy) + 1e-9
            fx = (speed * dx / d - velocity[k, c, 0]) / tau
            fy = (speed * dy / d - velocity[k, c, 1]) / tau
            for o in range(count):
                if o != c:
                    ox, oy = x - position[k, o, 0], y - position[k, o, 1]
                    dist = math.sqrt(ox * ox + oy * oy) + 1e-9
                    push = a_people * math.exp((2 * radius - dist) / b_people)
                    fx += push * ox / dist
                    fy += push * oy / dist
            for m in range(obstacles.shape[2]):  # (K, 3, M): rows x, y, radius
                ox, oy = x - obstacles[k, 0, m], y - obstacles[k, 1, m]
                dist = math.sqrt(ox * ox + oy * oy) + 1e-9
                push = a_wall * math.exp((radius + obstacles[k, 2, m] - dist) / b_wall)
                fx += push * ox / dist
                fy += push * oy / dist
            vx, vy = velocity[k, c, 0] + fx * dt, velocity[k, c, 1] + fy * dt
            v = math.sqrt(vx * vx + vy * vy)
            if v > 1.3 * speed:
                vx, vy = vx * 1.3 * speed / v, vy * 1.3 * speed / v
            velocity[k, c, 0], velocity[k, c, 1] = vx, vy
            position[k, c, 0], position[k, c, 1] = x + vx * dt, y + vy * dt


def social_force_runner(num_envs: int) -> tuple:
    """``(step, reset)`` of the compiled social-force kernel on the same pedestrians and goals."""
    field = _crowd_field(num_envs)
    position, velocity, goal = field.position.copy(), field.velocity.copy(), field.goal.copy()
    obstacles = field._obstacles

    def step(i: int) -> None:
        _social_force_step(position, velocity, goal, 0.4, 0.2, obstacles, PARAMS.dt)

    step(0)  # compile outside the timing
    return step, lambda: None


def pysocialforce_runner(num_envs: int) -> tuple | None:
    """``(step, reset)`` of pysocialforce (one simulator per environment), or None without it."""
    try:
        import pysocialforce as psf
    except ImportError:
        return None
    import logging

    logging.disable(
        logging.INFO
    )  # pysocialforce sets the root logger to DEBUG on import (and writes file.log)
    field = _crowd_field(num_envs)
    spec = load_map("map1")
    sides = 16
    angles = 2 * math.pi * np.arange(sides + 1) / sides
    lines = []
    for ox, oy, r in spec.obstacles:  # each round obstacle as the 16 sides of a polygon
        xs, ys = ox + r * np.cos(angles), oy + r * np.sin(angles)
        lines += [(xs[j], xs[j + 1], ys[j], ys[j + 1]) for j in range(sides)]
    sims = []
    for k in range(num_envs):
        state = np.hstack([field.position[k], np.zeros((PEDESTRIANS, 2)), field.goal[k]])
        sims.append(psf.Simulator(state, obstacles=lines))

    def step(i: int) -> None:
        for sim in sims:
            sim.step(1)

    return step, lambda: None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=1.0, help="length of one timing window")
    parser.add_argument("--repeats", type=int, default=REPEATS, help="windows per figure (best reported)")
    parser.add_argument(
        "--envs", type=int, default=1024, help="vector env size, constant movers (default 1024)"
    )
    parser.add_argument("--crowd-envs", type=int, default=64, help="environments for the crowd (default 64)")
    parser.add_argument("--json", help="also write the figures to this JSON file")
    args = parser.parse_args()
    timing, k, kc = (args.seconds, args.repeats), args.envs, args.crowd_envs
    print(
        f"KoopNav {koopman_envs.__version__}, numpy {np.__version__}, {platform.processor() or platform.machine()}"
    )
    results: dict[str, float | None] = {}
    constant = {"movers": {"count": 8}}
    plain, moving = (
        k * r for r in _timed_pair(vector_runner(ENV, k), vector_runner(ENV, k, **constant), *timing)
    )
    results.update({f"vector {k} plain": plain, f"vector {k} 8 constant movers": moving})
    print(f"vector env {k}, no movers          {plain:12,.0f} env-steps/s")
    print(
        f"vector env {k}, 8 constant movers  {moving:12,.0f} env-steps/s ({moving / plain:.2f}x without; target >= 0.5x)"
    )
    # the same movers observed exactly: what the people tracker (the default) costs
    exact = {"movers": {"count": 8, "tracking": False}}
    tracked, untracked = (
        k * r for r in _timed_pair(vector_runner(ENV, k, **constant), vector_runner(ENV, k, **exact), *timing)
    )
    results.update(
        {f"vector {k} 8 constant movers, tracked": tracked, f"vector {k} 8 constant movers, exact": untracked}
    )
    print(
        f"vector env {k}, 8 movers exact     {untracked:12,.0f} env-steps/s (the tracker costs "
        f"{1 - tracked / untracked:.0%} of the step)"
    )
    try:
        import pyrvo  # noqa: F401
    except ImportError:
        print("pyrvo not importable: pip install -e '.[crowd]' for the crowd figures")
        pyrvo = None
    if pyrvo is not None:
        for aware in (False, True):
            crowd = {"movers": {"count": PEDESTRIANS, "behaviour": "crowd", "aware": aware, "speed": 0.4}}
            plain, walking = (
                kc * r for r in _timed_pair(vector_runner(ENV, kc), vector_runner(ENV, kc, **crowd), *timing)
            )
            share = 1.0 - walking / plain  # of the step with the crowd, the part the crowd takes
            label = "aware" if aware else "oblivious"
            results.update({f"vector {kc} plain ({label})": plain, f"vector {kc} crowd {label}": walking})
            print(
                f"vector env {kc}, 8 pedestrians ({label}) {walking:10,.0f} env-steps/s "
                f"({walking / plain:.2f}x without; the crowd takes {100 * share:.0f}% of the step)"
            )
        orca, social = (kc * r for r in _timed_pair(orca_runner(kc), social_force_runner(kc), *timing))
        results.update({"crowd orca (pyrvo)": orca, "crowd social force (numba, ours)": social})
        print(f"crowd models, {kc} envs x 8 pedestrians, one period each:")
        print(f"  ORCA via pyrvo (KoopNav's)         {orca:12,.0f} env-steps/s")
        print(f"  social force, numba (comparison)   {social:12,.0f} env-steps/s ({social / orca:.1f}x ORCA)")
        runner = pysocialforce_runner(kc)
        if runner is None:
            results["crowd pysocialforce"] = None
            print("  pysocialforce not importable: see this script's docstring")
        else:
            orca, theirs = (kc * r for r in _timed_pair(orca_runner(kc), runner, *timing))
            results.update({"crowd orca (paired with pysocialforce)": orca, "crowd pysocialforce": theirs})
            print(
                f"  pysocialforce 1.1.2                {theirs:12,.0f} env-steps/s ({orca / theirs:.1f}x slower than ORCA)"
            )
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
