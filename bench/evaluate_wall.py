"""Wall time of the evaluator's protocols on this machine, as a newcomer gets it.

Usage::

    python bench/evaluate_wall.py [--protocol quick|paper] [--warm] [--previous-default] [--workers N]

Runs README's first command, ``python evaluate.py`` (the quick leaderboard; ``--protocol paper``:
``python evaluate.py --paper``), in a fresh process into a temporary directory and prints its
wall time and episodes per second. By default every cache starts empty, as on a fresh machine:
``KOOPNAV_CACHE`` (calibrations, compiled solvers), ``HOME`` and ``NUMBA_CACHE_DIR`` (the
compiled simulator step) point into a new temporary directory; ``--warm`` keeps the machine's
caches instead. The package install is not timed. ``--previous-default`` also runs the same
protocol with the NMPCs in the previous default setup (IPOPT, uncompiled) in the same run.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PREVIOUS = [
    "koopman-nmpc:solver=ipopt,jit=false,label=koopman-nmpc",
    "nominal-nmpc:solver=ipopt,jit=false,label=nominal-nmpc",
    "consensus",
]


def timed_run(
    protocol: str,
    workers: int | None,
    controllers: list[str] | None = None,
    cold: bool = True,
    extra: list[str] | None = None,
) -> tuple[float, int]:
    """(wall seconds, episodes) of one evaluator run in a fresh process (``cold``: empty caches;
    ``extra``: further evaluator options)."""
    with tempfile.TemporaryDirectory(prefix="koopnav-wall-") as out:
        cmd = [sys.executable, "evaluate.py", "--out", out, "--quiet", *(extra or [])]
        cmd += ["--paper"] if protocol == "paper" else []
        cmd += ["--workers", str(workers)] if workers else []
        cmd += ["--controllers", *controllers] if controllers else []
        env = {k: v for k, v in os.environ.items() if k != "KOOPNAV_NMPC_JIT"}
        if cold:
            home = Path(out) / "home"
            env.update(
                KOOPNAV_CACHE=str(home / "koopnav-cache"),
                HOME=str(home),
                NUMBA_CACHE_DIR=str(home / "numba-cache"),
            )
        start = time.perf_counter()
        proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, check=False)
        wall = time.perf_counter() - start
        if proc.returncode not in (0,) and not (Path(out) / "results.json").exists():
            raise SystemExit(f"evaluate.py failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
        episodes = len(json.loads((Path(out) / "results.json").read_text())["episodes"])
    return wall, episodes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--protocol", choices=["paper", "quick"], default="quick")
    parser.add_argument("--warm", action="store_true", help="keep the machine's caches (default: all empty)")
    parser.add_argument("--workers", type=int)
    parser.add_argument(
        "--previous-default",
        action="store_true",
        help="also run the NMPCs as IPOPT, uncompiled (the default before the solver cache)",
    )
    parser.add_argument(
        "--evaluator-args",
        default="",
        help='further evaluator options, one string (e.g. "--controllers consensus --max-episode-steps 20" '
        "for a quick check of this script)",
    )
    args = parser.parse_args()
    extra = shlex.split(args.evaluator_args)
    print(f"python evaluate.py {'--paper' if args.protocol == 'paper' else ''} on {os.cpu_count()} cores")
    wall, episodes = timed_run(args.protocol, args.workers, cold=not args.warm, extra=extra)
    caches = "warm caches" if args.warm else "empty caches"
    print(
        f"python evaluate.py{' --paper' if args.protocol == 'paper' else ''} ({caches}): {wall:7.1f} s wall, "
        f"{episodes} episodes, {episodes / wall:.2f} episodes/s"
    )
    if args.previous_default and args.protocol == "paper":
        wall, episodes = timed_run(args.protocol, args.workers, PREVIOUS, cold=not args.warm, extra=extra)
        print(
            f"previous default (IPOPT, uncompiled): {wall:7.1f} s wall, {episodes} episodes, "
            f"{episodes / wall:.2f} episodes/s"
        )


if __name__ == "__main__":
    main()
