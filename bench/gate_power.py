"""Power of ``--fail-if-worse`` to catch a drop in success rate, by episode count (simulation).

Usage::

    python bench/gate_power.py [--drop 0.2] [--base 0.9] [--alpha 0.05] [--delta 0.10] [--trials 20000]

For each episode count n the script draws ``trials`` pairs of runs and reports the fraction the
gate (evaluation/reports/baseline.py: success drop larger than ``delta`` with exact McNemar p < ``alpha``)
fails, for two ways a controller can get worse by ``drop``:

``nested``
    The worse controller loses a fraction of the baseline's successes and wins nothing new
    (every discordant pair goes one way; the same seeds make this the common case when a change
    breaks some situations).
``independent``
    The two runs' outcomes are independent given the rates (the most discordant pairs, both
    ways): the hardest case for a paired test.

It prints the smallest n with power >= 80% for each. The gate's decision uses the same functions
as the evaluator (:func:`evaluation.stats.statistics.paired_comparison`).
"""

from __future__ import annotations

import argparse

import numpy as np

from evaluation.reports.baseline import GateOptions
from evaluation.stats.statistics import paired_comparison


def power(
    n: int, base: float, drop: float, mode: str, gate: GateOptions, trials: int, rng: np.random.Generator
) -> float:
    """Fraction of simulated run pairs of ``n`` episodes that the gate fails."""
    fails = 0
    for _ in range(trials):
        baseline = rng.random(n) < base
        if mode == "nested":  # lose a fraction drop / base of the baseline's successes
            run = baseline & (rng.random(n) >= drop / base)
        else:
            run = rng.random(n) < base - drop
        result = paired_comparison(run.tolist(), baseline.tolist())
        fails += result.difference < -gate.delta and result.p_value < gate.alpha
    return fails / trials


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--drop", type=float, default=0.20, help="true drop in success rate (default 0.20)")
    parser.add_argument("--base", type=float, default=0.90, help="baseline success rate (default 0.90)")
    parser.add_argument("--alpha", type=float, default=GateOptions().alpha)
    parser.add_argument("--delta", type=float, default=GateOptions().delta)
    parser.add_argument("--trials", type=int, default=4000, help="simulated run pairs per n (default 4000)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    gate = GateOptions(alpha=args.alpha, delta=args.delta)
    print(
        f"gate: drop > {args.delta:.2f} and McNemar p < {args.alpha}; baseline success {args.base:.2f}, "
        f"true drop {args.drop:.2f}; {args.trials} simulated run pairs per n"
    )
    for mode in ("nested", "independent"):
        rng = np.random.default_rng(args.seed)
        found = None
        for n in (10, 15, 20, 25, 30, 40, 50, 60, 80, 100, 120, 150):
            p = power(n, args.base, args.drop, mode, gate, args.trials, rng)
            print(f"  {mode:<12} n = {n:4d}: power {p:.2f}")
            if p >= 0.8 and found is None:
                found = n
                break
        print(
            f"  {mode}: power >= 80% from n = {found} episodes per controller and task"
            if found
            else f"  {mode}: power < 80% up to 150 episodes"
        )


if __name__ == "__main__":
    main()
