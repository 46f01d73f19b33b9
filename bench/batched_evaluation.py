"""Episodes per second of the crowd protocol's learned-policy rows, batched against one by one.

Usage::

    python bench/batched_evaluation.py [--behaviours constant waypoints crowd] [--counts 0 4 8 16]
                                       [--controllers rl-ppo ...] [--episodes 20] [--batch 64]

Plans the crowd protocol (``python evaluate.py --crowd BEHAVIOUR``: both tasks on their paper maps
and random layouts, perturbed starts, nominal slip) for the learned policies at each mover count
and runs it twice in this process on one worker: with ``--batch`` (a cell's episodes together in
the vector env, :func:`evaluation.worker.run_batch`) and with ``batch=1`` (every episode alone, the
path every controller took before), alternating which goes first. Prints the wall time and
episodes per second of each, the ratio, and whether every record is the same (all fields but the
timing ones). A short warm-up run first compiles the kernels and loads the policies, so that
neither side pays for them.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

from evaluation import RunSpec, evaluate
from evaluation.configs import parse_controller
from evaluation.protocols import CROWD_COUNTS, crowd_protocol

POLICIES = ["rl-ppo", "rl-ppo-set", "rl-ppo-set-movers", "rl-ppo-set-realistic"]
TIMING = {"solve_ms", "solve_ms_median", "solve_ms_p95", "wall_seconds"}


def untimed(record: dict) -> dict:
    """A record without its timing fields (decision and wall times)."""
    extra = {k: v for k, v in (record.get("controller_extra") or {}).items() if "_ms" not in k}
    return {k: v for k, v in record.items() if k not in TIMING} | {"controller_extra": extra or None}


def protocol(behaviour: str, count: int, controllers: list[str], episodes: int) -> RunSpec:
    """The crowd protocol's run of ``controllers`` at ``count`` movers of ``behaviour``."""
    spec = crowd_protocol(behaviour)
    env_kwargs = {**spec.env_kwargs, "movers": {**spec.env_kwargs["movers"], "count": count}}
    return dataclasses.replace(
        spec,
        env_kwargs=env_kwargs,
        episodes=episodes,
        controllers=[parse_controller(name) for name in controllers],
    )


def timed(spec: RunSpec, batch: int) -> tuple[float, list[dict]]:
    start = time.perf_counter()
    records = evaluate(spec, workers=1, batch=batch).records
    return time.perf_counter() - start, records


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--behaviours", nargs="+", default=["constant", "waypoints", "crowd"])
    parser.add_argument("--counts", nargs="+", type=int, default=list(CROWD_COUNTS))
    parser.add_argument("--controllers", nargs="+", default=POLICIES)
    parser.add_argument("--episodes", type=int, default=20, help="trials per cell (the protocol's 20)")
    parser.add_argument("--batch", type=int, default=64)
    args = parser.parse_args(argv)
    timed(protocol(args.behaviours[0], max(args.counts), args.controllers, 2), args.batch)  # warm-up
    print(
        "| movers | episodes | one by one [s] | batched [s] | episodes/s one by one | batched | ratio | same records |"
    )
    print("|---|---|---|---|---|---|---|---|")
    totals = [0.0, 0.0, 0]
    for index, (behaviour, count) in enumerate((b, c) for b in args.behaviours for c in args.counts):
        spec = protocol(behaviour, count, args.controllers, args.episodes)
        order = (1, args.batch) if index % 2 == 0 else (args.batch, 1)
        runs = {batch: timed(spec, batch) for batch in order}
        (alone, alone_records), (together, batched_records) = runs[1], runs[args.batch]
        same = [untimed(r) for r in alone_records] == [untimed(r) for r in batched_records]
        n = len(alone_records)
        totals = [totals[0] + alone, totals[1] + together, totals[2] + n]
        print(
            f"| {count} {behaviour} | {n} | {alone:.1f} | {together:.1f} | {n / alone:.1f} | "
            f"{n / together:.1f} | {alone / together:.2f}x | {'yes' if same else 'NO'} |"
        )
    alone, together, n = totals
    print(
        f"| all | {n} | {alone:.1f} | {together:.1f} | {n / alone:.1f} | {n / together:.1f} | "
        f"{alone / together:.2f}x | |"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
