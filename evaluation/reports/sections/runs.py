"""A run's report, built once as sections (:mod:`evaluation.reports.sections.blocks`) that Markdown
(``results.md``, the terminal) and HTML (``index.html``) render alike: the leaderboard, the
paired comparisons, the per-controller tables, and the episodes that raised or degraded.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from evaluation.episodes.records import DEGRADED_FAILURE_SHARE, is_degraded
from evaluation.reports.sections.blocks import (
    Block,
    Items,
    Note,
    Section,
    Table,
    TableBlock,
    count_cell,
    markdown_table,
    mean_cell,
    mean_sd_cell,
    number_cell,
    p_cell,
    rate_cell,
)
from evaluation.reports.sections.suite_tables import suite_sections
from evaluation.stats.designs import table_power
from evaluation.stats.run_data import RunData
from evaluation.stats.suite_statistics import BREAKDOWNS
from koopman_envs import TASKS

__all__ = [
    "DEGRADED_NOTE",
    "LEADERBOARD_NOTE",
    "PAIRED_NOTE",
    "TABLES_NOTE",
    "controller_tables",
    "leaderboard_rows",
    "paired_power_note",
    "paired_rows",
    "paper_rows",
    "sections",
    "suite_heading",
    "suite_note",
    "suite_rows",
    "task_label",
    "terminal_summary",
]

_LABELS = {spec.env_id: spec.label for spec in TASKS.values()}


def task_label(env_id: str) -> str:
    """Report name of a task ("formation"), or the id itself for an unknown one."""
    return _LABELS.get(env_id, env_id)


#: how the reports name the clusters of the success rate's bootstrap, off a suite and on one
_TRIAL_CLUSTERS = (
    "a cluster bootstrap over trials (a trial's seed fixes its layout, start and slip draws in every cell)"
)
#: a suite run's intervals (evaluation.stats.suite_statistics): the text that replaces the other runs' in the notes
_SUITE_INTERVALS = {
    f"for the success rate the wider of Wilson's and {_TRIAL_CLUSTERS}, Wilson for the collision-free "
    "rate, bootstrap for means": "for the success and collision-free rates the wider of Wilson's and a "
    "two-stage bootstrap over layouts, then episodes within them (the suite's layouts are the sample); "
    "for the final distances the two-stage bootstrap"
}

LEADERBOARD_NOTE = (
    "Success: every robot settled within tolerance without collision. Collision-free: the paper's SR. "
    "Rank: by success, ties by the mean final distance over every episode (so a controller that "
    "never moves does not outrank one that tries). "
    "Episodes: distinct episodes (an episode that repeats an earlier one of its cell bit for bit is "
    f"counted once). Intervals: 95%; for the success rate the wider of Wilson's and {_TRIAL_CLUSTERS}, "
    "Wilson for the collision-free rate, bootstrap for means. "
    "Final distances over settled runs and over collision-free runs (the paper's convention). "
    "Time to goal over successes; path ratio: path length over straight-line distance, over "
    "successes; min clearance: median over episodes of the smallest surface clearance to an "
    "obstacle, team-mate or mover (negative: a collision); accel RMS: the RMS rate of change of "
    "the speed command. "
    f"Degraded: episodes whose solver failed in more than {DEGRADED_FAILURE_SHARE:.0%} of its periods "
    "(their outcomes count; see the list below the tables)."
)
DEGRADED_NOTE = (
    f"These episodes ran to their end, but the controller's optimizer failed in more than "
    f"{DEGRADED_FAILURE_SHARE:.0%} of its periods (each failure fell back to its previous plan): a broken "
    "calibration, model or solver set-up rather than a hard scenario is the usual cause."
)
PAIRED_NOTE = (
    "Success of a minus success of b on the episodes both ran (same map, slip and seed): "
    "Newcombe's 95% interval for paired proportions and the exact McNemar test on the discordant pairs."
)
TABLES_NOTE = (
    "Success and SR: k/n [95% Wilson interval]. Robots: mean+-SD over collision-free runs (the paper's "
    "convention). Team: mean over robots per run, mean [95% bootstrap interval]."
)


# --------------------------------------------------------------------------- tables
def leaderboard_rows(results: RunData) -> Table:
    """The leaderboard (ranked within each task): one row per (task, controller)."""
    header = [
        "Rank",
        "Task",
        "Controller",
        "Episodes",
        "Success [95% CI]",
        "Collision-free [95% CI]",
        "Final dist., settled [cm]",
        "Final dist., collision-free [cm]",
        "Time to goal [s]",
        "Path ratio",
        "Min clearance [cm]",
        "Accel RMS [m/s²]",
        "Solver",
        "Solve median [ms]",
        "Solver failures",
        "Degraded",
    ]
    rows = []
    rank, last_env = 0, None
    # the movers' own column only in runs where some episode met one (reports without movers
    # keep their columns)
    mover_hits = any((row.get("collisions_by_kind") or {}).get("mover", 0) for row in results.leaderboard())
    if mover_hits:
        header.insert(header.index("Solver"), "Mover collisions")
    compute_aware = bool(results.config.get("compute"))
    if compute_aware:
        header.append("Deadline misses")
    for row in results.leaderboard():
        rank = 1 if row["env_id"] != last_env else rank + 1
        last_env = row["env_id"]
        solve = "-" if math.isnan(row["solve_ms_median"]) else f"{row['solve_ms_median']:.1f}"
        rows.append(
            [
                str(rank),
                task_label(row["env_id"]),
                row["controller"],
                str(row["episodes"]),
                rate_cell(row["success_rate"], row["success_ci"]),
                rate_cell(row["collision_free_rate"], row["collision_free_ci"]),
                mean_cell(row["final_distance_cm"], *row["final_distance_ci"]),
                mean_cell(row["final_distance_collision_free_cm"], *row["final_distance_collision_free_ci"]),
                number_cell(row.get("time_to_goal_s"), "{:.1f}"),
                number_cell(row.get("path_ratio"), "{:.2f}"),
                number_cell(row.get("min_clearance_cm"), "{:.1f}"),
                number_cell(row.get("accel_rms"), "{:.2f}"),
                *([str((row.get("collisions_by_kind") or {}).get("mover", 0))] if mover_hits else []),
                row.get("solver") or "-",
                solve,
                str(row["solver_failures"]),
                str(row.get("degraded", 0)),
                *([_misses(row)] if compute_aware else []),
            ]
        )
    return header, rows


def _misses(row: Mapping[str, Any]) -> str:
    """Deadline misses of a leaderboard row: count and share of its decisions."""
    decisions = int(row.get("decisions") or 0)
    misses = int(row.get("deadline_misses") or 0)
    return f"{misses} ({100 * misses / decisions:.0f}%)" if decisions else "-"


def _compute_note(config: Mapping[str, Any]) -> str:
    compute = config.get("compute")
    if not compute:
        return ""
    return (
        f"Compute-aware run: every decision's wall time, times {compute.get('scale')}, was charged to "
        f"the robots (measured on {compute.get('machine')}): a command acts from the period boundary "
        "after its decision is ready, the last one holds meanwhile, and a decision longer than the "
        "period is a deadline miss (koopman_envs.episodes.single.ComputeCharge)."
    )


def paired_rows(results: RunData) -> Table:
    """The paired comparisons (success rate of a minus b on shared seeds)."""
    header = [
        "Task",
        "a",
        "b",
        "Pairs",
        "Success a",
        "Success b",
        "a - b [95% CI]",
        "only a / only b",
        "P(a > b)",
        "McNemar p",
        "Holm p",
    ]
    rows = []
    for r in results.paired():
        rows.append(
            [
                task_label(r["env_id"]),
                r["a"],
                r["b"],
                str(r["n"]),
                f"{100 * r['rate_a']:.0f}%",
                f"{100 * r['rate_b']:.0f}%",
                f"{100 * r['difference']:+.0f} [{100 * r['low']:+.0f}, {100 * r['high']:+.0f}]",
                f"{r['only_a']} / {r['only_b']}",
                number_cell(r.get("prob_improvement"), "{:.2f}"),
                p_cell(r["p_value"]),
                p_cell(r["p_holm"]) if "p_holm" in r else "-",
            ]
        )
    return header, rows


#: what one pair of a run's paired table is (the paper protocol and the slip-zone runs pair on it)
SEED_UNIT = "one (map, slip level, seed) episode of both controllers"


def paired_power_note(results: RunData, unit: str = SEED_UNIT) -> str | None:
    """The power statement below :func:`paired_rows` (:func:`evaluation.stats.designs.table_power`):
    the family's ``m`` and Holm's first step, the pairs per comparison, the discordance pooled over
    the table's comparisons and the smallest difference found with 80% power. None for a suite run
    (its tables carry their own, clustered by layout) or a run without pairs."""
    rows = results.paired()
    if not rows or "family_size" not in rows[0]:
        return None
    return table_power(
        [int(r["n"]) for r in rows],
        [int(r["only_a"]) + int(r["only_b"]) for r in rows],
        int(rows[0]["family_size"]),
        unit,
    ).sentence()


def paper_rows(results: RunData, env_id: str, controller: str) -> Table:
    """One controller's paper-style table: one row per map and slip."""
    cells = [c for c in results.cells if c.env_id == env_id and c.controller == controller]
    n = max((len(c.distance_collision_free.per_robot) for c in cells), default=0)
    header = [
        "Map",
        "Slip",
        "Success",
        "SR (collision-free)",
        *(f"Robot {i + 1} [cm]" for i in range(n)),
        "team, collision-free [cm]",
        "team, settled [cm]",
    ]
    rows = []
    for c in cells:
        free = c.distance_collision_free
        settled = c.distance_settled
        rows.append(
            [
                c.map,
                c.slip,
                count_cell(c.successes, c.valid, c.success_ci),
                count_cell(c.collision_free, c.valid, c.collision_free_ci),
                *(mean_sd_cell(m, s, free.runs) for m, s in free.per_robot),
                mean_cell(free.team_mean, free.team_low, free.team_high),
                mean_cell(settled.team_mean, settled.team_low, settled.team_high),
            ]
        )
    return header, rows


