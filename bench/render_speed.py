"""Rendering speed: frames per second of ``render_mode="rgb_array"``, new renderer beside the old one.

Usage::

    python bench/render_speed.py [--env KoopNav-Formation-v0] [--map map3] [--seconds 1] [--repeats 3]
                                 [--json out.json]

Records one episode (seed 0, the consensus controller with collision avoidance, at most 300
steps) and then, in the same process, times drawing its frames in order (growing trails, ticking clock):

* ``renderer (blit)``: :class:`koopman_envs.rendering.renderer.Renderer` as the envs use it: the static
  background is drawn once and kept as a bitmap, each frame redraws only the robots, trails and
  the clock;
* ``renderer (blit=False)``: the same artists, the whole figure drawn every frame (the reference
  the fast path is tested against in tests/test_rendering.py);
* ``old: clear + redraw``: the renderer before, reproduced here: per frame, clear the axes,
  create every artist again (:func:`~koopman_envs.rendering.renderer.draw_scenario`), ``tight_layout``
  and a full Agg draw;
* ``env.step + env.render``: the whole loop through ``gym.make`` with the new renderer.

Each figure is the best of ``--repeats`` windows of ``--seconds`` (other tenants of a shared
machine only ever slow a window down); the CPU time of the process per frame is printed beside
it, as waits for a core do not count there.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from collections.abc import Callable

import gymnasium as gym
import matplotlib
import numpy as np
from numpy.typing import NDArray

import koopman_envs
from controllers.consensus import ConsensusController
from koopman_envs.params import PARAMS
from koopman_envs.rendering.renderer import Renderer, draw_scenario, frame_title, title_parts
from koopman_envs.scenario import Scenario

REPEATS = 3  # timing windows per figure; the best is reported


def record_episode(env_id: str, map_name: str, steps: int = 300) -> tuple[gym.Env, NDArray, list[NDArray]]:
    """An episode of ``env_id`` on ``map_name`` (seed 0, at most ``steps`` steps) driven by the
    consensus controller with collision avoidance: the env, the actions and the poses."""
    env = gym.make(env_id, map=map_name, render_mode="rgb_array")
    controller = ConsensusController(collision_avoidance=True)
    obs, info = env.reset(seed=0)
    controller.reset(env.unwrapped.scenario, seed=0)
    poses, actions = [info["poses"]], []
    for _ in range(steps):
        actions.append(np.asarray(controller.act(obs, info), dtype=np.float32))
        obs, _, terminated, truncated, info = env.step(actions[-1])
        poses.append(info["poses"])
        if terminated or truncated:
            break
    return env, np.asarray(actions), poses


def best_rate(
    frame: Callable[[int], object], frames: int, seconds: float, repeats: int
) -> tuple[float, float]:
    """Best frames per second (wall clock) of ``frame(t)`` for t = 1, 2, ... (cycling through
    ``frames``), and the best CPU time of this process per frame [ms], which waits for a core
    on a shared machine do not inflate."""
    for t in range(1, 4):  # warm-up: figure creation and the first background
        frame(t)
    best, best_cpu = 0.0, float("inf")
    for _ in range(repeats):
        done, start, cpu = 0, time.perf_counter(), time.process_time()
        while True:
            frame(1 + done % frames)
            done += 1
            elapsed = time.perf_counter() - start
            if elapsed >= seconds:
                best = max(best, done / elapsed)
                best_cpu = min(best_cpu, 1e3 * (time.process_time() - cpu) / done)
                break
    return best, best_cpu


def old_full_redraw() -> Callable[[Scenario, NDArray, str], NDArray[np.uint8]]:
    """The renderer before the blitting one: every frame rebuilds and redraws the whole figure."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(5.0, 5.0), dpi=100)
    FigureCanvasAgg(figure)
    ax = figure.add_subplot(1, 1, 1)

    def draw(scenario: Scenario, trail: NDArray, title: str) -> NDArray[np.uint8]:
        draw_scenario(ax, scenario, trail, title)  # clears the axes, creates every artist again
        figure.tight_layout()
        figure.canvas.draw()
        return np.asarray(figure.canvas.buffer_rgba())[..., :3].copy()

    return draw


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--env", default="KoopNav-Formation-v0", choices=koopman_envs.ENV_IDS)
    parser.add_argument("--map", default="map3")
    parser.add_argument("--seconds", type=float, default=1.0, help="length of one timing window")
    parser.add_argument("--repeats", type=int, default=REPEATS, help="windows per figure (best reported)")
    parser.add_argument("--json", help="also write the figures to this JSON file")
    args = parser.parse_args()
    env, actions, poses = record_episode(args.env, args.map)
    scenario = env.unwrapped.scenario
    title = frame_title(env.unwrapped.config)
    trail = np.asarray(poses)
    frames = len(trail)
    print(
        f"KoopNav {koopman_envs.__version__}, matplotlib {matplotlib.__version__}, "
        f"{platform.processor() or platform.machine()}; {args.env} {args.map}, {frames} frames of 500x500"
    )

    def clock(t: int) -> float:
        return (t - 1) * PARAMS.dt

    fast, reference, old = Renderer(), Renderer(blit=False), old_full_redraw()
    contenders: dict[str, Callable[[int], object]] = {
        "renderer (blit)": lambda t: fast.draw(scenario, trail[:t], title, clock(t)),
        "renderer (blit=False)": lambda t: reference.draw(scenario, trail[:t], title, clock(t)),
        "old: clear + redraw": lambda t: old(scenario, trail[:t], "".join(title_parts(title, clock(t)))),
    }
    results: dict[str, dict[str, float]] = {}

    def report(name: str, frame: Callable[[int], object]) -> None:
        rate, cpu = best_rate(frame, frames, args.seconds, args.repeats)
        results[name] = {"frames_per_s": rate, "ms_per_frame": 1e3 / rate, "cpu_ms_per_frame": cpu}
        print(f"{name:28s} {rate:8.1f} frames/s  {1e3 / rate:7.2f} ms/frame  (CPU {cpu:6.2f} ms/frame)")

    for name, frame in contenders.items():
        report(name, frame)

    def env_frame(t: int) -> None:
        if t == 1:
            env.reset(seed=0)
        else:
            env.step(actions[t - 2])
        env.render()

    report("env.step + env.render", env_frame)
    speedup = results["renderer (blit)"]["frames_per_s"] / results["old: clear + redraw"]["frames_per_s"]
    print(f"speed-up of the renderer over the old redraw: {speedup:.1f}x")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(results, fh, indent=1)


if __name__ == "__main__":
    main()
