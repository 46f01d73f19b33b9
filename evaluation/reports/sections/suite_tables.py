"""A suite run's tested tables in its report (:mod:`evaluation.stats.suite_statistics`): each controller's
outcomes and metrics with their intervals over layouts, and one paired table per outcome and per
metric, each with its family and its power statement. Reports of runs without a suite have none.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from typing import Any

from evaluation.reports.sections.blocks import (
    Block,
    Note,
    Section,
    Table,
    TableBlock,
    number_cell,
    p_cell,
    rate_cell,
)
from evaluation.stats.run_data import RunData
from evaluation.stats.suite_statistics import MEASURES, METRICS, OUTCOMES, Measure
from koopman_envs import TASKS
from koopman_envs.params import PATH_RATIO_MIN_DISTANCE, STRICT_CLEARANCE_MARGIN

__all__ = [
    "SUITE_METRICS_NOTE",
    "PAIRED_CSV_COLUMNS",
    "SUITE_PAIRED_NOTE",
    "paired_csv",
    "paired_note",
    "paired_table",
    "suite_sections",
    "summary_rows",
]

_LABELS = {spec.env_id: spec.label for spec in TASKS.values()}

SUITE_METRICS_NOTE = (
    "Per controller, over its distinct episodes that ran: rates with the wider of Wilson's interval and "
    "the two-stage bootstrap over layouts, then episodes within them; metrics' means with the two-stage "
    f"bootstrap. Strict success: a success whose clearance stayed above {100 * STRICT_CLEARANCE_MARGIN:.0f} cm "
    "from every obstacle, team-mate and mover all episode. Success excusing unavoidable collisions: a "
    "success, or an episode ended by a collision that was no robot's fault after the team had arrived "
    "(docs/movers.md, 'Who is at fault'). Min clearance: the episode's smallest surface clearance to an "
    "obstacle, team-mate or mover (negative: a collision). Near obstacle: the share of periods that "
    f"ended within {100 * STRICT_CLEARANCE_MARGIN:.0f} cm of an obstacle (mean over robots). Time to goal "
    "and path ratio over successes only (a failed team has no arrival time, and its path ends early); "
    f"path ratio: per robot its path over the straight line to its target (robots starting within "
    f"{100 * PATH_RATIO_MIN_DISTANCE:.0f} cm of it left out), mean over robots. Jerk: RMS second "
    "difference of the speed command over dt^2 (mean over robots). docs/benchmark.md defines them."
)


def paired_note(design: str) -> str:
    """The note above a run's paired tables, whose families are ``design`` (what each table tests,
    as a clause: ``"every pair of controllers of each task"``)."""
    return (
        "Every table compares two controllers of a task on the (layout, seed) units both ran (a metric "
        "defined on successes: the units both won), with the layout as the unit: a minus b with its 95% "
        "two-stage bootstrap interval (layouts, then units within them), and the two-sided layout "
        "sign-flip test (exact up to 16 layouts with a non-zero difference, else 20,000 random sign "
        "patterns). Each table is one family of tests, declared from the run's design before any test "
        f"({design}; a pair without a shared unit counts as p = 1), and "
        "Holm's adjustment runs within it. Below each table: the family, its size m and the smallest "
        "paired difference it finds with 80% power at Holm's first step (alpha/m), from the measured "
        "discordance (rates) or SD of the differences (metrics) and the between-layout correlation."
    )


SUITE_PAIRED_NOTE = paired_note("every pair of controllers of each task")


def _task(env_id: str) -> str:
    return _LABELS.get(env_id, env_id)


def _mean_cell(value: float, ci: list[float], digits: int) -> str:
    if value is None or math.isnan(value):
        return "-"
    return f"{value:.{digits}f} [{ci[0]:.{digits}f}, {ci[1]:.{digits}f}]"


def _heading(measure: Measure) -> str:
    text = measure.label[0].upper() + measure.label[1:]
    return f"{text} [{measure.unit}]" if measure.unit else text


#: the short column names of the summary table, by measure
_COLUMNS = {
    "success": "Success",
    "strict_success": "Strict success",
    "success_excusing_unavoidable": "Success excusing unavoidable",
    "clearance_cm": "Min clearance [cm]",
    "near_obstacle_share": "Near obstacle (share)",
    "time_to_goal_s": "Time to goal [s]",
    "path_ratio": "Path ratio",
    "jerk_rms": "Jerk RMS [m/s³]",
}


def summary_rows(results: RunData) -> Table:
    """Each (task, controller)'s outcomes and metrics with their intervals over layouts."""
    header = ["Task", "Controller", *(_COLUMNS[m.key] for m in MEASURES)]
    rows = []
    for row in results.layout_summary:
        cells = []
        for measure in MEASURES:
            entry = row[measure.key]
            if measure.binary:
                cells.append(rate_cell(entry["value"], entry["ci"]))
            else:
                cells.append(_mean_cell(entry["value"], entry["ci"], measure.digits))
        rows.append([_task(row["env_id"]), row["controller"], *cells])
    return header, rows


def _difference_cell(row: Mapping[str, Any], measure: Measure) -> str:
    scale, digits = (100.0, 0) if measure.binary else (1.0, measure.digits)
    return (
        f"{scale * row['difference']:+.{digits}f} "
        f"[{scale * row['low']:+.{digits}f}, {scale * row['high']:+.{digits}f}]"
    )