def controller_tables(results: RunData) -> list[tuple[str, Table]]:
    """(caption, paper-style table) of every (task, controller), in report order."""
    keys = [
        (env_id, name)
        for env_id in dict.fromkeys(c.env_id for c in results.cells)
        for name in dict.fromkeys(c.controller for c in results.cells if c.env_id == env_id)
    ]
    return [(f"{name}, {task_label(env_id)}", paper_rows(results, env_id, name)) for env_id, name in keys]


def _clusters_text(text: str, config: Mapping[str, Any]) -> str:
    """``text`` with its intervals named as the run's are: over layouts in a suite run."""
    if config.get("suite"):
        for other, suite in _SUITE_INTERVALS.items():
            text = text.replace(other, suite)
    return text


def suite_note(config: Mapping[str, Any]) -> str:
    """A suite run's suite (:func:`suite_heading`) and how its intervals and pairs are taken;
    empty for a run without a suite."""
    heading = suite_heading(config)
    if not heading:
        return ""
    return (
        f"{heading}. Intervals resample layouts, then episodes within them (a two-stage bootstrap); "
        "paired comparisons pair on (layout, seed) units, which every controller met alike, and test "
        "with the layout as the unit."
    )


def suite_heading(config: Mapping[str, Any]) -> str:
    """A suite run's suite, as every report prints it: name and version, split, the layouts run,
    and each task's split label (with its hash); empty for a run without a suite."""
    suite = config.get("suite")
    if not suite:
        return ""
    selected = suite.get("layouts")
    sizes = {t.get("size") for t in suite["tasks"].values()}
    size = sizes.pop() if len(sizes) == 1 else None
    if selected is None:
        which = f"all {size} layouts" if size is not None else "every layout"
    else:
        count = selected[1] - selected[0]
        which = f"layouts {selected[0]}-{selected[1] - 1} ({count} {f'of {size}' if size else 'per split'})"
    episodes = suite.get("episodes_per_layout")
    labels = "; ".join(f"{task_label(env_id)} {t['label']}" for env_id, t in suite["tasks"].items())
    return (
        f"Suite {suite['name']} (version {suite['version']}), split {suite['split']}, {which}, "
        f"{episodes} episode{'s' if episodes != 1 else ''} per layout: {labels}"
    )


