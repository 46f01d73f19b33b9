"""Write docs/bench_results.md, and README.md's headline block, from the published test-suite runs
of koopnav-bench-v1 (issue 60: the README headline becomes the test suite's leaderboard, the paper
track after it).

Usage (the published page's arguments are in ``data/pages.json``)::

    python docs/make_bench_md.py --charged data/bench_test_realtime --free data/bench_test \\
        --paper data/paper.tar.xz --reference koopman-nmpc --out docs/bench_results.md

``--charged`` and ``--free`` are the publications of ``bash data/publish.sh bench_test_realtime``
(the decision time charged to the robots, ``--realtime``: the headline) and ``bench_test`` (free
compute, the idealised case beside it), each packed by ``bash data/publish.sh pack``; the two
runs may hold different controllers (a controller of one only is in that mode's tables only).
Every number is the evaluator's own (:class:`~evaluation.stats.run_data.RunData`:
``layout_summary``, ``suite_breakdown``; :func:`~evaluation.stats.suite_statistics.suite_tables`:
intervals over layouts, the paired tables with their families and power statements); this script
only lays them out. The page's primary test is its headline family per mode
(:func:`headline_families`), declared from the run's header: success of every controller against
``--reference`` pooled over both tasks (each (task, layout) its own cluster), Holm within it, with
what tuning gained (each tuned controller against its ``-v0``, pooled) as a family of its own. The
per-task paired tables are secondary, one family per table and mode, declared from the
run's header (:func:`page_pairs`): every controller against ``--reference``, and each tuned
controller against its ``-v0``; every pair of every table, each table corrected over every pair,
goes to ``bench_pairs.csv`` beside the page (:data:`PAIRS_FILE`), whose SHA-256 the page states.
Beside the leaderboard, which verdicts changed: each controller against ``--reference`` on the test
split and on the paper track, with a verdict by a stated rule (:func:`verdict_changes`,
:data:`VERDICT_RULE`). The tuning budget of each controller is its study in ``data/tuning/<name>/``
(:func:`controllers.tuning.studies.study_budget`).

A run may be partial (published progressively): a (task, controller) whose episodes are not all
in its publication is named as pending, with how many it has, and left out of every table and
test until it is complete; a publication not there yet makes its whole column pending. The page
opens with the headline block (:data:`HEADLINE`) that ``python docs/make_pages.py`` copies into
README.md (``"readme"`` in ``data/pages.json``); tests/test_prose_checks.py checks README's copy
against the page.
"""

from __future__ import annotations

import argparse
import hashlib
import math
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing
sys.path.insert(0, str(ROOT / "docs"))  # the README headline's module beside this one

from bench_headline import HEADLINE, headline, shipped_before_clause  # noqa: E402

from controllers.tuning import STUDIES_DIR  # noqa: E402
from evaluation.episodes.distinct import distinct_records  # noqa: E402
from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT  # noqa: E402
from evaluation.reports.bench import (  # noqa: E402
    BENCH_RUNS,
    PLANNED_DISCORDANCE,
    VERDICT_RULE,
    BenchMode,
    check_same_suite,
    declared_tasks,
    family_pending,
    headline_families,
    leaderboard_cells,
    load_mode,
    page_pairs,
    pairs_file,
    paper_variants_note,
    planned_power,
    verdict,
    verdict_changes,
)
from evaluation.reports.publications import extracted_archive  # noqa: E402
from evaluation.reports.published import results_from_log  # noqa: E402
from evaluation.reports.results import Results  # noqa: E402
from evaluation.reports.sections import markdown, markdown_table, suite_heading, task_label  # noqa: E402
from evaluation.reports.sections.blocks import p_cell  # noqa: E402
from evaluation.reports.sections.runs import SUITE_NOTE, suite_rows  # noqa: E402
from evaluation.reports.sections.suite_tables import paired_note, paired_table, suite_sections  # noqa: E402
from evaluation.stats.designs import pooled_families, tuned_pairs  # noqa: E402
from evaluation.stats.suite_statistics import OUTCOMES, measure_table, suite_tables  # noqa: E402
from evaluation.tune.report import decision, tuning_budget_rows  # noqa: E402
from koopman_envs.files import write_atomic  # noqa: E402

