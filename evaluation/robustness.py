"""Robustness profiles: how each controller degrades along a swept uncertainty (``--sweep``).

Per axis, controller and level: the success rate with its Wilson interval and the mean final
distance (per episode, the mean over robots) with its bootstrap interval; the paired difference
to a reference controller on the same episodes (success: Newcombe interval and exact McNemar
p; final distance: bootstrap interval of the per-episode differences). Per axis and controller,
two summaries with bootstrap intervals: the area under the success curve (the mean success over
the levels, per episode unit, resampled by unit so the levels stay paired) and the tail (the
mean final distance of the worst 10% of the sweep's episodes).

An episode *unit* is (env, map, slip, trial): the same seed, layout and slip draws at every level.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from evaluation.distinct import distinct_records, distinct_units, signature
from evaluation.profile_figures import save_profile_figures
from evaluation.records import json_safe, ran
from evaluation.report import Block, Note, Section, TableBlock, markdown, markdown_table
from evaluation.results import Results
from evaluation.statistics import (
    bootstrap_mean_interval,
    bootstrap_tail_interval,
    holm_adjusted,
    paired_comparison,
    tail_mean,
    wilson_interval,
)

__all__ = [
    "AxisProfile",
    "LevelRow",
    "overview_section",
    "profiles",
    "robustness_sections",
    "terminal_overview",
    "write_robustness",
]

#: share of the worst episodes the tail summary averages
TAIL_SHARE = 0.1

Unit = tuple[str, str, str, int]


@dataclass
class LevelRow:
    """One controller at one level of an axis (rates in [0, 1], distances in cm)."""

    controller: str
    level: Any
    episodes: int
    successes: int
    success_low: float
    success_high: float
    distance: float
    distance_low: float
    distance_high: float
    #: paired against the reference controller (None for the reference itself)
    paired: dict[str, float] | None = None
    #: episodes of the controller at this level that raised (not in ``episodes``)
    errors: int = 0

    @property
    def success(self) -> float:
        return self.successes / self.episodes if self.episodes else math.nan


@dataclass
class AxisProfile:
    """Every controller's profile along one swept axis."""

    key: str
    levels: list[Any]
    reference: str
    rows: list[LevelRow] = field(default_factory=list)
    #: controller -> {auc, auc_low, auc_high, tail, tail_low, tail_high, units}
    summary: dict[str, dict[str, float]] = field(default_factory=dict)

    def curve(self, controller: str) -> list[LevelRow]:
        """The rows of ``controller`` in level order."""
        return [r for r in self.rows if r.controller == controller]

    @property
    def controllers(self) -> list[str]:
        return list(self.summary)


def _unit(record: dict[str, Any], slip_axis: bool) -> Unit:
    return (record["env_id"], record["map"], "" if slip_axis else record["slip"], int(record["trial"]))


def _team_distance(record: dict[str, Any]) -> float:
    return 100.0 * float(np.mean(record["final_distance"]))


def _by_unit(results: Results, controller: str, slip_axis: bool) -> dict[Unit, dict[str, Any]]:
    return {_unit(r, slip_axis): r for r in results.records if r["controller"] == controller and ran(r)}


def _level_row(controller: str, level: Any, mine: dict, reference: dict | None) -> LevelRow:
    records = distinct_records(mine.values())  # an identical rerun is not a sample
    successes = sum(bool(r["success"]) for r in records)
    low, high = wilson_interval(successes, len(records)) if records else (math.nan, math.nan)
    distances = [_team_distance(r) for r in records]
    d_low, d_high = bootstrap_mean_interval(distances)
    row = LevelRow(
        controller,
        level,
        len(records),
        successes,
        low,
        high,
        float(np.mean(distances)) if distances else math.nan,
        d_low,
        d_high,
    )
    if reference is not None:
        # units sharing a cell whose two episodes repeat an earlier unit's count once
        shared = distinct_units(sorted(set(mine) & set(reference)), mine, reference, cell_of=lambda u: u[:3])
        if shared:
            test = paired_comparison(
                [bool(mine[u]["success"]) for u in shared], [bool(reference[u]["success"]) for u in shared]
            )
            gaps = [_team_distance(mine[u]) - _team_distance(reference[u]) for u in shared]
            g_low, g_high = bootstrap_mean_interval(gaps)
            row.paired = {
                "pairs": len(shared),
                "success_difference": test.difference,
                "success_low": test.low,
                "success_high": test.high,
                "p_value": test.p_value,
                "distance_difference": float(np.mean(gaps)),
                "distance_low": g_low,
                "distance_high": g_high,
            }
    return row


