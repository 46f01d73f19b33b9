"""Write docs/seeds_results.md from the published seeds run (``bash data/publish.sh seeds``).

Usage (the published page's arguments are in ``data/pages.json``)::

    python docs/make_seeds_md.py data/seeds --out docs/seeds_results.md

The publication is ``data/seeds/`` as ``bash data/publish.sh pack`` writes it (one run per task,
every finished training seed a controller ``<policy>@seed<k>`` of it; or one archive,
``NAME.tar.xz``), read by :func:`evaluation.experiments.seeds_published.read_publication`; each seed's
validation record is its seed folder's ``selection.json`` under ``--training`` (default
``data/training``). The page is the command's own tables
(:func:`evaluation.experiments.seeds.report_markdown`: each seed's success with its two-stage
interval over layouts, its kept checkpoint's validation success, the aggregate over seeds, the
IQM from 4 seeds on and the mean below, saying so, and the seed chosen on validation), the spread
across seeds, and the progress of the seeds the driver plans by default
(:func:`evaluation.experiments.seeds_published.planned_seeds`, ``data/training/run.sh``) that are not on it
yet, each named. A seed published partial (its run interrupted) is named with its episodes and left
out of the tables. While the publication is missing the page says so (:func:`pending_page`) and
how to publish it, with the same progress statement and no test number.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing
sys.path.insert(0, str(Path(__file__).resolve().parent))  # the page scripts beside this one

from page_writer import write_publication_page  # noqa: E402

from evaluation.experiments.seeds import TRAINING_ROOT, finished_seeds, report_markdown  # noqa: E402
from evaluation.experiments.seeds_published import (  # noqa: E402
    DRIVER,
    PublishedSeeds,
    planned_seeds,
    read_publication,
)
from evaluation.reports.publications import extracted_archive  # noqa: E402

TITLE = "Learned policies over training seeds"
#: the run of data/publish.sh behind the page, and the page
RUN = "seeds"
PAGE = "docs/seeds_results.md"


def _regenerate(publication: Path) -> str:
    return (
        f"the run is `bash data/publish.sh {RUN}` (resumable: each task's log is resumed, and a seed "
        f"finished later joins it), then `bash data/publish.sh pack`, which writes `{publication.as_posix()}`; "
        f"then `python docs/make_pages.py {PAGE}` rebuilds this page"
    )


def _seed(policy: str, task: str, seed: int) -> str:
    return f"`{policy}` {task} seed {seed}"


def progress_lines(
    training: Path, driver: Path, published: PublishedSeeds | None
) -> tuple[int, int, list[str]]:
    """The planned seeds (the driver's defaults), how many are on the page, and one line per
    planned seed that is not: published partial, finished but not evaluated, or not finished.
    Without a publication every planned seed is "not evaluated yet", whatever its training state:
    the pending page does not change each time a seed finishes training (docs/benchmark.md's
    seed paragraph states that, checked by tests/test_prose_checks.py)."""
    planned = planned_seeds(driver)
    progress = {} if published is None else published.progress
    lines, shown = [], 0
    for policy, task, seed in planned:
        state = progress.get((policy, task, seed))
        if state is not None and state.complete:
            shown += 1
            continue
        if published is None:
            why = 'not evaluated yet (which seeds finished training: docs/benchmark.md, "Learned policies")'
        elif state is not None:
            why = f"evaluation in progress ({state.done:,} of {state.planned:,} episodes published), left out of the tables"
        elif seed in {r.seed for r in finished_seeds(training, policy, task)}:
            why = "finished training, not evaluated yet"
        else:
            why = f"training not finished (no `finished.json` in its seed folder under `{training.as_posix()}/`)"
        lines.append(f"- {_seed(policy, task, seed)}: {why}")
    return shown, len(planned), lines


def _plan(driver: Path) -> str:
    planned = planned_seeds(driver)
    policies = list(dict.fromkeys(p for p, _, _ in planned))
    tasks = list(dict.fromkeys(t for _, t, _ in planned))
    seeds = max(k for _, _, k in planned)
    return (
        f"`{driver.as_posix()}`'s defaults: {' and '.join(f'`{p}`' for p in policies)}, "
        f"{' and '.join(tasks)}, seeds 0-{seeds}"
    )


def progress_section(training: Path, driver: Path, published: PublishedSeeds | None) -> str:
    """The progress statement: how many planned seeds are on the page, and each one that is not."""
    shown, planned, missing = progress_lines(training, driver, published)
    head = f"## Progress\n\nOn this page: {shown} of the {planned} planned seed runs ({_plan(driver)})."
    if not missing:
        return head + " Every planned seed is evaluated.\n"
    return head + f" Not on it yet ({len(missing)}):\n\n" + "\n".join(missing) + "\n"


def spread_table(published: PublishedSeeds) -> str:
    """Per (policy, task): the lowest and highest per-seed success and their distance in points,
    and the seed chosen on validation with its validation success."""
    split = published.split
    rows = [
        f"| policy | task | seeds | lowest seed's {split} success | highest | spread across seeds "
        "| chosen on validation (its validation success) |",
        "|---|---|---|---|---|---|---|",
    ]
    for s in published.summaries:
        rates = [rate for rate, _, _ in s["aggregate"].per_seed.values()]
        chosen = s["chosen"]
        rows.append(
            f"| `{s['policy']}` | {s['task']} | {len(rates)} | {100 * min(rates):.1f}% | {100 * max(rates):.1f}% "
            f"| {100 * (max(rates) - min(rates)):.1f} points | seed {chosen.seed} "
            f"({chosen.validation['successes']}/{chosen.validation['episodes']}) |"
        )
    return "\n".join(rows) + "\n"


def pending_page(publication: Path, training: Path, driver: Path) -> str:
    """The page while the publication is missing: what it will hold, how to make it, and the
    seeds' progress (no test number)."""
    return (
        f"# {TITLE}\n\n"
        f"**Pending: the seeds are not published yet** (`{publication.as_posix()}` is missing). To publish "
        f"them: {_regenerate(publication)}. The run plays every finished training seed (a "
        f"controller `<policy>@seed<k>` whose `policy_root` is its seed folder) on the test split of "
        "koopnav-bench-v1, on the same (layout, episode) units; the page then gives each seed's test "
        "success with its interval over layouts and its kept checkpoint's validation success, the "
        "aggregate over seeds (the interquartile mean from 4 seeds on, the mean below), the spread "
        'across seeds and the seed chosen on validation (docs/benchmark.md, "Learned policies").\n\n'
        + progress_section(training, driver, None)
    )


def page(publication: Path, training: Path, driver: Path) -> str:
    """The page of the published seeds run ``publication`` (``data/seeds``)."""
    with extracted_archive(publication) as run:
        try:
            published = read_publication(run, training)
        except ValueError as exc:  # named by the publication, not by its scratch copy
            where = str(exc).replace(f"{run.parent}/", "")
            raise ValueError(
                f"{publication}: not a seeds publication as data/publish.sh packs it: {where}"
            ) from None
    split = published.split
    labels = "; ".join(f"{task}: `{label}`" for task, label in published.suites.items())
    warning = (
        ""
        if split == "test"
        else f"**This publication ran on the {split} split, not on test: it is not the benchmark's result.**\n\n"
    )
    data = (
        f"Rebuilt from the committed episode logs `{publication.as_posix()}` ({published.episodes:,} episodes) "
        f"and the seeds' validation records (`selection.json` in each seed folder under "
        f"`{training.as_posix()}/`) by `python docs/make_pages.py {PAGE}`, byte for byte "
        f"(`tests/test_seeds_page.py`); {_regenerate(publication)}. Each seed is a controller "
        f"`<policy>@seed<k>` that plays its kept checkpoint, every seed on the same (layout, episode) "
        f"units of the {split} split ({labels or 'no seed complete yet'}). The chosen seed is the one with "
        "the best validation success of its kept checkpoint, whatever its test result "
        "(`evaluation.experiments.seeds.chosen_seed`)."
    )
    tables = (
        "## Per seed and over seeds\n\n"
        "Each seed's success with its 95% interval over layouts (two-stage: layouts, then episodes "
        "within them), and the aggregate over seeds (rliable's interquartile mean over the seeds' "
        "success rates, with an interval that re-draws the layouts; with fewer than 4 seeds the IQM trims "
        "nothing and the mean leads, as the table says).\n\n"
        + report_markdown(published.summaries, split)
        + "\n## Spread across seeds\n\n"
        + "The lowest and highest per-seed success rate and their distance.\n\n"
        + spread_table(published)
        if published.summaries
        else "No seed has every planned episode published yet: no table.\n"
    )
    return f"# {TITLE}\n\n{warning}{data}\n\n{tables}\n" + progress_section(training, driver, published)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("publication", help="the published seeds run, data/seeds (or NAME.tar.xz)")
    # no default page: the published one is a tracked file (docs/make_pages.py names it)
    parser.add_argument("--out", required=True, help=f"the page to write, e.g. {PAGE}")
    parser.add_argument(
        "--training", default=str(TRAINING_ROOT), help="the seed folders (default data/training)"
    )
    parser.add_argument(
        "--driver",
        default=str(DRIVER),
        help="the seed driver whose defaults are the plan (default data/training/run.sh)",
    )
    parser.add_argument("--figures", help="accepted for docs/make_pages.py; the page has no figures")
    args = parser.parse_args(argv)
    publication, training, driver = Path(args.publication), Path(args.training), Path(args.driver)
    return write_publication_page(
        args.out,
        publication,
        lambda: page(publication, training, driver),
        lambda: pending_page(publication, training, driver),
        RUN,
    )


if __name__ == "__main__":
    raise SystemExit(main())