def suite_rows(results: RunData, by: str) -> Table:
    """A suite run's success per layout tier (``by="layout_tier"``) or family
    (``"layout_family"``): one row per (task, controller), one column per group, each cell
    successes/episodes [95% interval over layouts]."""
    groups = BREAKDOWNS[by]
    table: dict[tuple[str, str], dict[str, str]] = {}
    for row in results.suite_breakdown():
        if row["by"] == by:
            key = (row["env_id"], row["controller"])
            table.setdefault(key, {})[row["group"]] = count_cell(
                row["successes"], row["episodes"], row["success_ci"]
            )
    header = ["Task", "Controller", *groups]
    rows = [
        [task_label(env_id), name, *(cells.get(g, "-") for g in groups)]
        for (env_id, name), cells in table.items()
    ]
    return header, rows


SUITE_NOTE = (
    "Success per layout tier (the suite's difficulty grade: easy, medium, hard) and per layout "
    "family (clutter, passages, rooms): successes/episodes [95% interval, the wider of Wilson's "
    "and the two-stage bootstrap over layouts, then episodes]. docs/benchmark.md defines the tiers "
    "and families."
)


def _calibration_note(config: Mapping[str, Any]) -> str:
    calibration = config.get("calibration", {})
    if not calibration:
        return ""
    return (
        f"Calibration: every controller was offered the same plant (the env's robots in an open field, "
        f"slip means hidden) with a budget of {calibration.get('budget'):,} team-transitions, seed "
        f"{calibration.get('seed')}; the per-cell tables list what each used. The plant's slip "
        "is the cell's (its setting, never its means): the paper identifies its Koopman model from "
        "the robots as they are, as a lab drives its robots on its own floor, so a controller that "
        "learns calibrates on the slip distribution it is then evaluated on."
    )


