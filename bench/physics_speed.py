"""Physics plant speed: env-steps/s of ``plant="mujoco"`` beside the kinematic plant, same run.

Usage::

    python bench/physics_speed.py [--seconds 2] [--repeats 3] [--envs 16] [--json out.json]

Prints, for 3 robots on the task's default map with random actions within the limits and auto
resets: the kinematic single env, the physics single env (one thread; every env-step is
``PHYSICS.substeps`` MuJoCo steps, printed too), and the physics vector env of ``--envs``
environments on 1 and on 2 threads (MuJoCo's rollout threads; the results are the same numbers
either way). Actions are drawn before timing. Each figure is the best of ``--repeats`` windows
of ``--seconds``; on a machine shared with other work the wall-clock figures move with its load,
so each is printed beside its rate per CPU-second of this process (``time.process_time``: the
time the process ran, which other work slows far less; for two threads it counts both).

Without MuJoCo it times nothing and exits 2 naming the install command; ``--repeats`` and
``--envs`` below 1 (``--envs``: below 2, a batch) are refused by name. ``--json`` is written
whole or not at all (:func:`~koopman_envs.files.write_atomic`).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import time
from collections.abc import Callable, Mapping
from typing import Any, cast

import gymnasium as gym
import numpy as np

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs.checks import check_int
from koopman_envs.files import write_atomic
from koopman_envs.params import INSTALL_HINT, PHYSICS

ENV_ID = "KoopNav-TargetReaching-v0"


def best_rate(step: Callable[[int], int], seconds: float, repeats: int) -> tuple[float, float]:
    """The best of ``repeats`` windows of ``seconds``: env-steps per wall-clock second and per
    CPU-second of ``step(i)``, which returns the env-steps it made."""
    for i in range(20):  # warm up (compilation, first resets)
        step(i)
    best, best_cpu = 0.0, 0.0
    for _ in range(repeats):
        done, start, cpu, i = 0, time.perf_counter(), time.process_time(), 0
        while (elapsed := time.perf_counter() - start) < seconds:
            done += step(i)
            i += 1
        best = max(best, done / elapsed)
        best_cpu = max(best_cpu, done / max(time.process_time() - cpu, 1e-9))
    return best, best_cpu


def single(plant: str, seconds: float, repeats: int) -> tuple[float, float]:
    """env-steps/s of one ``gym.make`` env of ``plant``."""
    env = gym.make(ENV_ID, plant=plant)
    env.reset(seed=0)
    box: Any = env.action_space  # a Box
    actions = np.random.default_rng(0).uniform(box.low, box.high, (512, 6))
    actions = actions.astype(np.float32)

    def step(i: int) -> int:
        _, _, terminated, truncated, _ = env.step(actions[i % 512])
        if terminated or truncated:
            env.reset()
        return 1

    rate = best_rate(step, seconds, repeats)
    env.close()
    return rate


def vector(num_envs: int, threads: int, seconds: float, repeats: int) -> tuple[float, float]:
    """env-steps/s of a physics vector env of ``num_envs`` on ``threads`` threads."""
    venv = gym.make_vec(ENV_ID, num_envs=num_envs, plant="mujoco")
    cast(Any, venv.unwrapped).engine.physics.threads = threads
    venv.reset(seed=0)
    space: Any = venv.action_space  # a Box
    actions = np.random.default_rng(0).uniform(space.low, space.high, (64, *space.shape)).astype(np.float32)

    def step(i: int) -> int:
        venv.step(actions[i % 64])
        return num_envs

    rate = best_rate(step, seconds, repeats)
    venv.close()
    return rate


def check_counts(
    parser: argparse.ArgumentParser, args: argparse.Namespace, minimums: Mapping[str, int]
) -> None:
    """End the command (``parser.error``, exit 2) naming the first option of ``minimums`` (its
    ``dest`` -> smallest allowed value) whose value is smaller, before any work."""
    for dest, minimum in minimums.items():
        try:
            check_int(f"--{dest.replace('_', '-')}", getattr(args, dest), minimum)
        except ValueError as exc:
            parser.error(str(exc))


def main(argv: list[str] | None = None) -> dict[str, tuple[float, float]]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0, help="length of a timing window [s]")
    parser.add_argument("--repeats", type=int, default=3, help="timing windows per figure (best kept)")
    parser.add_argument("--envs", type=int, default=16, help="environments of the vector env")
    parser.add_argument("--json", default=None, help="also write the figures to this JSON file")
    args = parser.parse_args(argv)
    # one env per batch would take the lone-env path (mj_step), not the threads the figure is of
    check_counts(parser, args, {"repeats": 1, "envs": 2})
    if not args.seconds > 0:
        parser.error(f"--seconds={args.seconds!r} must be a number > 0")
    if importlib.util.find_spec("mujoco") is None:
        # a speed run that timed nothing is a failure, not a success with an empty table
        parser.error(
            f"the physics plant needs mujoco, which is not installed: {INSTALL_HINT} (nothing timed)"
        )
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, load {load:.1f}")
    print(f"physics: {PHYSICS.timestep * 1e3:g} ms steps, {PHYSICS.substeps} per env-step; 3 robots")
    figures = {
        "kinematic single env": single("kinematic", args.seconds, args.repeats),
        "physics single env": single("mujoco", args.seconds, args.repeats),
    }
    for threads in (1, 2):
        figures[f"physics vector env, {args.envs} envs, {threads} thread(s)"] = vector(
            args.envs, threads, args.seconds, args.repeats
        )
    print(f"{'':45s} {'env-steps/s':>12s} {'per CPU-s':>10s} {'MuJoCo steps/s':>15s}")
    for name, (rate, cpu_rate) in figures.items():
        physics = f"{rate * PHYSICS.substeps:15,.0f}" if "physics" in name else ""
        print(f"{name:45s} {rate:12,.0f} {cpu_rate:10,.0f} {physics}")
    if args.json:
        write_atomic(args.json, json.dumps({"load": load, **figures}, indent=1))
    return figures


if __name__ == "__main__":
    main()
