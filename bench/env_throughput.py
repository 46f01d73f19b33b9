"""Environment throughput: steps per second of the single env and the native vector env.

Usage::

    python bench/env_throughput.py [--seconds 1] [--repeats 3] [--json out.json]

Prints steps/s for ``gym.make`` (3 robots, random actions in the actuation limits, auto reset),
the vector env at 1, 64 and 1024 envs (env-steps/s), and, when ``mpe2`` is installed,
PettingZoo MPE2 ``simple_spread_v3`` (3 agents, continuous random actions) in the same run, its
windows alternating with each task's single env (the ratio printed at the end).
Beside the fixed map (the task's default) it times the same map with two slip zones added (a
``replace`` circle and an ``add`` rectangle on the route, single env and 1024 envs), random maps
(1024 envs, a new layout per reset) and random maps with two slip zones each.
Random actions are drawn before timing for every contender alike, so only environment time is
measured. Each figure is the best of ``--repeats`` timing windows, timed by the wall clock or,
with ``--clock cpu``, by this process's CPU time (other tenants of a shared machine stretch the
wall time of a window, not its CPU time; caches and a shared core's other thread still slow it).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import gymnasium as gym
import numpy as np

import koopman_envs
from koopman_envs import MapSpec, load_map, task_for_env

REPEATS = 3  # timing windows per figure; the best is reported
#: the clock a window is timed by (``--clock``)
CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}
_clock = CLOCKS["wall"]


def two_zone_map(env_id: str) -> MapSpec:
    """The task's default map with two slip zones across its route: a circle that replaces the
    slip mean midway and a rectangle that adds to it near the starts."""
    spec = load_map(task_for_env(env_id).default_map)
    mid = (spec.starts[:, :2].mean(axis=0) + spec.targets[:, :2].mean(axis=0)) / 2
    x0, y0 = spec.starts[:, :2].min(axis=0) - 0.5
    x1, y1 = spec.starts[:, :2].max(axis=0) + 0.5
    zones = [
        {"circle": [float(mid[0]), float(mid[1]), 1.5], "lambda": 0.3, "mode": "replace"},
        {"rect": [float(x0), float(y0), float(x1) + 1.0, float(y1)], "lambda": 0.1, "mode": "add"},
    ]
    return MapSpec(f"{spec.name}+2 zones", spec.obstacles, spec.starts, spec.targets, slip_zones=zones)


class _Contender:
    """One thing to time: ``step(i)`` and its ``reset()``, with the best rate seen so far."""

    def __init__(self, step, reset) -> None:
        self.step, self.count, self.best = step, 0, 0.0
        reset()
        for i in range(50):
            step(i)

    def window(self, seconds: float) -> None:
        done, start = 0, _clock()
        while True:
            for i in range(500):
                self.step(self.count + i)
            self.count += 500
            done += 500
            elapsed = _clock() - start
            if elapsed >= seconds:
                self.best = max(self.best, done / elapsed)
                return


def _timed(step, reset, seconds: float, repeats: int = REPEATS) -> float:
    """Best steps per second of ``step(i)`` over ``repeats`` windows of ``seconds`` each.

    The best window, not the mean: on a shared machine, other tenants only ever slow a window
    down, so the fastest one is the closest to what the code itself costs.
    """
    contender = _Contender(step, reset)
    for _ in range(repeats):
        contender.window(seconds)
    return contender.best


def _timed_together(*runners: tuple, seconds: float, repeats: int = REPEATS) -> list[float]:
    """Best steps per second of each ``(step, reset)`` contender, their windows taken in turn, so
    that a change of the machine's load during the run slows them alike and their ratios hold."""
    contenders = [_Contender(*runner) for runner in runners]
    for _ in range(repeats):
        for contender in contenders:
            contender.window(seconds)
    return [contender.best for contender in contenders]


def _timed_pair(a: tuple, b: tuple, seconds: float, repeats: int = REPEATS) -> tuple[float, float]:
    """:func:`_timed_together` of two contenders."""
    first, second = _timed_together(a, b, seconds=seconds, repeats=repeats)
    return first, second