def profiles(sweep: dict[str, list[tuple[Any, Results]]], reference: str | None = None) -> list[AxisProfile]:
    """The robustness profile of every axis of a sweep (:func:`evaluation.sweep.run_sweep`'s result).

    ``reference`` (default: the first controller of the run) is the controller every other is
    paired against.

    Raises
    ------
    ValueError
        ``reference`` is not one of the run's controllers.
    """
    out = []
    for key, levels in sweep.items():
        controllers = list(levels[0][1].config["controllers"])
        ref = reference or controllers[0]
        if ref not in controllers:
            raise ValueError(f"--reference {ref!r} is not one of the run's controllers {controllers}")
        slip_axis = key == "slip"
        profile = AxisProfile(key, [level for level, _ in levels], ref)
        for controller in controllers:
            per_level = [_by_unit(results, controller, slip_axis) for _, results in levels]
            ref_level = [_by_unit(results, ref, slip_axis) for _, results in levels]
            for (level, results), mine, theirs in zip(levels, per_level, ref_level, strict=True):
                row = _level_row(controller, level, mine, None if controller == ref else theirs)
                row.errors = sum(r["controller"] == controller and not ran(r) for r in results.records)
                profile.rows.append(row)
            units = _distinct_units(sorted(set.intersection(*(set(m) for m in per_level))), per_level)
            scores = [float(np.mean([bool(m[u]["success"]) for m in per_level])) for u in units]
            distances = [_team_distance(r) for m in per_level for r in m.values()]
            auc_low, auc_high = bootstrap_mean_interval(scores)
            tail_low, tail_high = bootstrap_tail_interval(distances, TAIL_SHARE)
            profile.summary[controller] = {
                "units": len(units),
                "auc": float(np.mean(scores)) if scores else math.nan,
                "auc_low": auc_low,
                "auc_high": auc_high,
                "tail": tail_mean(distances, TAIL_SHARE),
                "tail_low": tail_low,
                "tail_high": tail_high,
            }
        out.append(profile)
    # every paired test of the sweep as one family: Holm's adjustment beside the raw p
    tests = [row.paired for profile in out for row in profile.rows if row.paired]
    for test, adjusted in zip(tests, holm_adjusted(t["p_value"] for t in tests), strict=True):
        test["p_holm"] = adjusted
    return out


def _distinct_units(units: list[Unit], per_level: list[dict[Unit, dict[str, Any]]]) -> list[Unit]:
    """``units`` without those whose episodes at every level repeat an earlier unit's of the
    same cell (an identical rerun is not a sample)."""
    seen: set[tuple] = set()
    out = []
    for unit in units:
        identity = (unit[:3], *(signature(level[unit]) for level in per_level))
        if identity not in seen:
            seen.add(identity)
            out.append(unit)
    return out


# --------------------------------------------------------------------------- report
def _level_text(level: Any) -> str:
    return level if isinstance(level, str) else json.dumps(level)


def _ci(value: float, low: float, high: float, scale: float = 1.0, digits: int = 0) -> str:
    if math.isnan(value):
        return "-"
    return f"{value * scale:.{digits}f} [{low * scale:.{digits}f}, {high * scale:.{digits}f}]"