__all__ = [
    "HEADLINE",
    "PAIRS_FILE",
    "decision",
    "headline",
    "headline_families",
    "load_mode",
    "page",
    "option_values",
    "page_pairs",
    "pairs_file",
    "pooled_families",
    "published_runs",
    "tuned_pairs",
    "verdict",
    "verdict_changes",
]

#: the runs of data/publish.sh behind the two modes, and their titles (docs/make_sizing.py reads them)
RUNS = BENCH_RUNS
#: the headline's note on the ``*-paper`` rows (tests/test_bench_page.py reads it by this name)
_paper_variants_note = paper_variants_note
#: the file beside the page with every pair of every paired table (the page tests fewer): plain
#: CSV in the repository, whose next version git stores as a delta of this one (docs/benchmark.md)
PAIRS_FILE = "bench_pairs.csv"


def published_runs(script: Path = ROOT / "data" / "publish.sh") -> dict[str, list[str]]:
    """data/publish.sh's runs as bash expands them: NAME -> evaluate.py's arguments (the script's
    definitions only; nothing is run)."""
    text = script.read_text(encoding="utf-8")
    definitions = text[: text.index("\nrun() {")]
    show = 'for name in "${!RUNS[@]}"; do printf "%s\\t%s\\n" "$name" "${RUNS[$name]}"; done'
    printed = subprocess.run(
        ["bash", "-c", f"{definitions}\n{show}", str(script)], capture_output=True, text=True, check=True
    ).stdout
    return {name: words.split() for name, words in (line.split("\t", 1) for line in printed.splitlines())}


def option_values(arguments: Sequence[str], option: str) -> list[str]:
    """The words after ``option`` in ``arguments`` up to the next option (``--controllers``' labels)."""
    start = list(arguments).index(option) + 1
    end = next((i for i in range(start, len(arguments)) if arguments[i].startswith("--")), len(arguments))
    return list(arguments[start:end])


def _headline_family(mode: BenchMode, pairs: list[tuple[str, str, str]], design: str) -> list[str]:
    """One pooled family's table: the pairs of controllers complete in both tasks tested, the
    others named as pending (counted in m as p = 1), Holm within the family, its power."""
    assert mode.results is not None
    tasks = list(mode.declared())
    complete = {label for _, label in mode.progress if all(mode.pending(t, label) is None for t in tasks)}
    records = [r for r in mode.results.records if r["controller"] in complete]
    m = len(pairs)
    planned = planned_power(mode, m)
    found = (
        f"it finds {100 * planned:.1f} points"
        if not math.isnan(planned)
        else "no difference is found with that power on so few layouts"
    )
    lines = [
        f"m = {m} tests, declared from the run's header. By the run's design, at 80% power after "
        f"Holm's first step and discordance psi = {PLANNED_DISCORDANCE}, {found} (docs/benchmark.md, "
        "Statistics, the sizing).",
        "",
    ]
    table = measure_table(records, OUTCOMES[0], pairs, design) if records else None
    if table is not None and table["rows"]:
        lines += [markdown_table(paired_table(table, OUTCOMES[0])), ""]
        family = table["family"]
        rejected = [t["comparison"] for t in family["tests"] if t["rejected"]]
        power = table["power"]["sentence"] if table["power"] is not None else ""
        lines += [
            f"{power} "
            + (
                f"Rejected at alpha = {family['alpha']:g} after Holm: {', '.join(rejected)}."
                if rejected
                else f"None rejected at alpha = {family['alpha']:g} after Holm."
            ),
            "",
        ]
    pending = family_pending(mode, pairs)
    if pending:
        lines += [
            "Pending until both controllers are complete in both tasks (counted in m as p = 1): "
            + "; ".join(pending)
            + ".",
            "",
        ]
    return lines


