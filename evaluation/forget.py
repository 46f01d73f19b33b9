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
    """Drop the labels' records; print how many per directory. Bad input (exit 2) for a log that cannot be read."""
    parser = argparse.ArgumentParser(prog="python -m evaluation.forget", description=__doc__.split("\n\n")[0])
    parser.add_argument("labels", nargs="+", metavar="LABEL", help="controller labels whose records to drop")
    parser.add_argument("runs", nargs="+", metavar="DIR", help="run or sweep directories (after --)")
    args = parser.parse_args(argv)
    for run in args.runs:
        try:
            print(f"{run}: {forget_controllers(run, args.labels)} records dropped")
        except (LogError, RunLocked) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return BAD_INPUT_EXIT
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