def terminal_overview(axes: Sequence[AxisProfile]) -> str:
    """What a terminal gets after a sweep: per axis, every controller's success at each level
    (distinct episodes, %), the controllers ranked by their success over the axis (AUC)."""
    blocks = []
    for profile in axes:
        header = ["Controller", *(f"{profile.key}={_level_text(v)}" for v in profile.levels), "AUC"]
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
                "-" if summary is None else _ci(summary["auc"], summary["auc_low"], summary["auc_high"], 100)
            )
            curve = profile.curve(controller)
            if len(curve) >= 2:
                first, last = curve[0].success, curve[-1].success
                text = f"{profile.key} ({first:.0%} -> {last:.0%} at {_level_text(curve[-1].level)})"
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
                _level_text(row.level),
                str(row.episodes) + (f" ({row.errors} raised)" if row.errors else ""),
                _ci(row.success, row.success_low, row.success_high, 100),
                _ci(row.distance, row.distance_low, row.distance_high, digits=1),
                _ci(paired["success_difference"], paired["success_low"], paired["success_high"], 100)
                if paired
                else ("(reference)" if row.controller == profile.reference else "-"),
                f"{paired['p_value']:.3g}" if paired else "",
                f"{paired['p_holm']:.3g}" if "p_holm" in paired else "",
                _ci(
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
    """The report: an overview of every axis (two or more), then per axis a summary table (area
    under the success curve, tail) and a table of every level (success, final distance, paired
    difference to the reference)."""
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
                    _ci(s["auc"], s["auc_low"], s["auc_high"], 100),
                    _ci(s["tail"], s["tail_low"], s["tail_high"], digits=1),
                ]
                for c, s in sorted(profile.summary.items(), key=lambda item: -np.nan_to_num(item[1]["auc"]))
            ],
        )
        header, rows = _level_table(profile)
        note = (
            f"Levels of `{profile.key}`: {', '.join(_level_text(v) for v in profile.levels)}; the same "
            "episode units (env, map, slip, trial: seed, layout and slip draws) at every level. Success "
            "with 95% Wilson intervals; final distance (mean over robots) with 95% bootstrap intervals; "
            f"paired differences to {profile.reference} on the shared units (Newcombe interval, exact "
            "McNemar p, and Holm's adjustment over every paired test of the sweep; bootstrap interval "
            "of the per-episode distance differences). Distinct episodes only: an episode or unit that "
            "repeats an earlier one of its cell bit for bit counts once. AUC: the mean success "
            "over the levels per unit, bootstrap over units; tail: the mean final distance of the worst "
            f"{TAIL_SHARE:.0%} of the sweep's episodes, bootstrap."
        )
        raised = [r for r in profile.rows if r.errors]
        if raised:
            note += (
                f" **{sum(r.errors for r in raised)} episode(s) raised and are not counted**: "
                + ", ".join(f"{r.controller} at {_level_text(r.level)} ({r.errors})" for r in raised)
                + "; each level's results.md names their errors."
            )
        blocks: list[Block] = [
            Note(note),
            TableBlock(summary, "Summary over the sweep"),
            TableBlock((header, rows), "Every level"),
        ]
        out.append(Section(f"sweep-{profile.key}", f"Robustness: {profile.key}", tuple(blocks)))
    if command and out:
        out[0] = Section(out[0].anchor, out[0].title, (Note(f"Command: `{command}`"), *out[0].blocks))
    return out


def write_robustness(axes: Sequence[AxisProfile], out: str | Path, command: str = "") -> dict[str, Path]:
    """Write ``robustness.md``, ``robustness.json``, ``figures/robustness_*.png`` and
    ``robustness.html`` (self-contained) under ``out``."""
    from evaluation.html import render_page

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    report = robustness_sections(axes, command)
    figures = save_profile_figures(axes, out / "figures")
    paths = {
        "markdown": out / "robustness.md",
        "json": out / "robustness.json",
        "html": out / "robustness.html",
    }
    paths["markdown"].write_text(
        "# KoopNav robustness profiles\n\n" + markdown(report) + "\n", encoding="utf-8"
    )
    data = [
        {
            "key": p.key,
            "levels": p.levels,
            "reference": p.reference,
            "summary": p.summary,
            "rows": [asdict(r) for r in p.rows],
        }
        for p in axes
    ]
    paths["json"].write_text(json.dumps(json_safe(data), indent=1) + "\n", encoding="utf-8")
    paths["html"].write_text(render_page("KoopNav robustness profiles", report, figures), encoding="utf-8")
    return paths
