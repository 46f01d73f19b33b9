"""A sweep's report, built as sections (:mod:`evaluation.reports.sections.blocks`) like a run's: the
overview of every axis, and per axis the summary over the sweep and the table of every level,
from the profiles :func:`evaluation.stats.robustness.profiles` computes; and the overview a terminal
gets after a sweep.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from evaluation.reports.sections.blocks import (
    Block,
    Note,
    Section,
    TableBlock,
    interval_cell,
    level_text,
    markdown_table,
)
from evaluation.stats.designs import table_power
from evaluation.stats.robustness import TAIL_SHARE, AxisProfile, LevelCost

__all__ = [
    "SWEEP_UNIT",
    "level_cost_power_note",
    "level_cost_section",
    "level_power_note",
    "overview_section",
    "robustness_sections",
    "terminal_overview",
]


def terminal_overview(axes: Sequence[AxisProfile]) -> str:
    """What a terminal gets after a sweep: per axis, every controller's success at each level
    (distinct episodes, %), the controllers ranked by their success over the axis (AUC).

    Parameters
    ----------
    axes : sequence of AxisProfile
        The profiles (:func:`evaluation.stats.robustness.profiles`).

    Returns
    -------
    str
        Markdown: a table per axis, then a note on where the intervals and figures are.
    """
    blocks = []
    for profile in axes:
        header = ["Controller", *(f"{profile.key}={level_text(v)}" for v in profile.levels), "AUC"]
        ranked = sorted(profile.summary, key=lambda c: -np.nan_to_num(profile.summary[c]["auc"]))
        rows = [
            [
                c,
                *(f"{100 * r.success:.0f}% ({r.episodes})" for r in profile.curve(c)),
                f"{100 * profile.summary[c]['auc']:.0f}%",
            ]
            for c in ranked
        ]
        blocks.append(markdown_table((header, rows)))
    note = (
        "Success at each level (distinct episodes in brackets); AUC: the mean success over the "
        "axis's levels. Intervals, paired tests (Holm-adjusted) and figures: the report files."
    )
    return "\n\n".join([*blocks, note])


def overview_section(
    axes: Sequence[AxisProfile],
    scope: str = "Each axis swept alone, the others at their perfect level.",
    title: str = "Robustness overview",
) -> Section | None:
    """Every controller against every axis at once (None for fewer than two axes): the success
    over each axis's sweep (AUC, %), and the axis that costs it most, i.e. the largest drop in
    success from the axis's first level to its last (ties: the earlier axis).

    Parameters
    ----------
    axes
        The profiles, one column each.
    scope
        The note's first sentence: what the axes are and what stayed fixed while each was swept.
    title
        The section's title.
    """
    if len(axes) < 2:
        return None
    controllers = sorted({c for profile in axes for c in profile.summary})
    header = [
        "Controller",
        *(f"{p.key} AUC [%]" for p in axes),
        "Hurts most (success at first -> last level)",
    ]
    rows = []
    for controller in controllers:
        cells = [controller]
        worst: tuple[float, str] | None = None
        for profile in axes:
            summary = profile.summary.get(controller)
            cells.append(
                "-"
                if summary is None
                else interval_cell(summary["auc"], summary["auc_low"], summary["auc_high"], 100)
            )
            curve = profile.curve(controller)
            if len(curve) >= 2:
                first, last = curve[0].success, curve[-1].success
                text = f"{profile.key} ({first:.0%} -> {last:.0%} at {level_text(curve[-1].level)})"
                if worst is None or first - last > worst[0]:
                    worst = (first - last, text)
        cells.append(worst[1] if worst is not None and worst[0] > 0 else "-")
        rows.append(cells)
    note = (
        f"{scope} AUC: the mean success over the "
        "axis's levels per episode unit, 95% bootstrap interval over units (as in each axis's "
        "summary below). Hurts most: the axis with the largest drop in success from its first "
        "level to its last."
    )
    return Section("sweep-overview", title, (Note(note), TableBlock((header, rows))))


#: what one pair of a sweep's paired tables is
SWEEP_UNIT = "one episode unit (env, map, slip, trial) of both sides"


def level_power_note(profile: AxisProfile) -> str | None:
    """The power statement below an axis's table of every level
    (:func:`evaluation.stats.designs.table_power`): the sweep's family ``m``, the pairs of each
    test against the reference, their pooled discordance; None without a paired test."""
    tested = [row.paired for row in profile.rows if row.paired]
    if not tested or profile.family_size < 1:
        return None
    return table_power(
        [int(t["pairs"]) for t in tested],
        [int(t["discordant"]) for t in tested],
        profile.family_size,
        SWEEP_UNIT,
    ).sentence()


def level_cost_power_note(costs: Sequence[LevelCost]) -> str | None:
    """The power statement below the level-cost table, as :func:`level_power_note`."""
    if not costs or costs[0].family_size < 1:
        return None
    return table_power(
        [c.pairs for c in costs], [c.discordant for c in costs], costs[0].family_size, SWEEP_UNIT
    ).sentence()


def _level_table(profile: AxisProfile) -> tuple[list[str], list[list[str]]]:
    """Every controller at every level of ``profile``: rates, distances and the paired tests."""
    header = [
        "Controller",
        profile.key,
        "Episodes",
        "Success [%]",
        "Final distance [cm]",
        f"Success vs {profile.reference} [pp]",
        "McNemar p",
        "Holm p",
        f"Distance vs {profile.reference} [cm]",
    ]
    rows = []
    for row in profile.rows:
        paired = row.paired or {}
        rows.append(
            [
                row.controller,
                level_text(row.level),
                str(row.episodes) + (f" ({row.errors} raised)" if row.errors else ""),
                interval_cell(row.success, row.success_low, row.success_high, 100),
                interval_cell(row.distance, row.distance_low, row.distance_high, digits=1),
                interval_cell(
                    paired["success_difference"], paired["success_low"], paired["success_high"], 100
                )
                if paired
                else ("(reference)" if row.controller == profile.reference else "-"),
                f"{paired['p_value']:.3g}" if paired else "",
                f"{paired['p_holm']:.3g}" if "p_holm" in paired else "",
                interval_cell(
                    paired["distance_difference"],
                    paired["distance_low"],
                    paired["distance_high"],
                    digits=1,
                )
                if paired
                else "",
            ]
        )
    return header, rows


def robustness_sections(axes: Sequence[AxisProfile], command: str = "") -> list[Section]:
    """A sweep's report: an overview of every axis (two or more), then per axis a summary table
    (area under the success curve, tail) and a table of every level (success, final distance,
    paired difference to the reference).

    Parameters
    ----------
    axes : sequence of AxisProfile
        The profiles (:func:`evaluation.stats.robustness.profiles`), one part each.
    command : str, optional
        The command that ran the sweep, quoted at the top (nothing when empty).

    Returns
    -------
    list of Section
        The report's sections in order, for :func:`evaluation.reports.sections.markdown` and
        :func:`evaluation.reports.html.render_page`.
    """
    overview = overview_section(axes)
    out = [] if overview is None else [overview]
    for profile in axes:
        summary = (
            [
                "Controller",
                "Units",
                "Success over the sweep (AUC) [%]",
                f"Worst {TAIL_SHARE:.0%} final distance [cm]",
            ],
            [
                [
                    c,
                    str(int(s["units"])),
                    interval_cell(s["auc"], s["auc_low"], s["auc_high"], 100),
                    interval_cell(s["tail"], s["tail_low"], s["tail_high"], digits=1),
                ]
                for c, s in sorted(profile.summary.items(), key=lambda item: -np.nan_to_num(item[1]["auc"]))
            ],
        )
        header, rows = _level_table(profile)
        note = (
            f"Levels of `{profile.key}`: {', '.join(level_text(v) for v in profile.levels)}; the same "
            "episode units (env, map, slip, trial: seed, layout and slip draws) at every level. Success "
            "with 95% Wilson intervals; final distance (mean over robots) with 95% bootstrap intervals; "
            f"paired differences to {profile.reference} on the shared units (Newcombe interval, exact "
            "McNemar p, and Holm's adjustment over every distinct paired test of the sweep, a "
            "bit-identical twin's test counted once; bootstrap interval "
            "of the per-episode distance differences). Distinct episodes only: an episode or unit that "
            "repeats an earlier one of its cell bit for bit counts once. AUC: the mean success "
            "over the levels per unit, bootstrap over units; tail: the mean final distance of the worst "
            f"{TAIL_SHARE:.0%} of the sweep's episodes, bootstrap."
        )
        raised = [r for r in profile.rows if r.errors]
        if raised:
            note += (
                f" **{sum(r.errors for r in raised)} episode(s) raised and are not counted**: "
                + ", ".join(f"{r.controller} at {level_text(r.level)} ({r.errors})" for r in raised)
                + "; each level's results.md names their errors."
            )
        blocks: list[Block] = [
            Note(note),
            TableBlock(summary, "Summary over the sweep"),
            TableBlock((header, rows), "Every level"),
        ]
        power = level_power_note(profile)
        if power is not None:
            blocks.append(Note(power))
        out.append(Section(f"sweep-{profile.key}", f"Robustness: {profile.key}", tuple(blocks)))
    if command and out:
        out[0] = Section(out[0].anchor, out[0].title, (Note(f"Command: `{command}`"), *out[0].blocks))
    return out


def level_cost_section(costs: Sequence[LevelCost], title: str = "What each level costs") -> Section | None:
    """Every controller's success at each level against its own at the axis's first level,
    paired on the same episodes (:func:`evaluation.stats.robustness.level_costs`); None without any."""
    if not costs:
        return None
    header = [
        "Controller",
        "Axis",
        "Level (against)",
        "Pairs",
        "Success [%]",
        "Difference [pp]",
        "McNemar p",
        "Holm p",
    ]
    rows = [
        [
            c.controller,
            c.key,
            f"{level_text(c.level)} ({level_text(c.first)})",
            str(c.pairs),
            f"{100 * c.success:.0f} ({100 * c.first_success:.0f})",
            interval_cell(c.difference, c.low, c.high, 100),
            f"{c.p_value:.3g}",
            f"{c.p_holm:.3g}",
        ]
        for c in costs
    ]
    note = (
        "Each controller against itself: its success at a level against its success at the axis's "
        "first level (in brackets), on the episode units both levels share (distinct units only), "
        "difference with a 95% Newcombe interval, exact McNemar p and Holm's adjustment over every "
        "distinct test of the table (a bit-identical twin's test, e.g. a `-robust` variant's at "
        "nominal slip, is its base's and counted once)."
    )
    anchor = "level-costs"
    blocks: list[Block] = [Note(note), TableBlock((header, rows))]
    power = level_cost_power_note(costs)
    if power is not None:
        blocks.append(Note(power))
    return Section(anchor, title, tuple(blocks))