def _headline_section(modes: Sequence[BenchMode], reference: str) -> list[str]:
    """The headline families of every published mode, before the per-task tables."""
    published = [mode for mode in modes if mode.results is not None]
    if not published:
        return []
    lines = [
        "## The headline family: success over both tasks",
        "",
        f"The page's primary test, per mode: success of each controller against {reference}, pooled "
        "over both tasks (a comparison's units are the (task, layout) units of both tasks that both "
        "controllers ran), declared from the run's header before any "
        "outcome and corrected with Holm within its own family. Each (task, layout) is its own "
        "cluster (layout 3 of one task and layout 3 of the other are two layouts): a minus "
        f"{reference} with the two-stage bootstrap interval over those layouts and the layout "
        "sign-flip test, as in every paired table. The tuned controllers against their `-v0` "
        "(what tuning gained, free compute) are a family of their own after it: another question "
        "than the headline's, so it does not spend the headline's power. The per-task tables of "
        "each mode (its section below) are secondary families.",
        "",
    ]
    for mode in modes:
        if mode.results is None:
            what = "not published yet" if not mode.progress else "no controller complete in both tasks yet"
            lines += [f"**{RUNS[mode.name][1]}**: pending, {what}.", ""]
            continue
        for pairs, design in headline_families(mode, reference):
            lines += [f"**{RUNS[mode.name][1]}: {design}**", "", *_headline_family(mode, pairs, design)]
    return lines


def _runs_section(modes: Sequence[BenchMode]) -> list[str]:
    lines = ["## The runs", ""]
    for mode in modes:
        run, title = RUNS[mode.name]
        command = f"the run `{run}` of data/publish.sh"
        if not mode.progress:
            lines.append(
                f"- **{title}** ({command}): pending, `{mode.path.as_posix()}` is not published yet "
                f"(`bash data/publish.sh {run}`, then `bash data/publish.sh pack`)."
            )
            continue
        pending = [
            f"{task_label(e)} {c} ({p.text().removeprefix('pending: ')})"
            for (e, c), p in mode.progress.items()
            if not p.complete
        ]
        episodes = 0 if mode.results is None else len(distinct_records(mode.results.records))
        lines.append(
            f"- **{title}** ({command}, `{mode.path.as_posix()}`): {episodes:,} distinct episodes of complete rows"
            + (f"; pending: {'; '.join(pending)}." if pending else "; every row complete.")
        )
        if mode.results is not None:
            compute = mode.results.config.get("compute")
            machine = f" Decision times measured on {compute['machine']}." if compute else ""
            lines.append(f"  {suite_heading(mode.results.config)}.{machine}")
    return lines + [""]


def _leaderboard_section(modes: Sequence[BenchMode]) -> list[str]:
    names = {o.key: o.label for o in OUTCOMES}
    lines = [
        "## Leaderboard: compute charged beside free compute",
        "",
        "Per task, ranked by success with compute charged. Each outcome with compute charged, then "
        "free: success; " + names["strict_success"] + "; success excusing the "
        "collisions no robot could avoid. Rates with the wider of Wilson's interval and the two-stage "
        "bootstrap over layouts, then episodes.",
        "",
    ]
    header = ["Controller"] + [
        f"{head}, {mode}"
        for head in ("Success", "Strict", "Excusing unavoidable")
        for mode in ("charged", "free")
    ]
    for env_id in declared_tasks(modes):
        rows = leaderboard_cells(modes, env_id)
        lines += [f"**{task_label(env_id)}**", "", markdown_table((header, rows)), ""]
    return lines


def _breakdown_section(modes: Sequence[BenchMode]) -> list[str]:
    lines = ["## By layout tier and family", "", SUITE_NOTE, ""]
    for mode in modes:
        if mode.results is None:
            continue
        title = RUNS[mode.name][1]
        for by, what in (("layout_tier", "tier"), ("layout_family", "family")):
            lines += [f"**{title}, by {what}**", "", markdown_table(suite_rows(mode.results, by)), ""]
    return lines


