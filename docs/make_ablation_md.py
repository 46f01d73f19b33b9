"""Write docs/ablation.md from the published ablation run (``bash data/publish.sh ablation``).

Usage (the published page's arguments are in ``data/pages.json``)::

    python docs/make_ablation_md.py data/ablation.tar.xz --out docs/ablation.md

The page is the evaluator's own ablation report (:func:`evaluation.experiments.ablation.ablation_markdown`,
what ``python evaluate.py --ablation`` writes beside its run: the main effects paired per
episode unit), headed by where its data are.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT  # noqa: E402
from evaluation.experiments.ablation import ablation_markdown  # noqa: E402
from evaluation.reports.publications import extracted_archive  # noqa: E402
from evaluation.reports.published import results_from_log  # noqa: E402
from koopman_envs.files import write_atomic  # noqa: E402

#: the run of data/publish.sh behind the page
RUN = "ablation"


def page(archive: str | Path) -> str:
    """The ablation page of the published run in ``archive`` (``data/ablation.tar.xz``)."""
    with extracted_archive(archive) as run:
        results = results_from_log(run / "episodes.jsonl")
    report = ablation_markdown(results)  # how to regenerate: the paragraph below
    title, _, rest = report.partition("\n\n")
    episodes = len(results.records)
    data = (
        f"Rebuilt from the committed episode log `data/{RUN}.tar.xz` ({episodes:,} episodes) by "
        f"`python docs/make_pages.py docs/ablation.md`, byte for byte (`tests/test_published_pages.py`); "
        f"the run is `bash data/publish.sh {RUN}` (resumable), then `bash data/publish.sh pack`."
    )
    return f"{title}\n\n{data}\n\n{rest}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("archive", help="the published ablation run, data/ablation.tar.xz")
    # no default page: the published one is a tracked file (docs/make_pages.py names it)
    parser.add_argument("--out", required=True, help="the page to write, e.g. docs/ablation.md")
    parser.add_argument("--figures", help="accepted for docs/make_pages.py; the page has no figures")
    args = parser.parse_args(argv)
    try:
        text = page(args.archive)
    except ValueError as exc:  # an archive that is not as KoopNav packs it (the message names it)
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    write_atomic(args.out, text)
    print(f"wrote {args.out}")
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
