"""What a reset costs the vector env: the environments that end in one step reset together
(``NavigationEngine.reset_envs``, what the vector env does) against one at a time
(``reset_env`` in a loop, what it did before). Run on an earlier checkout
(``PYTHONPATH=<its root> python bench/batched_resets.py``) it times that release's
one-at-a-time reset alone.

Usage::

    python bench/batched_resets.py [--envs 1024] [--batch 10] [--repeats 5] [--calls 200]

For each setting (target reaching, 3 robots: the fixed map, random layouts, 8 constant movers
exact and tracked, 8 waypoint walkers) it resets the same ``--batch`` environments of a
``--envs`` vector env ``--calls`` times both ways, alternating which goes first, and prints the
time per environment reset (best of ``--repeats``). Both ways draw the same episodes
(tests/test_batched_reset.py); random actions end about 1% of the environments per step among
8 movers and 0.1-0.2% otherwise, so ``--batch 10`` is what a 1024-env step resets.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from typing import Any

import gymnasium as gym
import numpy as np

import koopman_envs  # noqa: F401 - registers the ids

ENV = "KoopNav-TargetReaching-v0"
SETTINGS: dict[str, dict[str, Any]] = {
    "fixed map": {},
    "random layouts": {"map": "random"},
    "8 constant movers, exact": {"movers": {"count": 8, "tracking": False}},
    "8 constant movers, tracked": {"movers": {"count": 8}},
    "8 waypoint walkers": {"movers": {"count": 8, "behaviour": "waypoints"}},
}


def _per_reset(run, calls: int, batch: int) -> float:
    start = time.perf_counter()
    for _ in range(calls):
        run()
    return (time.perf_counter() - start) / (calls * batch)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--envs", type=int, default=1024, help="vector env size (default 1024)")
    parser.add_argument("--batch", type=int, default=10, help="environments reset per call (default 10)")
    parser.add_argument("--repeats", type=int, default=5, help="windows per figure, best reported")
    parser.add_argument("--calls", type=int, default=200, help="resets of the batch per window")
    parser.add_argument("--json", help="also write the figures to this JSON file")
    args = parser.parse_args()
    for name, value in (("--envs", args.envs), ("--batch", args.batch), ("--repeats", args.repeats), ("--calls", args.calls)):  # fmt: skip
        if value < 1:
            parser.error(f"{name}={value} must be >= 1")
    if args.batch > args.envs:
        parser.error(f"--batch={args.batch} must be <= --envs={args.envs}")
    print(f"KoopNav {koopman_envs.__version__}, numpy {np.__version__}, {platform.machine()}")
    print(
        f"{args.envs} envs, {args.batch} reset per call; time per environment reset [us], best of {args.repeats}"
    )
    rows = list(np.linspace(0, args.envs - 1, args.batch).astype(int))
    figures = {}
    for name, kwargs in SETTINGS.items():
        engine = gym.make_vec(ENV, num_envs=args.envs, **kwargs).unwrapped.engine  # type: ignore[attr-defined]
        rngs = [np.random.default_rng(i) for i in rows]
        batched = hasattr(engine, "reset_envs")  # a release before batched resets: one at a time only
        for index in range(args.envs):
            engine.reset_env(index, np.random.default_rng(index))

        def together(engine=engine, rngs=rngs) -> None:  # type: ignore[no-untyped-def]
            engine.reset_envs(rows, rngs)

        def one_at_a_time(engine=engine, rngs=rngs) -> None:  # type: ignore[no-untyped-def]
            for index, rng in zip(rows, rngs):
                engine.reset_env(index, rng)

        best = {"together": np.inf, "one at a time": np.inf}
        for repeat in range(args.repeats):
            order = [("together", together), ("one at a time", one_at_a_time)][0 if batched else 1 :]
            for label, run in order if repeat % 2 == 0 else order[::-1]:
                best[label] = min(best[label], _per_reset(run, args.calls, args.batch))
        figures[name] = {label: 1e6 * value for label, value in best.items() if np.isfinite(value)}
        ratio = f"({best['one at a time'] / best['together']:.1f}x)" if batched else ""
        print(
            f"{name:28s} together {1e6 * best['together']:7.1f}   one at a time {1e6 * best['one at a time']:7.1f}"
            f"   {ratio}",
            flush=True,
        )
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(figures, handle, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
