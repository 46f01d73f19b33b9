"""Paired comparison of two NMPC solvers from evaluator runs, as the Markdown table of docs/results.md.

Usage::

    python docs/solver_comparison.py RESULTS_JSON [RESULTS_JSON ...] [--a rti] [--b ipopt]

Each run evaluates controllers labelled ``<controller>@<solver>`` (e.g. ``koopman-nmpc@rti`` and
``koopman-nmpc@ipopt``, see the command in docs/results.md). For every task and controller the
table gives both success rates, the paired difference ``a - b`` on the episodes both solvers ran
(same map, slip and seed) with Newcombe's 95% interval, the discordant pairs, the exact McNemar
p-value (all from the run's own ``paired_comparisons``) and both median decision times, then the
verdict of the rule that picks the default solver: ``a`` may replace ``b`` when no task loses
significantly (p < 0.05) and the interval's lower end is above -5 points.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

#: the rule of the default solver: no significant loss, and the interval's lower end above this
LOWER_END_LIMIT = -0.05
ALPHA = 0.05


def comparison_rows(documents: list[dict[str, Any]], a: str, b: str) -> list[dict[str, Any]]:
    """One row per (run, task, controller) that ran with both solvers ``a`` and ``b``."""
    rows = []
    for doc in documents:
        board = {(r["env_id"], r["controller"]): r for r in doc["leaderboard"]}
        for pair in doc["paired_comparisons"]:
            labels = {pair["a"], pair["b"]}
            bases = {label.rsplit("@", 1)[0] for label in labels}
            solvers = {label.rsplit("@", 1)[-1] for label in labels}
            if len(bases) != 1 or solvers != {a, b}:
                continue
            base = bases.pop()
            flip = pair["a"] != f"{base}@{a}"  # report a - b whatever order the run paired them in
            sign = -1 if flip else 1
            low, high = (-pair["high"], -pair["low"]) if flip else (pair["low"], pair["high"])
            rows.append({
                "env_id": pair["env_id"], "controller": base, "cells": pair["cells"], "n": pair["n"],
                "rate_a": pair["rate_b"] if flip else pair["rate_a"], "rate_b": pair["rate_a"] if flip else pair["rate_b"],
                "difference": sign * pair["difference"], "low": low, "high": high,
                "only_a": pair["only_b"] if flip else pair["only_a"], "only_b": pair["only_a"] if flip else pair["only_b"],
                "p_value": pair["p_value"],
                "ms_a": board[(pair["env_id"], f"{base}@{a}")]["solve_ms_median"],
                "ms_b": board[(pair["env_id"], f"{base}@{b}")]["solve_ms_median"],
            })  # fmt: skip
    return rows


def loses(row: dict[str, Any]) -> bool:
    """Whether ``a`` fails the default rule on this row."""
    significant_loss = row["difference"] < 0 and row["p_value"] < ALPHA
    return significant_loss or row["low"] <= LOWER_END_LIMIT


def markdown(rows: list[dict[str, Any]], a: str, b: str) -> str:
    """The table and the verdict."""
    lines = [f"| Task | Controller | Cells | Pairs | Success {a} | Success {b} | {a} - {b} [95% CI] | "
             f"only {a} / only {b} | McNemar p | Median [ms] {a} / {b} | Rule |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in rows:
        task = "formation" if "Formation" in r["env_id"] else "target reaching"
        cells = ", ".join(f"{m} {s}" for m, s in r["cells"])
        p = "<0.001" if r["p_value"] < 0.001 else f"{r['p_value']:.3f}"
        lines.append(
            f"| {task} | {r['controller']} | {cells} | {r['n']} | {100 * r['rate_a']:.0f}% | {100 * r['rate_b']:.0f}% | "
            f"{100 * r['difference']:+.0f} [{100 * r['low']:+.0f}, {100 * r['high']:+.0f}] | {r['only_a']} / {r['only_b']} "
            f"| {p} | {r['ms_a']:.1f} / {r['ms_b']:.1f} | {'fails' if loses(r) else 'passes'} |"
        )  # fmt: skip
    verdict = "passes" if rows and not any(loses(r) for r in rows) else "fails"
    lines += ["", f"Rule (no significant loss at p < {ALPHA}, interval's lower end above {100 * LOWER_END_LIMIT:+.0f} "
              f"points, on every row): **{verdict}**."]  # fmt: skip
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("results", nargs="+", type=Path, help="results.json of evaluator runs")
    parser.add_argument("--a", default="rti", help="the candidate solver label suffix (default rti)")
    parser.add_argument("--b", default="ipopt", help="the solver it is compared with (default ipopt)")
    args = parser.parse_args()
    documents = [json.loads(path.read_text(encoding="utf-8")) for path in args.results]
    rows = comparison_rows(documents, args.a, args.b)
    if not rows:
        raise SystemExit(f"no controller ran as both <name>@{args.a} and <name>@{args.b} in {args.results}")
    print(markdown(rows, args.a, args.b))


if __name__ == "__main__":
    main()
