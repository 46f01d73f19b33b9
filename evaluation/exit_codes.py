"""The exit codes of KoopNav's command lines, one table (:data:`EXIT_CODES`) that ``--help``,
docs/ci.md and docs/evaluator.md show, so that a CI script can act on the code alone.

Each code means one thing: ``2`` is bad input only (never a count of episodes), ``1`` a fault of
KoopNav itself (an unexpected exception: a bug to report), and ``3`` one or more episodes that
raised, however many (the count is printed, not encoded). When several outcomes apply at once the
code of highest priority is returned (:func:`worst`): ``130 > 103 > 102 > 101 > 3``.
"""

from __future__ import annotations

import re
import sys
import traceback

__all__ = [
    "BAD_INPUT_EXIT",
    "EPISODES_RAISED_EXIT",
    "EXIT_CODES",
    "EXIT_PRECEDENCE",
    "FAILED_CHECK_EXIT",
    "FAILED_GATE_EXIT",
    "INTERNAL_ERROR_EXIT",
    "INTERRUPTED_EXIT",
    "SUCCESS_EXIT",
    "UNWRITABLE_OUT_EXIT",
    "exit_codes_help",
    "exit_codes_markdown",
    "report_internal_error",
    "worst",
]

SUCCESS_EXIT = 0
INTERNAL_ERROR_EXIT = 1  # an unexpected exception in KoopNav itself: the traceback is printed
BAD_INPUT_EXIT = 2  # named on stderr, before any episode ran
EPISODES_RAISED_EXIT = 3  # one or more episodes raised; the others' results are written
FAILED_CHECK_EXIT = 101  # --check: a cell below its floor
FAILED_GATE_EXIT = 102  # --fail-if-worse: a controller significantly worse than the baseline
UNWRITABLE_OUT_EXIT = 103  # --out cannot be made or written
INTERRUPTED_EXIT = 130  # the shell's code for a run stopped by Ctrl-C (128 + SIGINT)

#: the codes of outcomes that can apply together, highest priority first (:func:`worst`)
EXIT_PRECEDENCE = (
    INTERRUPTED_EXIT,
    UNWRITABLE_OUT_EXIT,
    FAILED_GATE_EXIT,
    FAILED_CHECK_EXIT,
    EPISODES_RAISED_EXIT,
)

#: every exit code and what it means, as ``--help`` and the docs list them
EXIT_CODES: tuple[tuple[int, str], ...] = (
    (SUCCESS_EXIT, "success: every episode ran (and --check / --fail-if-worse, if given, passed)"),
    (
        INTERNAL_ERROR_EXIT,
        "internal error: an unexpected exception in KoopNav itself (the traceback is printed; a bug to report)",
    ),
    (
        BAD_INPUT_EXIT,
        "bad input, named on stderr before any episode ran; also --fail-if-worse when too few episodes "
        "pair with the --baseline to judge the run (a stale or empty baseline fails closed; when episodes "
        "that raised leave too few pairs after the run, 2 ranks below 101 and above 3)",
    ),
    (
        EPISODES_RAISED_EXIT,
        "one or more episodes raised (the count is printed in the summary); the others' results are written",
    ),
    (FAILED_CHECK_EXIT, "a --check floor was missed"),
    (FAILED_GATE_EXIT, "--fail-if-worse: a controller is significantly worse than the --baseline"),
    (
        UNWRITABLE_OUT_EXIT,
        "--out cannot be made or written (a file, read-only, no permission or space); before any "
        "episode, or when a report could not be written",
    ),
    (INTERRUPTED_EXIT, "interrupted (Ctrl-C or SIGTERM); continue with --resume"),
)


def worst(*codes: int) -> int:
    """The one code to exit with when several outcomes apply: the first of
    :data:`EXIT_PRECEDENCE` among ``codes``, else 0.

    Raises
    ------
    ValueError
        A code outside :data:`EXIT_PRECEDENCE` and 0 (bad input and internal errors end a run at
        once: they never combine).
    """
    for code in codes:
        if code != SUCCESS_EXIT and code not in EXIT_PRECEDENCE:
            raise ValueError(
                f"exit code {code!r} does not combine; allowed: {[SUCCESS_EXIT, *EXIT_PRECEDENCE]}"
            )
    return next((code for code in EXIT_PRECEDENCE if code in codes), SUCCESS_EXIT)


def exit_codes_help() -> str:
    """The table as an argparse epilog (``--help``), with the precedence."""
    order = " > ".join(str(code) for code in EXIT_PRECEDENCE)
    rows = "\n".join(f"  {code:<6} {meaning}" for code, meaning in EXIT_CODES)
    return f"exit codes:\n{rows}\n  when several apply, the highest-priority one: {order}"


_OPTION = re.compile(r"--[a-z][a-z-]*")


def exit_codes_markdown() -> str:
    """The table as Markdown (docs/ci.md and docs/evaluator.md hold it verbatim, a test checks),
    options set as code."""
    as_code = r"`\g<0>`"
    rows = "\n".join(f"| {code} | {_OPTION.sub(as_code, meaning)} |" for code, meaning in EXIT_CODES)
    return f"| code | meaning |\n|---|---|\n{rows}\n"


def report_internal_error(program: str) -> int:
    """Print the exception being handled and that it is a bug; return :data:`INTERNAL_ERROR_EXIT`.

    Call from an ``except Exception`` block of a command line's entry point."""
    traceback.print_exc()
    print(
        f"error: internal error in {program}: a bug in KoopNav, not in your input; please report it "
        "with the traceback above and the command line",
        file=sys.stderr,
    )
    return INTERNAL_ERROR_EXIT
