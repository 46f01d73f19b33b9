"""Wall time of the evaluator's protocols on this machine.

Usage::

    python bench/evaluate_wall.py [--protocol paper|quick] [--previous-default] [--workers N]

Runs ``python evaluate.py --paper`` (or the quick leaderboard) in a fresh process into a
temporary directory and prints its wall time and episodes per second. The solver cache is the
machine's (``controllers.solver_cache``): run once to fill it, then again for the figure the
targets refer to ("after the first compile"). ``--previous-default`` also runs the same protocol
with the NMPCs in the previous default setup (IPOPT, uncompiled) for comparison in the same run.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PREVIOUS = ["koopman-nmpc:solver=ipopt,jit=false,label=koopman-nmpc",
            "nominal-nmpc:solver=ipopt,jit=false,label=nominal-nmpc", "consensus"]  # fmt: skip


def timed_run(protocol: str, workers: int | None, controllers: list[str] | None = None) -> tuple[float, int]:
    """(wall seconds, episodes) of one evaluator run in a fresh process."""
    with tempfile.TemporaryDirectory(prefix="koopnav-wall-") as out:
        cmd = [sys.executable, "evaluate.py", "--out", out, "--quiet"]
        cmd += ["--paper"] if protocol == "paper" else []
        cmd += ["--workers", str(workers)] if workers else []
        cmd += ["--controllers", *controllers] if controllers else []
        env = {k: v for k, v in os.environ.items() if k != "KOOPNAV_NMPC_JIT"}
        start = time.perf_counter()
        proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
        wall = time.perf_counter() - start
        if proc.returncode not in (0,) and not (Path(out) / "results.json").exists():
            raise SystemExit(f"evaluate.py failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
        episodes = len(json.loads((Path(out) / "results.json").read_text())["episodes"])
    return wall, episodes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--protocol", choices=["paper", "quick"], default="paper")
    parser.add_argument("--workers", type=int)
    parser.add_argument("--previous-default", action="store_true",
                        help="also run the NMPCs as IPOPT, uncompiled (the default before the solver cache)")
    args = parser.parse_args()
    print(f"python evaluate.py {'--paper' if args.protocol == 'paper' else ''} on {os.cpu_count()} cores")
    wall, episodes = timed_run(args.protocol, args.workers)
    print(f"default (IPOPT, compiled, cached): {wall:7.1f} s wall, {episodes} episodes, {episodes / wall:.2f} episodes/s")
    if args.previous_default and args.protocol == "paper":
        wall, episodes = timed_run(args.protocol, args.workers, PREVIOUS)
        print(f"previous default (IPOPT, uncompiled): {wall:7.1f} s wall, {episodes} episodes, "
              f"{episodes / wall:.2f} episodes/s")  # fmt: skip


if __name__ == "__main__":
    main()