def paired_table(table: Mapping[str, Any], measure: Measure) -> Table:
    """One measure's paired rows (:func:`evaluation.stats.suite_statistics.measure_table`) as a report table."""
    unit = "points, " if measure.binary else (f"{measure.unit}, " if measure.unit else "")
    header = ["Task", "a", "b", "Layouts", "Pairs", "a", "b", f"a - b [{unit}95% CI]"]
    if measure.binary:
        header += ["only a / only b", "P(a > b)"]
    header += ["Sign-flip p", "Holm p"]
    rows = []
    for r in table["rows"]:
        if measure.binary:
            means = [f"{100 * r['rate_a']:.0f}%", f"{100 * r['rate_b']:.0f}%"]
        else:
            means = [
                number_cell(r["mean_a"], f"{{:.{measure.digits}f}}"),
                number_cell(r["mean_b"], f"{{:.{measure.digits}f}}"),
            ]
        extra = [f"{r['only_a']} / {r['only_b']}", f"{r['prob_improvement']:.2f}"] if measure.binary else []
        rows.append(
            [
                _task(r["env_id"]),
                r["a"],
                r["b"],
                str(r["layouts"]),
                str(r["n"]),
                *means,
                _difference_cell(r, measure),
                *extra,
                p_cell(r["p_value"]),
                p_cell(r["p_holm"]) if not math.isnan(r["p_holm"]) else "-",
            ]
        )
    return header, rows


#: the columns of :func:`paired_csv`: the run, the table's measure and its family's size ``m`` (the
#: family is the table: its name is the run's and the measure's), then the row's
#: fields (``mean_a``/``mean_b``: a rate or a metric's mean; ``only_a``/``only_b``: a rate's
#: discordant units, empty for a metric)
PAIRED_CSV_COLUMNS = (
    "run",
    "measure",
    "m",
    "task",
    "a",
    "b",
    "layouts",
    "pairs",
    "mean_a",
    "mean_b",
    "difference",
    "low",
    "high",
    "only_a",
    "only_b",
    "p",
    "p_holm",
    "rejected",
)


def _csv_number(value: Any) -> str:
    # 6 significant digits: what a reader needs, and a file whose versions delta well in git
    return "" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.6g}"


def paired_csv(runs: Sequence[tuple[str, Sequence[Mapping[str, Any]]]]) -> str:
    """Paired tables as CSV text, one line per row (:data:`PAIRED_CSV_COLUMNS`): for each
    ``(run, tables)`` of ``runs`` (a name and its tables,
    :func:`evaluation.stats.suite_statistics.suite_tables`), every table's rows with its family's
    size, in order. Holm's p is the one of that family."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(PAIRED_CSV_COLUMNS)
    for run, tables in runs:
        for table in tables:
            family = table["family"]
            for r in table["rows"]:
                writer.writerow(
                    [run, table["measure"], family["size"], _task(r["env_id"]), r["a"], r["b"]]
                    + [r["layouts"], r["n"], _csv_number(r["mean_a"]), _csv_number(r["mean_b"])]
                    + [_csv_number(r[k]) for k in ("difference", "low", "high")]
                    + [r.get("only_a", ""), r.get("only_b", ""), _csv_number(r["p_value"])]
                    + [_csv_number(r.get("p_holm")), int(bool(r.get("rejected")))]
                )
    return buffer.getvalue()


def _family_note(table: Mapping[str, Any]) -> str:
    family = table["family"]
    if table["power"] is not None:
        text = table["power"]["sentence"]
    else:
        text = f"Family {family['family']!r}: m = {family['size']} tests, none run."
    rejected = [t["comparison"] for t in family["tests"] if t["rejected"]]
    verdict = (
        f" Rejected at alpha = {family['alpha']:g} after Holm: {', '.join(rejected)}."
        if rejected
        else (f" None rejected at alpha = {family['alpha']:g} after Holm.")
    )
    return f"Over the {table['where']}. {text}{verdict}"


def suite_sections(
    results: RunData, tables: Sequence[Mapping[str, Any]] | None = None, note: str = SUITE_PAIRED_NOTE
) -> list[Section]:
    """A suite run's sections: outcomes and metrics per controller, then the paired tables, each
    with its family and power; empty for a run without a suite. ``tables``: the paired tables
    (default the run's own, every pair: ``results.suite_tables``; a page that tests a narrower
    family passes its own, :func:`evaluation.stats.suite_statistics.suite_tables` with ``pairs``),
    and ``note`` the note above them that names their families (:func:`paired_note`)."""
    tables = results.suite_tables if tables is None else tables
    if not tables:
        return []
    summary = Section(
        "suite-metrics",
        "Outcomes and metrics over layouts",
        (Note(SUITE_METRICS_NOTE), TableBlock(summary_rows(results))),
    )
    blocks: list[Block] = [Note(note)]
    by_key = {m.key: m for m in (*OUTCOMES, *METRICS)}
    for table in tables:
        measure = by_key[table["measure"]]
        caption = f"Paired: {_heading(measure)}"
        if table["rows"]:
            blocks.append(TableBlock(paired_table(table, measure), caption))
        else:  # nothing to show but the family, which still counts its tests
            blocks.append(Note(f"{caption}: no pair of controllers shares a unit with a value."))
        blocks.append(Note(_family_note(table)))
    return [summary, Section("paired", "Paired comparisons over layouts", tuple(blocks))]
