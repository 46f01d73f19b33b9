"""The published archives' command, which ``bash data/publish.sh`` runs: ``python -m evaluation.archive
RUN_DIR ARCHIVE`` packs a run's episode logs into ``data/NAME.tar.xz``; ``python -m evaluation.archive
unpack ARCHIVE DIR [--force]`` restores one. The archives themselves, and their checks on reading,
are :mod:`evaluation.reports.published`'s."""

from __future__ import annotations

import sys

from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT
from evaluation.reports.published import pack_run, unpack_run

__all__ = ["main"]


def main(argv: list[str]) -> int:
    """``python -m evaluation.archive RUN_DIR ARCHIVE`` packs a run;
    ``python -m evaluation.archive unpack ARCHIVE DIR [--force]`` restores one (exit 2, named, if refused)."""
    try:
        if argv[:1] == ["unpack"] and len(argv) in (3, 4) and argv[3:] in ([], ["--force"]):
            print(unpack_run(argv[1], argv[2], force=argv[3:] == ["--force"]))
        elif len(argv) == 2:
            print(pack_run(argv[0], argv[1]))
        else:
            print(main.__doc__, file=sys.stderr)
            return BAD_INPUT_EXIT
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