def tuning_budget(labels: Sequence[str], studies: Path = STUDIES_DIR) -> list[str]:
    """A table of each controller's tuning budget: its study (:func:`controllers.tuning.studies.study_budget`),
    or why it has none."""
    lines = [
        "## Tuning budget",
        "",
        "What each controller's shipped defaults cost to find: its study on the validation split "
        "(`data/tuning/<name>/`, docs/benchmark.md), every study with the same budget and objective.",
        "",
        "| Controller | Tuned on | Configurations run | Validation episodes per configuration | Episodes | Decision |",
        "|---|---|---|---|---|---|",
    ]
    lines += ["| " + " | ".join(row) + " |" for row in tuning_budget_rows(labels, studies)]
    return lines + [""]


def _mode_tables(mode: BenchMode, reference: str) -> tuple[list[dict[str, Any]], str] | None:
    """``mode``'s tested tables on the page's design and the design's clause (None: no rows yet);
    computed once, the verdict table and the tested section both read them."""
    if mode.results is None:
        return None
    pairs, design = page_pairs(mode, reference)
    return suite_tables(mode.results.records, pairs, design), design


def _success_rows(tables: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The rows of the success table among a mode's tested tables."""
    return next(list(table["rows"]) for table in tables if table["measure"] == OUTCOMES[0].key)


def _verdicts_section(
    modes: Sequence[BenchMode], tested: Mapping[str, Any], paper: Results | None, reference: str
) -> list[str]:
    """Per published mode, every controller paired with ``reference`` on both the test split and the
    paper track: the two differences, their corrected p and what became of the verdict."""
    lines = [
        "## Which verdicts changed: the test split against the paper track",
        "",
        f"Each controller against {reference}, success: its difference on the test split (the page's "
        "success table) and on the paper track (free compute; its rows ran with the defaults they "
        f"were published with, the hand-set ones for a controller tuned later{shipped_before_clause()}). "
        + VERDICT_RULE,
        "",
    ]
    if paper is None:
        return lines + ["The paper track is not published: nothing to compare with yet.", ""]
    header = [
        "Task",
        "Controller",
        "Test split a - ref",
        "Holm p",
        "Paper track a - ref",
        "Holm p",
        "Verdict",
    ]
    for mode in modes:
        if tested.get(mode.name) is None:
            continue
        rows = [
            [
                task_label(row["env_id"]),
                row["controller"],
                f"{100 * row['test'][0]:+.0f}",
                "-" if math.isnan(row["test"][1]) else p_cell(row["test"][1]),
                f"{100 * row['paper'][0]:+.0f}",
                "-" if math.isnan(row["paper"][1]) else p_cell(row["paper"][1]),
                row["verdict"],
            ]
            for row in verdict_changes(_success_rows(tested[mode.name][0]), paper.paired(), reference)
        ]
        table = (
            markdown_table((header, rows)) if rows else f"No controller is paired with {reference} on both."
        )
        lines += [f"**{RUNS[mode.name][1]}**", "", table, ""]
    return lines


def _tested_section(mode: BenchMode, tested: tuple[list[dict[str, Any]], str] | None) -> list[str]:
    if mode.results is None or tested is None:
        return []
    title = RUNS[mode.name][1]
    tables, design = tested
    text = markdown(suite_sections(mode.results, tables, paired_note(design))).replace("\n## ", "\n### ")
    secondary = (
        "The paired tables of this section are secondary families, within each task (the headline "
        "family, over both tasks, is above)."
    )
    return [
        f"## {title}: outcomes, metrics and paired tests",
        "",
        secondary,
        "",
        "### " + text.removeprefix("## "),
        "",
    ]


def _pairs_section(pairs: str) -> list[str]:
    rows = pairs.count("\n") - 1
    digest = hashlib.sha256(pairs.encode()).hexdigest()
    return [
        "## Every pair",
        "",
        "The paired tables below test the pairs this page reads: per mode and per table one family, "
        "declared from the run's header and corrected with Holm within it (named under each table). "
        f"Every pair of each mode's controllers, for every table, is in [{PAIRS_FILE}]({PAIRS_FILE}) "
        f"({rows:,} rows; SHA-256 `{digest}`), each table there one family over every pair within "
        "each task (its size in the column `m`): a larger family, so a pair's Holm p there is no "
        "smaller than on this page.",
        "",
    ]


def page(
    modes: Sequence[BenchMode],
    paper: Results | None,
    reference: str,
    studies: Path = STUDIES_DIR,
    paper_path: str = "data/paper.tar.xz",
    pairs: str | None = None,
) -> str:
    """The page's Markdown: the headline block, the runs, the leaderboard, which verdicts changed
    from the paper track (:func:`verdict_changes`; once a mode has rows), the breakdowns, the
    tuning budget, where every pair is (``pairs``: :data:`PAIRS_FILE`'s text, :func:`pairs_file`)
    and each mode's tested tables against ``reference`` (:func:`page_pairs`)."""
    labels = list(dict.fromkeys(c for mode in modes for _, c in mode.progress))
    lines = [
        "# koopnav-bench-v1: results on the held-out test split",
        "",
        "The primary controllers on the test split of koopnav-bench-v1 (docs/benchmark.md), which no "
        "controller was tuned or trained on, with the decision time charged to the robots (the "
        "headline) and with free compute beside it, where the hand-set defaults the tuned presets "
        "replaced (`-v0`) run too; the variants are on their own pages (docs/benchmark.md, "
        '"Running the benchmark", says which and why). Written by `docs/make_bench_md.py` from the '
        "committed publications; a (task, controller) still running is named as pending and left "
        "out of every table and test.",
        "",
        headline(modes, paper, paper_path).rstrip("\n"),
        "",
        *_runs_section(modes),
    ]
    tested = {mode.name: _mode_tables(mode, reference) for mode in modes}
    lines += _headline_section(modes, reference)
    if any(mode.results is not None for mode in modes):
        lines += _leaderboard_section(modes)
        lines += _verdicts_section(modes, tested, paper, reference)
        lines += _breakdown_section(modes)
    lines += tuning_budget(labels, studies) if labels else []
    lines += _pairs_section(pairs) if pairs is not None else []
    for mode in modes:
        lines += _tested_section(mode, tested[mode.name])
    return "\n".join(lines).rstrip("\n") + "\n"


def _paper(path: str | None) -> Results | None:
    if path is None or not Path(path).exists():
        return None
    with extracted_archive(path) as run:
        return results_from_log(run / "episodes.jsonl")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--charged", required=True, help="the compute-charged publication, data/bench_test_realtime"
    )
    parser.add_argument("--free", required=True, help="the free-compute publication, data/bench_test")
    parser.add_argument("--paper", help="the paper track's publication, data/paper.tar.xz")
    parser.add_argument(
        "--reference",
        required=True,
        help="the controller the page's paired tables compare every other one with (koopman-nmpc)",
    )
    parser.add_argument(
        "--studies", type=Path, default=STUDIES_DIR, help="the tuning studies (default data/tuning)"
    )
    parser.add_argument("--out", required=True, help="the page to write, e.g. docs/bench_results.md")
    parser.add_argument("--figures", help="accepted for docs/make_pages.py; the page has no figures")
    args = parser.parse_args(argv)
    try:
        modes = [load_mode("charged", args.charged), load_mode("free", args.free)]
        check_same_suite(modes)
        pairs = pairs_file(modes)
        paper_path = args.paper or "data/paper.tar.xz"
        text = page(modes, _paper(args.paper), args.reference, args.studies, paper_path, pairs)
    except ValueError as exc:  # a publication that is not as KoopNav packs it, or the wrong run
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    if pairs is not None:
        write_atomic(Path(args.out).with_name(PAIRS_FILE), pairs)
    write_atomic(args.out, text)
    missing = [m.path.as_posix() for m in modes if m.results is None and not m.progress]
    print(f"wrote {args.out}" + (f" (pending: {', '.join(missing)} not published yet)" if missing else ""))
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
