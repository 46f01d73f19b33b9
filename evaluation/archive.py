"""The published runs' command, which ``bash data/publish.sh`` runs: ``python -m evaluation.archive
RUN_DIR data/NAME`` publishes a run's episode logs split per controller (``data/NAME/run.tar.xz``
and ``data/NAME/controllers/LABEL.tar.xz``: a rerun of one controller rewrites its file only),
``python -m evaluation.archive RUN_DIR ARCHIVE.tar.xz`` packs them into one archive (the form of
the runs published before issue 61); ``python -m evaluation.archive unpack PUBLICATION DIR
[--force]`` restores either. The forms, and their checks on reading, are
:mod:`evaluation.reports.publications`' and :mod:`evaluation.reports.published`'s."""

from __future__ import annotations

import sys

from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT, UNWRITABLE_OUT_EXIT
from evaluation.reports.publications import pack_split, unpack_run
from evaluation.reports.published import is_archive, pack_run

__all__ = ["main"]


def main(argv: list[str]) -> int:
    """``python -m evaluation.archive RUN_DIR data/NAME`` publishes a run split per controller
    (``RUN_DIR ARCHIVE.tar.xz``: in one archive);
    ``python -m evaluation.archive unpack PUBLICATION DIR [--force]`` restores one (exit 2, named, if refused; 103 when the file system refuses a write)."""
    # "unpack" is always the command: "unpack ARCHIVE" without DIR once packed a run named
    # "unpack" (none) over ARCHIVE
    unpack = argv[:1] == ["unpack"]
    try:
        if unpack and len(argv) in (3, 4) and argv[3:] in ([], ["--force"]):
            print(unpack_run(argv[1], argv[2], force=argv[3:] == ["--force"]))
        elif not unpack and len(argv) == 2:
            print((pack_run if is_archive(argv[1]) else pack_split)(argv[0], argv[1]))
        else:
            print(main.__doc__, file=sys.stderr)
            return BAD_INPUT_EXIT
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    except OSError as exc:  # no space or no permission where the publication or the run is written
        print(f"error: {exc}", file=sys.stderr)
        return UNWRITABLE_OUT_EXIT
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