def single_runner(env_id: str, **kwargs) -> tuple:
    """``(step, reset)`` of ``gym.make(env_id, **kwargs)`` with random actions and auto reset."""
    env = gym.make(env_id, **kwargs)
    actions = np.random.default_rng(0).uniform(-1, 1, (4096, 6)).astype(np.float32) * env.action_space.high

    def step(i: int) -> None:
        _, _, terminated, truncated, _ = env.step(actions[i & 4095])
        if terminated or truncated:
            env.reset()

    return step, lambda: env.reset(seed=0)


def vector_runner(env_id: str, num_envs: int, **kwargs) -> tuple:
    """``(step, reset)`` of the native vector env (``map="random"``: a new seeded layout per reset)."""
    venv = gym.make_vec(env_id, num_envs=num_envs, **kwargs)
    high = venv.single_action_space.high
    actions = np.random.default_rng(0).uniform(-1, 1, (64, num_envs, 6)).astype(np.float32) * high

    def step(i: int) -> None:
        venv.step(actions[i & 63])

    return step, lambda: venv.reset(seed=0)


def bench_single(env_id: str, seconds: float, repeats: int = REPEATS, **kwargs) -> float:
    """Steps/s of the single env."""
    return _timed(*single_runner(env_id, **kwargs), seconds, repeats)


def bench_vector(env_id: str, num_envs: int, seconds: float, repeats: int = REPEATS, **kwargs) -> float:
    """Env-steps/s of the native vector env."""
    return _timed(*vector_runner(env_id, num_envs, **kwargs), seconds, repeats) * num_envs


def mpe2_runner() -> tuple | None:
    """``(step, reset)`` of PettingZoo MPE2 ``simple_spread_v3`` (3 agents, continuous random
    actions), None when ``mpe2`` is not installed."""
    try:
        from mpe2 import simple_spread_v3
    except ImportError:
        return None
    env = simple_spread_v3.parallel_env(N=3, continuous_actions=True, max_cycles=10**9)
    env.reset(seed=0)
    space = env.action_space(env.agents[0])
    rng = np.random.default_rng(0)
    table = rng.uniform(space.low, space.high, (4096, len(env.agents), space.shape[0])).astype(np.float32)
    agents = list(env.agents)

    def step(i: int) -> None:
        row = table[i & 4095]
        env.step({a: row[k] for k, a in enumerate(agents)})
        if not env.agents:
            env.reset()

    return step, lambda: env.reset(seed=0)


def bench_mpe2(seconds: float, repeats: int = REPEATS) -> float | None:
    """Steps/s of MPE2 ``simple_spread_v3`` alone (None without ``mpe2``)."""
    runner = mpe2_runner()
    return None if runner is None else _timed(*runner, seconds, repeats)


def measure_task(env_id: str, seconds: float, repeats: int) -> tuple[dict[str, float], float | None]:
    """One task's figures (keyed as the JSON names them, without the task) and MPE2's rate timed
    beside its single env (None without mpe2)."""
    zoned = two_zone_map(env_id)
    timing = (seconds, repeats)
    # the single env's windows alternate with the same env on the zoned map and with MPE2's,
    # so that their ratios hold however the machine's load changes during the run
    runners = [single_runner(env_id), single_runner(env_id, map=zoned)]
    mpe = mpe2_runner()
    rates = _timed_together(*runners, *([] if mpe is None else [mpe]), seconds=seconds, repeats=repeats)
    figures = {"single": rates[0], "single two slip zones": rates[1]}
    for k in (1, 64):
        figures[f"vector {k}"] = bench_vector(env_id, k, seconds, repeats)
    # each comparison alternates its two contenders' windows (see _timed_pair)
    pair = _timed_pair(vector_runner(env_id, 1024), vector_runner(env_id, 1024, map=zoned), *timing)
    figures["vector 1024"], figures["vector 1024 two slip zones"] = (1024 * r for r in pair)
    # the setting RL training uses: a new random layout at every reset, without and with zones
    plain = vector_runner(env_id, 1024, map="random")
    with_zones = vector_runner(env_id, 1024, map="random", random_map={"n_slip_zones": 2})
    random_pair = _timed_pair(plain, with_zones, *timing)
    figures["vector 1024 random maps"], figures["vector 1024 random maps two slip zones"] = (
        1024 * r for r in random_pair
    )
    return figures, None if mpe is None else rates[2]


