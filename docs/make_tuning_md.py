"""Write docs/tuning.md, the tuning studies' curves, from the committed studies (data/tuning/).

Usage (the published page's arguments are in ``data/pages.json``)::

    python docs/make_tuning_md.py orca dwa ... --out docs/tuning.md [--figures DIR] [--studies DIR]

Each controller's study is ``DIR/NAME`` (default ``data/tuning``, as ``bash data/tuning/run.sh``
writes it).

What ``python -m evaluation.tune --report STUDY ... --out FIG.png`` draws and tabulates, as a
page: the figure of each study's expected best validation score against the configurations tried
(:func:`evaluation.tune.report.report_figure`, drawn into ``--figures``, default ``_static``
beside the page, as ``tuning.png``), the table of budgets, defaults' and best scores
(:func:`~evaluation.tune.report.report_markdown`, the report's FIG.md) and the curves as a table
(:func:`~evaluation.tune.report.expected_best_markdown`, the page's own). docs/make_pages.py rebuilds it;
tests/test_tuning_curves.py holds the table to the studies and the figure to the generator.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from controllers.tuning import STUDIES_DIR  # noqa: E402
from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT  # noqa: E402
from evaluation.tune.report import (  # noqa: E402
    expected_best_markdown,
    load_summary,
    report_figure,
    report_markdown,
)
from koopman_envs.files import write_atomic  # noqa: E402

#: the figure's file name under ``--figures``
FIGURE = "tuning.png"

TITLE = "Tuning studies: the expected best score against the configurations tried"


def _shown(folder: Path) -> str:
    """A study folder as the page names it: relative to the checkout when inside it."""
    folder = folder.resolve()
    return folder.relative_to(ROOT).as_posix() if folder.is_relative_to(ROOT) else folder.as_posix()


def page(folders: list[Path], out: Path, figures: Path) -> str:
    """The page's Markdown, the figure drawn into ``figures`` (``ValueError`` from a study that
    is not whole or whose suite changed, naming it)."""
    studies = [load_summary(folder) for folder in folders]
    figure = figures / FIGURE
    report_figure(studies, figure)
    link = Path(os.path.relpath(figure.resolve(), out.resolve().parent)).as_posix()
    names = ", ".join(f"`{s.controller}`" for s in studies)
    command = (
        "python -m evaluation.tune --report "
        + " ".join(map(_shown, folders))
        + " --out docs/_static/tuning.png"
    )
    return "\n\n".join(
        [
            f"# {TITLE}",
            f"The studies of {names} ([Tuning](benchmark.md#tuning) says how they ran and what they "
            "decided). Each curve is the expected best validation score of n configurations drawn "
            'from a study\'s trials against n (Dodge et al. 2019, "Show Your Work"; the caveat of '
            "Optuna's TPE trials against random search: [Tuning](benchmark.md#tuning)). Rebuilt from "
            "the committed studies by `python docs/make_pages.py docs/tuning.md`; the same figure and "
            f"first table as `{command}`.",
            f"![Expected best validation score of {', '.join(s.controller for s in studies)} against "
            f"the configurations tried]({link})",
            "## Budgets and scores",
            report_markdown(studies).rstrip("\n"),
            "## The curves as a table",
            "The expected best validation score of n configurations, at the n of each column; a "
            "curve still rising at its N says the controller was under-tuned at this budget.",
            expected_best_markdown(studies).rstrip("\n"),
        ]
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "controllers", nargs="+", help="the controllers whose studies the page shows, in order"
    )
    parser.add_argument(
        "--studies", type=Path, default=STUDIES_DIR, help="the folder of the studies (default: data/tuning)"
    )
    # no default page: the published one is a tracked file (docs/make_pages.py names it)
    parser.add_argument("--out", required=True, help="the page to write, e.g. docs/tuning.md")
    parser.add_argument("--figures", help="where the figure goes (default: _static beside --out)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    figures = Path(args.figures) if args.figures else out.parent / "_static"
    folders = [args.studies / name for name in args.controllers]
    missing = [folder.as_posix() for folder in folders if not folder.is_dir()]
    if missing:
        print(
            f"error: no study folder {missing}; allowed: the controllers with a study in {args.studies.as_posix()}",
            file=sys.stderr,
        )
        return BAD_INPUT_EXIT
    figures.mkdir(parents=True, exist_ok=True)
    try:
        text = page(folders, out, figures)
    except ValueError as exc:  # a study not whole, or whose suite changed (the message names it)
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    write_atomic(out, text + "\n")
    print(f"wrote {out} and {figures / FIGURE}")
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
