"""Check that a run reproduced a baseline field for field: ``python -m evaluation.exact RUN BASE [--subset]``
(what ``bash .ci/leaderboard.sh --exact`` runs after the gate).

Both are results.json files or run directories. Exit 0 when every episode of the baseline is in
the run and equal to it in every field but the timings
(:func:`evaluation.reports.reproduced.exact_differences`), 101 when an episode is missing, extra
or differs (each named, with the differing fields and both values), 2 for bad input (a file that
cannot be read, a baseline of other settings). ``--subset``: the run ran part of the baseline's
protocol (some controllers, cells or trials); only the baseline's episodes it planned are expected.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from evaluation.exit_codes import BAD_INPUT_EXIT, FAILED_CHECK_EXIT, SUCCESS_EXIT
from evaluation.reports import exact_differences, load_baseline, refuse_incomparable, within_run


def main(argv: Sequence[str] | None = None) -> int:
    """Compare the two runs' episodes; print the verdict and every difference; return the exit code."""
    parser = argparse.ArgumentParser(prog="python -m evaluation.exact", description=__doc__.split("\n\n")[0])
    parser.add_argument("run", metavar="RUN", help="the run's results.json or directory")
    parser.add_argument("baseline", metavar="BASE", help="the baseline's results.json or directory")
    parser.add_argument(
        "--subset",
        action="store_true",
        help="the run ran part of the baseline's protocol: expect only the baseline's episodes it planned",
    )
    args = parser.parse_args(argv)
    try:
        run = load_baseline(args.run, what="run")
        baseline = load_baseline(args.baseline)
        refuse_incomparable(run["config"], run["package_version"], baseline)
        expected = within_run(baseline["episodes"], run["config"]) if args.subset else baseline["episodes"]
        comparison = exact_differences(run["episodes"], expected)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    if comparison.equal:
        print(
            f"{comparison.compared} episodes equal to the baseline's field for field, timings aside "
            f"({args.baseline})"
        )
        return SUCCESS_EXIT
    problems = comparison.problems()
    print(
        f"the run does not reproduce the baseline {args.baseline} ({len(problems)} episodes; "
        f"{comparison.compared} paired):\n" + "\n".join(f"  - {p}" for p in problems),
        file=sys.stderr,
    )
    return FAILED_CHECK_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
