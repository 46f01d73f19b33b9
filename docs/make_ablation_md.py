"""Write docs/ablation.md from the published ablation run (``bash data/publish.sh ablation``).

Usage (the published page's arguments are in ``data/pages.json``)::

    python docs/make_ablation_md.py data/ablation --out docs/ablation.md

The page is the evaluator's own ablation report (:func:`evaluation.experiments.ablation.ablation_markdown`,
what ``python evaluate.py --ablation`` writes beside its run: the main effects paired per
episode unit, Holm within the table's family and its power statement), headed by where its data
are. The publication is ``data/ablation/`` as ``bash data/publish.sh pack`` writes it (or one
archive, ``NAME.tar.xz``); while it is missing the page says so (:func:`pending_page`) and how
to publish it, and states no number. A publication packed while the run goes on (a checkpoint
carried to the next session) holds some configurations only: the page then says how far the run
is, configuration by configuration (:func:`progress_page`), and estimates no effect until every
configuration has all the episodes the run's header plans.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing
sys.path.insert(0, str(Path(__file__).resolve().parent))  # the page scripts beside this one

from page_writer import write_publication_page  # noqa: E402

from evaluation.experiments.ablation import ABLATION_TITLE, ablation_configs, ablation_markdown  # noqa: E402
from evaluation.reports.publications import extracted_archive  # noqa: E402
from evaluation.reports.published import results_from_log  # noqa: E402
from evaluation.stats import planned_episodes  # noqa: E402

#: the run of data/publish.sh behind the page
RUN = "ablation"


def _regenerate(archive: Path) -> str:
    return (
        f"the run is `bash data/publish.sh {RUN}` (resumable), then `bash data/publish.sh pack`, "
        f"which writes `{archive.as_posix()}`"
    )


def pending_page(archive: str | Path) -> str:
    """The page while the publication ``archive`` is missing: what it will hold and how to make it."""
    archive = Path(archive)
    return (
        f"# {ABLATION_TITLE}\n\n"
        f"**Pending: the ablation run is not published yet** (`{archive.as_posix()}` is missing). "
        f"To publish it: {_regenerate(archive)}; then `python docs/make_pages.py docs/ablation.md` "
        f"rebuilds this page from it. The run is every combination of the factors' levels "
        f"({len(ablation_configs())} configurations of Koopman-NMPC and nominal NMPC) on the paper maps "
        "under high slip, on IPOPT; the page is then the evaluator's report: success per "
        "configuration and map, and each factor's main effect paired per episode unit (a unit counted "
        "once per comparison), with Holm's correction within the table and its power statement.\n\n"
        "Figures measured earlier, at commit 473c74b, without committed data and with each episode "
        "unit counted four times, are in this page's history (`git log -p -- docs/ablation.md`); "
        "they are not repeated here.\n"
    )


def shortfalls(config: dict, records: list[dict]) -> dict[str, tuple[int, int]]:
    """Each configuration of the run's header (``config``) whose episodes are not all in
    ``records``: its label -> (episodes there, episodes planned)."""
    planned = sum(planned_episodes(config, env_id) for env_id in config["env_ids"])
    done: dict[str, int] = {}
    for record in records:
        done[record["controller"]] = done.get(record["controller"], 0) + 1
    labels = [entry["label"] for entry in config["controller_configs"]]
    return {label: (done.get(label, 0), planned) for label in labels if done.get(label, 0) < planned}


def progress_page(archive: Path, short: dict[str, tuple[int, int]], configurations: int) -> str:
    """The page while the published run is incomplete: how far each configuration is, no effect."""
    rows = "\n".join(f"| {label} | {done:,} of {planned:,} |" for label, (done, planned) in short.items())
    return (
        f"# {ABLATION_TITLE}\n\n"
        f"**In progress: the ablation run is published partial** (`{archive.as_posix()}`): "
        f"complete configurations (every episode their run plans) {configurations - len(short)} of "
        f"{configurations}, and no main effect is estimated until all are (an effect over part of the "
        f"configurations would not be the factor's). To finish it: {_regenerate(archive)}; then "
        "`python docs/make_pages.py docs/ablation.md` rebuilds this page from it.\n\n"
        "| configuration still running or not started | episodes published |\n|---|---|\n"
        f"{rows}\n"
    )


def page(archive: str | Path) -> str:
    """The ablation page of the published run in ``archive`` (``data/ablation``): the evaluator's
    report when every configuration is complete, else :func:`progress_page`."""
    archive = Path(archive)
    with extracted_archive(archive) as run:
        results = results_from_log(run / "episodes.jsonl")
    short = shortfalls(results.config, results.records)
    if short:
        return progress_page(archive, short, len(results.config["controller_configs"]))
    report = ablation_markdown(results)  # how to regenerate: the paragraph below
    _, _, rest = report.partition("\n\n")
    episodes = len(results.records)
    data = (
        f"Rebuilt from the committed episode logs `{archive.as_posix()}` ({episodes:,} episodes) by "
        f"`python docs/make_pages.py docs/ablation.md`, byte for byte (`tests/test_published_pages.py`); "
        f"{_regenerate(archive)}."
    )
    return f"# {ABLATION_TITLE}\n\n{data}\n\n{rest}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("archive", help="the published ablation run, data/ablation (or NAME.tar.xz)")
    # no default page: the published one is a tracked file (docs/make_pages.py names it)
    parser.add_argument("--out", required=True, help="the page to write, e.g. docs/ablation.md")
    parser.add_argument("--figures", help="accepted for docs/make_pages.py; the page has no figures")
    args = parser.parse_args(argv)
    return write_publication_page(
        args.out, Path(args.archive), lambda: page(args.archive), lambda: pending_page(args.archive), RUN
    )


if __name__ == "__main__":
    raise SystemExit(main())
