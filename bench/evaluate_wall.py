"""Wall time of the evaluator: the quick default run or the paper's protocol.

Usage::

    python bench/evaluate_wall.py [--paper] [--workers N]

Runs ``evaluate.py`` in-process with a fresh output directory and prints the wall time, the
number of episodes and episodes per second.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import evaluate as ev  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--paper", action="store_true", help="the paper's protocol (default: the quick run)")
    parser.add_argument("--workers", type=int, default=os.cpu_count())
    args = parser.parse_args()
    protocol = ev.paper_protocol() if args.paper else ev.quick_protocol()
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        results = ev.evaluate(
            protocol["env_ids"], protocol.get("controllers"), protocol["maps"], episodes=protocol["episodes"],
            workers=args.workers, out=out,
        )  # fmt: skip
        results.write(out)
        wall = time.perf_counter() - start
    n = len(results.records)
    label = "paper protocol" if args.paper else "quick default run"
    print(f"{label}: {n} episodes, {args.workers} workers, wall {wall:.1f} s ({wall / 60:.2f} min), "
          f"{n / wall:.2f} episodes/s, {len(results.failed_episodes)} raised")  # fmt: skip


if __name__ == "__main__":
    main()
