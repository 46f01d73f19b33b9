"""Paired comparison of two NMPC solvers from evaluator runs, as the Markdown table of docs/results.md.

Usage::

    python docs/solver_comparison.py RESULTS_JSON [RESULTS_JSON ...] [--a rti] [--b ipopt]

(a label's episodes in a later file replace the same label's episodes of the same cell and seed
in an earlier one, so a rerun of one arm is given after the run it updates)

The runs evaluate controllers labelled ``<controller>@<solver>`` (e.g. ``koopman-nmpc@rti`` and
``koopman-nmpc@ipopt``, in one run or in two runs of the same protocol; see the commands in
docs/results.md). For every task and controller the table gives both success rates, the paired
difference ``a - b`` on the episodes both solvers ran (same map, slip and seed) with Newcombe's
95% interval, the discordant pairs, the exact McNemar p-value and both median decision times
(median over the paired episodes of each episode's median), then the
verdict of the rule that picks the default solver: ``a`` may replace ``b`` when no task loses
significantly (p < 0.05) and the interval's lower end is above -5 points. Then the successes of
every cell for both solvers (a later file's episodes replace the same label's, cell's and seed's).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from evaluation.episodes.records import ran
from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT
from evaluation.reports.baseline import load_baseline
from evaluation.reports.sections import task_label
from evaluation.stats.statistics import paired_comparison

#: the rule of the default solver: no significant loss, and the interval's lower end above this
LOWER_END_LIMIT = -0.05
ALPHA = 0.05


def comparison_rows(documents: list[dict[str, Any]], a: str, b: str) -> list[dict[str, Any]]:
    """One row per (task, controller) that ran as ``<controller>@a`` and ``<controller>@b``.

    Episodes are paired on (task, map, slip, seed) across all ``documents``, so the two solvers
    may come from separate runs of the same protocol (the seeds depend only on the base seed and
    an episode's index in its cell). An episode of a label in a later document replaces the one
    of the same label, cell and seed in an earlier document (a rerun of one arm).
    """
    outcomes: dict[tuple[str, str, str], dict[tuple, dict[str, Any]]] = {}
    for doc in documents:
        for r in doc["episodes"]:
            if not ran(r) or "@" not in r["controller"]:
                continue
            base, solver = r["controller"].rsplit("@", 1)
            outcomes.setdefault((r["env_id"], base, solver), {})[(r["map"], r["slip"], r["seed"])] = r
    rows = []
    for (env_id, base, solver), mine in outcomes.items():
        other = outcomes.get((env_id, base, b))
        if solver != a or other is None:
            continue
        shared = sorted(set(mine) & set(other))
        if not shared:
            continue
        pair = paired_comparison(
            [bool(mine[k]["success"]) for k in shared], [bool(other[k]["success"]) for k in shared]
        )
        rows.append(
            {
                "env_id": env_id,
                "controller": base,
                "cells": sorted({(m, s) for m, s, _ in shared}),
                **pair.to_dict(),
                "ms_a": float(np.median([mine[k]["solve_ms_median"] for k in shared])),
                "ms_b": float(np.median([other[k]["solve_ms_median"] for k in shared])),
            }
        )
    return sorted(rows, key=lambda r: (r["env_id"], r["controller"]))


def per_cell_markdown(documents: list[dict[str, Any]], a: str, b: str) -> str:
    """Successes per (task, map, slip) cell and controller for both solvers, e.g. ``9/10``."""
    counts: dict[tuple, list[int]] = {}
    for doc in documents:
        latest = {}
        for r in doc["episodes"]:
            if ran(r) and "@" in r["controller"]:
                latest[(r["env_id"], r["map"], r["slip"], r["controller"], r["seed"])] = bool(r["success"])
        for key, success in latest.items():
            counts.setdefault(key[:4], {})[key[4]] = success
    bases = sorted({k[3].rsplit("@", 1)[0] for k in counts})
    header = "| Task | Map | Slip | " + " | ".join(f"{c} {s}" for c in bases for s in (b, a)) + " |"
    lines = [header, "|" + "---|" * (3 + 2 * len(bases))]
    for env_id, map_name, slip in sorted(
        {k[:3] for k in counts}, key=lambda k: (task_label(k[0]), k[1], k[2])
    ):
        cells = []
        for c in bases:
            for solver in (b, a):
                seeds = counts.get((env_id, map_name, slip, f"{c}@{solver}"), {})
                cells.append(f"{sum(seeds.values())}/{len(seeds)}" if seeds else "-")
        lines.append(f"| {task_label(env_id)} | {map_name} | {slip} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def loses(row: dict[str, Any]) -> bool:
    """Whether ``a`` fails the default rule on this row."""
    significant_loss = row["difference"] < 0 and row["p_value"] < ALPHA
    return significant_loss or row["low"] <= LOWER_END_LIMIT


def markdown(rows: list[dict[str, Any]], a: str, b: str) -> str:
    """The table and the verdict."""
    lines = [
        f"| Task | Controller | Cells | Pairs | Success {a} | Success {b} | {a} - {b} [95% CI] | "
        f"only {a} / only {b} | McNemar p | Median [ms] {a} / {b} | Rule |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        task = task_label(r["env_id"])
        cells = (
            ", ".join(f"{m} {s}" for m, s in r["cells"])
            if len(r["cells"]) <= 6
            else f"{len(r['cells'])} cells"
        )
        p = "<0.001" if r["p_value"] < 0.001 else f"{r['p_value']:.3f}"
        lines.append(
            f"| {task} | {r['controller']} | {cells} | {r['n']} | {100 * r['rate_a']:.0f}% | {100 * r['rate_b']:.0f}% | "
            f"{100 * r['difference']:+.0f} [{100 * r['low']:+.0f}, {100 * r['high']:+.0f}] | {r['only_a']} / {r['only_b']} "
            f"| {p} | {r['ms_a']:.1f} / {r['ms_b']:.1f} | {'fails' if loses(r) else 'passes'} |"
        )
    verdict = "passes" if rows and not any(loses(r) for r in rows) else "fails"
    lines += [
        "",
        f"Rule (no significant loss at p < {ALPHA}, interval's lower end above {100 * LOWER_END_LIMIT:+.0f} "
        f"points, on every row): **{verdict}**.",
    ]
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("results", nargs="+", type=Path, help="results.json of evaluator runs")
    parser.add_argument("--a", default="rti", help="the candidate solver label suffix (default rti)")
    parser.add_argument("--b", default="ipopt", help="the solver it is compared with (default ipopt)")
    args = parser.parse_args()
    # each file read checked, its episodes each once (a conflicting repeat within a file is refused);
    # across files a later rerun of one arm replaces the earlier one on purpose (see above)
    documents = [load_baseline(path, what="results") for path in args.results]
    rows = comparison_rows(documents, args.a, args.b)
    if not rows:
        print(
            f"error: no controller ran as both <name>@{args.a} and <name>@{args.b} in {args.results}",
            file=sys.stderr,
        )
        return BAD_INPUT_EXIT
    print(markdown(rows, args.a, args.b))
    print()
    print(per_cell_markdown(documents, args.a, args.b))
    return SUCCESS_EXIT


if __name__ == "__main__":
    try:
        raise SystemExit(main())
    except ValueError as exc:  # a results file that is not as KoopNav writes it (the message names it)
        print(f"error: {exc}", file=sys.stderr)
        raise SystemExit(BAD_INPUT_EXIT) from None
