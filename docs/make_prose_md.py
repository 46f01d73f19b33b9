"""Write a page whose text is a template with its numbers computed from the committed data
(issue 60: prose that cannot drift), e.g. docs/paper.md from docs/_intros/paper.md.

Usage (the published pages' arguments are in ``data/pages.json``)::

    python docs/make_prose_md.py TEMPLATE --runs NAME=data/NAME.tar.xz ... --out PAGE

The template is Markdown in which every result is a placeholder ``{{ FUNCTION ARGUMENT ...
KEY=VALUE ... }}`` (its words split as a shell splits them: quote one that holds spaces). Each
is replaced by what FUNCTION prints from the published runs the page names, so the page states
no number its data do not give and a republication updates every number at once:

- the numbers of a run (``docs/prose_numbers.py``): ``episodes``, ``kn``, ``count``, ``rate``,
  ``ci``, ``diff``, ``points``, ``p``, ``holm``, ``tests``, ``median`` (a per-episode number),
  ``misses`` (deadline misses), ``collisions`` (episodes with a collision of a kind), filtered
  by ``task=``, ``map=``, ``slip=``, ``trial=`` (a value may list several: ``trial=0,1,2``);
  ``effect``, ``effect_p`` (the ablation's main effects), ``steps`` (a shipped policy's budget);
- the numbers of a sweep (``docs/prose_sweeps.py``): ``vsref``, ``vsref_points``, ``vsref_holm``
  (paired against its reference), ``cost``, ``cost_points``, ``cost_change``, ``cost_holm``
  (what a level costs), ``sweep_tests`` (the size of its Holm family);
- ``span`` (``docs/prose_span.py``): any of these over alternatives, ``94-100%``;
- the tables (``docs/prose_tables.py``), each alone on its line: ``success_table``,
  ``slip_table``, ``paper_cells``, ``run_table``, ``scale_table``, ``factor_table``.

A run is named ``NAME`` or, for one level of a sweep, ``NAME@KEY=LEVEL``
(``paper_realistic@uncertainty=realistic``). Each function's docstring says what it prints;
``python docs/make_prose_md.py --list`` prints them all.

The other generated pages' intros (``docs/_intros/*.md``, read by ``docs/make_robustness_md.py``
and ``docs/make_results_md.py``) are templates too (:func:`expand_template`): their runs are the
archives the generator reads, each named by its file (``data/lab_day_sweep.tar.xz`` is
``lab_day_sweep``).
"""

from __future__ import annotations

import argparse
import re
import shlex
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the page scripts beside this one

from prose_numbers import FILTERED, FILTERS, NUMBERS, ROOT, Options, Runs, parse_runs  # noqa: E402
from prose_span import SPAN  # noqa: E402
from prose_sweeps import SWEEP_NUMBERS  # noqa: E402
from prose_tables import TABLES  # noqa: E402

sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT  # noqa: E402
from koopman_envs.files import write_atomic  # noqa: E402

__all__ = ["FUNCTIONS", "PLACEHOLDER", "expand", "expand_template", "main", "runs_by_file"]

#: a placeholder: ``{{ FUNCTION ARGUMENT ... }}`` (on one line or several)
PLACEHOLDER = re.compile(r"\{\{(.*?)\}\}", re.DOTALL)
#: every placeholder function by name: the numbers (of a run, of a sweep), their span, the tables
FUNCTIONS: dict[str, Callable[[Runs, Sequence[str], Options], str]] = {
    **NUMBERS,
    **SWEEP_NUMBERS,
    **SPAN,
    **TABLES,
}
#: the words of a placeholder that are options, not arguments: the filters and the tables' lists
OPTION = re.compile(rf"^({'|'.join([*FILTERS, 'runs', 'times'])})=(.+)$")


def _call(runs: Runs, inner: str) -> str:
    words = shlex.split(inner)
    if not words or words[0] not in FUNCTIONS:
        raise ValueError(f"{words[0] if words else ''!r} is not one of the functions {sorted(FUNCTIONS)}")
    options = {m[1]: m[2] for m in map(OPTION.match, words[1:]) if m}
    args = [w for w in words[1:] if not OPTION.match(w)]
    filters = set(options) & set(FILTERS)
    if filters and words[0] not in FILTERED:
        raise ValueError(f"{words[0]} takes no filter, got {sorted(filters)}")
    return FUNCTIONS[words[0]](runs, args, options)


def expand(text: str, runs: Runs) -> str:
    """``text`` with every placeholder replaced by what its function computes from ``runs``.

    Raises
    ------
    ValueError
        A placeholder names an unknown function, run, controller, level or filter, or counts no
        episode (the message quotes the placeholder); or ``{{`` / ``}}`` is left unpaired.
    """

    def replace(match: re.Match[str]) -> str:
        try:
            return _call(runs, match[1])
        except (ValueError, KeyError) as exc:
            raise ValueError(f"placeholder {match[0]!r}: {exc}") from None

    out = PLACEHOLDER.sub(replace, text)
    for mark in ("{{", "}}"):
        if mark in out:
            line = out[: out.index(mark)].count("\n") + 1
            raise ValueError(f"an unpaired {mark!r} is left in the page at line {line}")
    return out


def runs_by_file(archives: Sequence[str | Path]) -> Runs:
    """The published archives a generator reads as a page's runs, each named by its file without
    the suffixes (``data/lab_day_sweep.tar.xz`` -> ``lab_day_sweep``). A name two different
    archives share is refused only when a placeholder names it (a page may read one sweep twice)."""
    named: dict[str, list[str]] = {}
    for archive in archives:
        paths = named.setdefault(Path(archive).name.split(".")[0], [])
        if str(archive) not in paths:
            paths.append(str(archive))
    return Runs(
        {name: Path(paths[0]) for name, paths in named.items() if len(paths) == 1},
        {name: paths for name, paths in named.items() if len(paths) > 1},
    )


def expand_template(template: Path, archives: Sequence[str | Path]) -> str:
    """The text of ``template`` (a page's intro) with its placeholders filled from ``archives``
    (:func:`runs_by_file`); a text without placeholders comes back as it is.

    Raises
    ------
    ValueError
        As :func:`expand`, the message naming the template.
    """
    text = template.read_text(encoding="utf-8")
    try:
        return expand(text, runs_by_file(archives))
    except ValueError as exc:
        raise ValueError(f"{template}: {exc}") from None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "template", nargs="?", type=Path, help="the page's template, e.g. docs/_intros/paper.md"
    )
    parser.add_argument(
        "--runs", nargs="+", default=[], help="the published runs it reads, NAME=data/NAME.tar.xz"
    )
    parser.add_argument("--out", help="the page to write, e.g. docs/paper.md")
    parser.add_argument("--figures", help="accepted for docs/make_pages.py; these pages draw no figure")
    parser.add_argument("--list", action="store_true", help="print every placeholder function and exit")
    args = parser.parse_args(argv)
    if args.list:
        for name, function in FUNCTIONS.items():
            print(f"{name}: {' '.join((function.__doc__ or '').split())}")
        return SUCCESS_EXIT
    if args.template is None or args.out is None:
        parser.error("a TEMPLATE and --out are needed (or --list)")
    try:
        text = expand(args.template.read_text(encoding="utf-8"), Runs(parse_runs(args.runs)))
    except (ValueError, OSError) as exc:  # the message names the placeholder, run or file
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    write_atomic(args.out, text)
    print(f"wrote {args.out}")
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
