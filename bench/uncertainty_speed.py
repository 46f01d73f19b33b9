"""What runtime uncertainty costs a step: lidar, pose noise, radio and actuation delay, beside VMAS.

Usage::

    python bench/uncertainty_speed.py [--seconds 1] [--repeats 3] [--envs 1024] [--json out.json]

Target reaching on map1, 3 robots, random actions. Each setting is timed against the plain
state observation with alternating windows (a change of the machine's load slows both alike):

* ``sensing="lidar"`` with 32 exact beams (360 deg, 5 m), single env and vector env (target:
  >= 0.5x), and the same with reading noise and dropouts (2 cm, 2%: two random draws per beam);
* ``pose_noise``, ``comm`` and ``actuation_delay`` at the ``harsh`` preset's values, with the
  slip unchanged (target: <= 10% of the step at 1024 envs, i.e. >= 0.9x);
* when ``vmas`` is importable, VMAS 1.5.2's ``navigation`` scenario (3 agents, its lidar with
  32 rays like ours, CPU, the same number of envs) in the same run. VMAS needs torch; keep it out of the project's
  environment with ``python -m venv --system-site-packages /tmp/vmas && /tmp/vmas/bin/pip install
  vmas==1.5.2`` and run this script with ``/tmp/vmas/bin/python``.

Each figure is the best of ``--repeats`` windows of ``--seconds``.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the sibling script's timing helpers
from env_throughput import REPEATS, _timed_pair, single_runner, vector_runner  # noqa: E402

import koopman_envs  # noqa: E402
from koopman_envs.settings import UNCERTAINTY_PRESETS  # noqa: E402

ENV = "KoopNav-TargetReaching-v0"
LIDAR = {"sensing": "lidar", "lidar": {"beams": 32, "range": 5.0}}
NOISY_LIDAR = {"sensing": "lidar", "lidar": {"beams": 32, "range": 5.0, "noise": 0.02, "dropout": 0.02}}
_HARSH = UNCERTAINTY_PRESETS["harsh"]
FAULTS = {
    "pose_noise": _HARSH.pose_noise.__dict__,
    "comm": {"latency": _HARSH.comm.latency, "drop": _HARSH.comm.drop, "range": _HARSH.comm.range},
    "actuation_delay": _HARSH.actuation_delay,
}


def vmas_runner(num_envs: int) -> tuple | None:
    """``(step, reset)`` of VMAS's navigation scenario on CPU (3 agents, lidar), or None without vmas."""
    try:
        import torch
        import vmas
    except ImportError:
        return None
    torch.set_num_threads(1)  # as KoopNav's compiled step: one core
    env = vmas.make_env(
        "navigation",
        num_envs=num_envs,
        device="cpu",
        continuous_actions=True,
        n_agents=3,
        n_lidar_rays=32,  # as KoopNav's (VMAS's default is 12)
        seed=0,
    )
    generator = torch.Generator().manual_seed(0)
    table = [[torch.rand((num_envs, 2), generator=generator) * 2 - 1 for _ in range(3)] for _ in range(64)]

    def step(i: int) -> None:
        env.step(table[i & 63])

    return step, lambda: env.reset()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=1.0, help="length of one timing window")
    parser.add_argument("--repeats", type=int, default=REPEATS, help="windows per figure (best reported)")
    parser.add_argument("--envs", type=int, default=1024, help="vector env size (default 1024)")
    parser.add_argument("--json", help="also write the figures to this JSON file")
    args = parser.parse_args()
    timing, k = (args.seconds, args.repeats), args.envs
    print(
        f"KoopNav {koopman_envs.__version__}, numpy {np.__version__}, {platform.processor() or platform.machine()}"
    )
    results: dict[str, float | None] = {}
    state, lidar = _timed_pair(single_runner(ENV), single_runner(ENV, **LIDAR), *timing)
    results.update({"single state": state, "single lidar32": lidar})
    print(f"single env, state observation      {state:12,.0f} steps/s")
    print(
        f"single env, lidar 32 beams         {lidar:12,.0f} steps/s ({lidar / state:.2f}x state; target >= 0.5x)"
    )
    state, lidar = (
        k * r for r in _timed_pair(vector_runner(ENV, k), vector_runner(ENV, k, **LIDAR), *timing)
    )
    results.update({f"vector {k} state": state, f"vector {k} lidar32": lidar})
    print(f"vector env {k}, state observation {state:12,.0f} env-steps/s")
    print(
        f"vector env {k}, lidar 32 beams    {lidar:12,.0f} env-steps/s ({lidar / state:.2f}x state; target >= 0.5x)"
    )
    exact, noisy = (
        k * r
        for r in _timed_pair(vector_runner(ENV, k, **LIDAR), vector_runner(ENV, k, **NOISY_LIDAR), *timing)
    )
    results.update(
        {f"vector {k} lidar32 (paired with noisy)": exact, f"vector {k} lidar32 noise+dropout": noisy}
    )
    print(
        f"vector env {k}, lidar, noise+dropout {noisy:12,.0f} env-steps/s ({noisy / exact:.2f}x exact lidar)"
    )
    plain, faults = (
        k * r for r in _timed_pair(vector_runner(ENV, k), vector_runner(ENV, k, **FAULTS), *timing)
    )
    results.update({f"vector {k} plain": plain, f"vector {k} noise+comm+delay": faults})
    print(
        f"vector env {k}, noise+comm+delay  {faults:12,.0f} env-steps/s ({faults / plain:.2f}x without; "
        f"cost {100 * (plain / faults - 1):.0f}% of the step, target <= 10%)"
    )
    runner = vmas_runner(k)
    if runner is None:
        results["vmas navigation"] = None
        print("vmas not importable: see this script's docstring to compare against VMAS 1.5.2")
    else:
        ours, theirs = (k * r for r in _timed_pair(vector_runner(ENV, k, **LIDAR), runner, *timing))
        results.update({f"vector {k} lidar32 (paired with vmas)": ours, "vmas navigation": theirs})
        print(f"VMAS 1.5.2 navigation, {k} envs, lidar, CPU {theirs:12,.0f} env-steps/s")
        print(
            f"KoopNav lidar {k} envs, same windows       {ours:12,.0f} env-steps/s ({ours / theirs:.1f}x VMAS; target >= 10x)"
        )
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