def _calibration_used(results: RunData) -> str:
    used = [c for c in results.cells if c.calibration_transitions is not None]
    if not used:
        return ""
    return "Calibration data used (team-transitions): " + ", ".join(
        sorted({f"{c.controller} {c.calibration_transitions:,}" for c in used})
    )


# --------------------------------------------------------------------------- sections
def sections(results: RunData) -> list[Section]:
    """The report of a run, in order: leaderboard, paired comparisons (when any two controllers
    share episodes), per-controller tables, and the episodes that raised (when any did)."""
    lead: list[Block] = [
        TableBlock(leaderboard_rows(results)),
        Note(_clusters_text(LEADERBOARD_NOTE, results.config)),
    ]
    if suite_note(results.config):
        lead.insert(0, Note(suite_note(results.config)))
    if _calibration_note(results.config):
        lead.append(Note(_calibration_note(results.config)))
    if _compute_note(results.config):
        lead.append(Note(_compute_note(results.config)))
    out = [Section("leaderboard", "Leaderboard", tuple(lead))]
    if results.config.get("suite"):
        by_group = tuple(
            TableBlock(suite_rows(results, by), f"Success by layout {by.removeprefix('layout_')}")
            for by in BREAKDOWNS
        )
        out.append(Section("suite", "By layout tier and family", (Note(SUITE_NOTE), *by_group)))
    if results.config.get("suite"):
        # a suite run's paired tables: one family per outcome and metric, with its power
        out += suite_sections(results)
    else:
        paired = paired_rows(results)
        if paired[1]:
            out.append(Section("paired", "Paired comparisons", (Note(PAIRED_NOTE), TableBlock(paired))))
    tables: list[Block] = [Note(TABLES_NOTE)]
    tables += [TableBlock(table, caption) for caption, table in controller_tables(results) if table[1]]
    if _calibration_used(results):
        tables.append(Note(_calibration_used(results)))
    out.append(Section("tables", "Per-controller tables", tuple(tables)))
    if results.failed_episodes:
        entries = tuple((str(r["key"]), str(r.get("error"))) for r in results.failed_episodes)
        out.append(Section("failed", "Episodes that raised", (Items(entries),)))
    degraded = [r for r in results.records if is_degraded(r)]
    if degraded:
        entries = tuple(
            (str(r["key"]), f"solver failed in {r['solver_failures']} of {r['steps']} periods")
            for r in degraded
        )
        out.append(Section("degraded", "Degraded episodes", (Note(DEGRADED_NOTE), Items(entries))))
    return out


def terminal_summary(results: RunData, paths: Mapping[str, Path]) -> str:
    """The compact leaderboard a terminal gets (rank, controller, episodes, success with its
    interval, settled final distance, solver and its median time) and where the full report is."""
    header, rows = leaderboard_rows(results)
    keep = [
        header.index(name)
        for name in (
            "Rank",
            "Task",
            "Controller",
            "Episodes",
            "Success [95% CI]",
            "Final dist., settled [cm]",
            "Solver",
            "Solve median [ms]",
            "Deadline misses",
        )
        if name in header
    ]
    table = markdown_table(([header[i] for i in keep], [[row[i] for i in keep] for row in rows]))
    cells = sorted({(c.map, c.slip) for c in results.cells})
    note = (
        f"{len(results.records)} episodes over {len(cells)} map/slip cells "
        f"({', '.join(f'{m} {s}' for m, s in cells)}); success = every robot settled within tolerance "
        "without collision; 95% intervals (the wider of Wilson's and a "
        f"{'two-stage bootstrap over layouts, then episodes' if results.config.get('suite') else 'cluster bootstrap over trials'}); "
        "Episodes: distinct ones. Few episodes per controller give wide intervals: a smoke test, not "
        "a ranking."
    )
    if _compute_note(results.config):
        note += " " + _compute_note(results.config)
    if suite_note(results.config):
        note += " " + suite_note(results.config)
    lines = [table, "", note]
    reports = [str(paths[k]) for k in ("markdown", "html") if k in paths]
    if reports:
        lines.append(
            f"Full report (paired comparisons on shared seeds, per-cell tables, figures): "
            f"{', '.join(reports)}"
        )
    return "\n".join(lines)
