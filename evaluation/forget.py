"""Republish a changed controller's rows: ``python -m evaluation.forget LABEL [LABEL ...] -- DIR [DIR ...]``
drops the records of those controller labels from every episode log under each run or sweep
directory (:func:`evaluation.episodes.runlog.forget_controllers`), so that running the same command again
with ``--resume`` runs exactly their episodes."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from evaluation.episodes.runlog import LogError, RunLocked, forget_controllers
from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT


def main(argv: Sequence[str] | None = None) -> int:
    """Drop the labels' records; print how many per directory. Bad input (exit 2) for a command
    without ``--`` between the labels and the directories, or a log that cannot be read.

    The ``--`` is split on here, not by argparse: argparse gives two greedy positional lists all
    but the last word, so ``LABEL -- DIR1 DIR2`` would read DIR1 as a label and drop nothing
    from it, silently.
    """
    words = list(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(
        prog="python -m evaluation.forget",
        usage="python -m evaluation.forget LABEL [LABEL ...] -- DIR [DIR ...]",
        description=__doc__.split("\n\n")[0],
    )
    parser.add_argument("labels", nargs="+", metavar="LABEL", help="controller labels whose records to drop")
    parser.add_argument("runs", nargs="+", metavar="DIR", help="run or sweep directories (after --)")
    if "--" not in words:
        if any(word in ("-h", "--help") for word in words):
            parser.parse_args(words)  # prints the help, exits 0
        print(
            f"error: no '--' in {words!r}: write the labels, then --, then the run directories "
            "(python -m evaluation.forget LABEL [LABEL ...] -- DIR [DIR ...])",
            file=sys.stderr,
        )
        return BAD_INPUT_EXIT
    split = words.index("--")
    labels, runs = words[:split], words[split + 1 :]
    if not labels or not runs:
        what = "no controller label before" if not labels else "no run directory after"
        print(f"error: {what} '--' in {words!r}", file=sys.stderr)
        return BAD_INPUT_EXIT
    for run in runs:
        try:
            print(f"{run}: {forget_controllers(run, labels)} records dropped")
        except (LogError, RunLocked) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return BAD_INPUT_EXIT
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