def print_task(env_id: str, figures: dict[str, float]) -> None:
    """One task's lines, from :func:`measure_task`'s figures."""
    rate, zones = figures["single"], figures["single two slip zones"]
    print(f"{env_id:28s} gym.make single env      {rate:12,.0f} steps/s")
    print(f"{env_id:28s} single, two slip zones   {zones:12,.0f} steps/s ({zones / rate:.2f}x the fixed map)")
    for k in (1, 64):
        print(f"{env_id:28s} make_vec num_envs={k:<5d}   {figures[f'vector {k}']:12,.0f} env-steps/s")
    fixed, zones = figures["vector 1024"], figures["vector 1024 two slip zones"]
    print(f"{env_id:28s} make_vec num_envs=1024    {fixed:12,.0f} env-steps/s")
    print(
        f"{env_id:28s} make_vec 1024, two zones {zones:12,.0f} env-steps/s "
        f"({zones / fixed:.2f}x the fixed map)"
    )
    rate, zones = figures["vector 1024 random maps"], figures["vector 1024 random maps two slip zones"]
    print(
        f"{env_id:28s} make_vec 1024, map=random {rate:12,.0f} env-steps/s "
        f"({rate / fixed:.2f}x the fixed map)"
    )
    print(
        f"{env_id:28s} 1024, random + 2 zones   {zones:12,.0f} env-steps/s "
        f"({zones / rate:.2f}x random maps without zones)"
    )


def print_mpe(results: dict[str, float | None], mpe_rates: dict[str, float]) -> None:
    """MPE2's simple_spread_v3 beside every task (or why not), its figures added to ``results``."""
    if not mpe_rates:
        results["mpe2 simple_spread_v3"] = None
        print("mpe2 not installed: `pip install mpe2` to compare against simple_spread_v3")
        return
    first = koopman_envs.ENV_IDS[0]
    results["mpe2 simple_spread_v3"] = mpe_rates[first]
    for env_id, mpe_rate in mpe_rates.items():
        results[f"mpe2 simple_spread_v3 beside {env_id}"] = mpe_rate
        print(f"{env_id:28s} beside it: MPE2 simple_spread_v3 (3 agents) {mpe_rate:12,.0f} steps/s")
    ratios = ", ".join(
        f"{env_id} {results[f'{env_id} single'] / mpe_rate:.2f}x" for env_id, mpe_rate in mpe_rates.items()
    )
    ours = results[f"{first} single"]
    print(
        f"ratio KoopNav single / simple_spread: {ours / mpe_rates[first]:.2f}x ({ratios}; windows alternating)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=1.0, help="length of one timing window")
    parser.add_argument("--repeats", type=int, default=REPEATS, help="windows per figure (best reported)")
    parser.add_argument("--json", help="also write the figures to this JSON file")
    parser.add_argument(
        "--clock",
        choices=sorted(CLOCKS),
        default="wall",
        help="time the windows by the wall clock or CPU time",
    )
    args = parser.parse_args()
    global _clock
    _clock = CLOCKS[args.clock]
    results: dict[str, float | None] = {}
    print(
        f"KoopNav {koopman_envs.__version__}, numpy {np.__version__}, {platform.processor() or platform.machine()}, "
        f"{args.clock} clock, load average {os.getloadavg()[0]:.1f}"
    )
    mpe_rates: dict[str, float] = {}
    for env_id in koopman_envs.ENV_IDS:
        figures, mpe_rate = measure_task(env_id, args.seconds, args.repeats)
        results.update({f"{env_id} {key}": value for key, value in figures.items()})
        if mpe_rate is not None:
            mpe_rates[env_id] = mpe_rate
        print_task(env_id, figures)
    print_mpe(results, mpe_rates)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(results, fh, indent=1)


if __name__ == "__main__":
    main()
