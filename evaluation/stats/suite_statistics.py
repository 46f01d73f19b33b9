"""A suite run's statistics: every interval over layouts and every tested table of a report on a
benchmark suite (docs/benchmark.md, "Metrics" and "Statistics"). Each paired table is a named
family of tests, declared before its p-values are computed, corrected with Holm within it, and
stated with its power.

- :data:`OUTCOMES`: success, strict success and success excusing the collisions no robot could
  avoid (rates); :data:`METRICS`: minimum clearance, the share of periods near an obstacle, time to
  goal, path-length ratio and jerk (means). Each is a :class:`Measure`: how it is read from an
  episode record, and on which episodes it is defined.
- :func:`suite_rate_interval`, :func:`suite_mean_interval`: a rate (the wider of Wilson's and the
  two-stage bootstrap) or a mean (the two-stage bootstrap) over layouts, then episodes within
  them (:mod:`evaluation.stats.clustered`): the intervals of the leaderboard, the breakdowns
  (:func:`breakdown`, per layout tier and family) and :func:`layout_summary` (each controller's
  rates and means).
- :func:`measure_table`: one measure's paired table. It pairs every two controllers of a task on
  their shared (layout, seed) units with the layout as the unit
  (:func:`~evaluation.stats.layout_tests.paired_rates_by_layout`,
  :func:`~evaluation.stats.layout_tests.paired_means_by_layout`: the difference's two-stage bootstrap
  interval and the layout sign-flip test). Its family (:class:`~evaluation.stats.families.HypothesisFamily`)
  is the run's design, every pair of controllers of every task that ran, known before any outcome:
  a pair without a shared unit counts in ``m`` as ``p = 1``; or a narrower design declared the
  same way (:mod:`evaluation.stats.designs`: every controller against a reference, and named
  pairs). A comparison may pool the tasks (``pooled_reference_pairs``, task ``ALL``): its units are
  every task's, each (task, layout) its own cluster, so one layout number of two tasks is never
  one cluster. :func:`suite_tables`: every measure's table.

Records of runs without a suite (no ``layout``) have none of these.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from evaluation.episodes.distinct import distinct_records, distinct_units, paired_identity
from evaluation.episodes.records import ran
from evaluation.run.suite_runs import cluster_of
from evaluation.stats.clustered import layout_mean_interval, layout_rate_interval
from evaluation.stats.designs import ALL, EVERY_PAIR, declared_pairs, pair_label
from evaluation.stats.families import HypothesisFamily, power_statement
from evaluation.stats.layout_tests import LayoutComparison, paired_means_by_layout, paired_rates_by_layout
from evaluation.stats.statistics import wilson_interval
from koopman_envs import FAMILIES, SUITE_PREFIX, TIERS, path_ratio, smallest_clearance

__all__ = [
    "BREAKDOWNS",
    "METRICS",
    "MEASURES",
    "OUTCOMES",
    "Measure",
    "breakdown",
    "is_suite_run",
    "layout_summary",
    "suite_mean_interval",
    "suite_rate_interval",
    "suite_tables",
    "measure_table",
]


@dataclass(frozen=True)
class Measure:
    """A quantity a suite table compares.

    Attributes
    ----------
    key : str
        Its name in ``results.json`` (``"success"``, ``"clearance_cm"``).
    label : str
        Its name in a table's caption and its family's name.
    unit : str
        Unit of a metric (``""`` for a rate or a ratio).
    binary : bool
        A rate (success outcomes), else a metric's mean.
    read : callable
        ``read(record)``: the record's value, None where it has none (the measure is undefined
        there, or the record was written before the field existed).
    where : str
        The paired units it is compared on, for the notes: ``"units both ran"``, or ``"units
        both won"`` for a metric defined on successes only.
    digits : int
        Decimals a table prints.
    """

    key: str
    label: str
    unit: str
    binary: bool
    read: Callable[[Mapping[str, Any]], Any]
    where: str
    digits: int = 1


def _field(name: str) -> Callable[[Mapping[str, Any]], Any]:
    return lambda record: record.get(name)


def _team_mean(name: str) -> Callable[[Mapping[str, Any]], float | None]:
    """The mean over robots of a per-robot list field (None where the record has none)."""

    def read(record: Mapping[str, Any]) -> float | None:
        values = record.get(name)
        return float(np.mean(values)) if values else None

    return read


def _clearance_cm(record: Mapping[str, Any]) -> float | None:
    low = smallest_clearance(record.get("min_clearance"))
    return None if low is None else 100.0 * low


def _won(read: Callable[[Mapping[str, Any]], Any]) -> Callable[[Mapping[str, Any]], Any]:
    """``read`` on a successful episode, None on the others."""
    return lambda record: read(record) if record.get("success") else None


OUTCOMES = (
    Measure("success", "success", "", True, _field("success"), "units both ran", 0),
    Measure(
        "strict_success",
        "strict success (clearance above 5 cm all episode)",
        "",
        True,
        _field("strict_success"),
        "units both ran",
        0,
    ),
    Measure(
        "success_excusing_unavoidable",
        "success excusing unavoidable collisions",
        "",
        True,
        _field("success_excusing_unavoidable"),
        "units both ran",
        0,
    ),
)
METRICS = (
    Measure("clearance_cm", "minimum clearance", "cm", False, _clearance_cm, "units both ran", 1),
    Measure(
        "near_obstacle_share",
        "share of periods within 5 cm of an obstacle",
        "",
        False,
        _team_mean("near_obstacle_share"),
        "units both ran",
        3,
    ),
    Measure("time_to_goal_s", "time to goal", "s", False, _won(_field("time_to_goal")), "units both won", 1),
    Measure(
        "path_ratio",
        "path-length ratio",
        "",
        False,
        _won(lambda r: path_ratio(r.get("path_length"), r.get("straight_distance"))),
        "units both won",
        3,
    ),
    Measure("jerk_rms", "jerk RMS", "m/s³", False, _team_mean("jerk_rms"), "units both ran", 1),
)
MEASURES = OUTCOMES + METRICS


def is_suite_run(records: Sequence[Mapping[str, Any]]) -> bool:
    """Whether ``records`` are a suite run's (they carry ``layout``)."""
    return any(r.get("layout") is not None for r in records)


def _clusters(records: Sequence[Mapping[str, Any]], read: Callable[[Mapping[str, Any]], Any]) -> list[list]:
    """The values of ``records`` grouped by layout (:func:`~evaluation.run.suite_runs.cluster_of`),
    records without a value left out."""
    groups: dict[Any, list] = {}
    for record in records:
        value = read(record)
        if value is not None:
            groups.setdefault(cluster_of(record), []).append(value)
    return list(groups.values())


def suite_rate_interval(
    records: Sequence[Mapping[str, Any]], read: Callable[[Mapping[str, Any]], Any] | None = None
) -> tuple[float, list[float]]:
    """A suite run's rate of an outcome over ``records`` (distinct episodes that ran) and its 95%
    interval: the wider of Wilson's and the two-stage bootstrap over layouts, then episodes within
    them (:func:`~evaluation.stats.clustered.layout_rate_interval`). Wilson covers small samples, where a
    bootstrap of a rate at 0 or 1 has no width; the bootstrap covers the layouts' clustering,
    which Wilson assumes away. ``read``: the outcome of a record (default: ``success``; None: the
    record has none). (NaN, [NaN, NaN]) without a value."""
    clusters = _clusters(records, read or _field("success"))
    n = sum(len(c) for c in clusters)
    if n == 0:
        return math.nan, [math.nan, math.nan]
    wins = sum(bool(v) for c in clusters for v in c)
    wilson = wilson_interval(wins, n)
    _, low, high = layout_rate_interval([[bool(v) for v in c] for c in clusters])
    return wins / n, [min(wilson[0], low), max(wilson[1], high)]


def suite_mean_interval(
    records: Sequence[Mapping[str, Any]], read: Callable[[Mapping[str, Any]], Any]
) -> tuple[float, list[float]]:
    """A suite run's mean of a metric over ``records`` (those with a value) and its 95% two-stage
    bootstrap interval over layouts, then episodes within them
    (:func:`~evaluation.stats.clustered.layout_mean_interval`); (NaN, [NaN, NaN]) without a value."""
    clusters = _clusters(records, read)
    if not clusters:
        return math.nan, [math.nan, math.nan]
    mean, low, high = layout_mean_interval(clusters)
    return mean, [low, high]


def _scope(records: Sequence[Mapping[str, Any]]) -> str:
    """The suite splits the records ran on (``koopnav-bench-v1/test``), for a family's name."""
    maps = sorted({str(r.get("map", "")).removeprefix(SUITE_PREFIX) for r in records})
    return ", ".join(maps) or "suite"


def _units(records: Sequence[Mapping[str, Any]]) -> dict[tuple[str, str], dict[tuple, Mapping[str, Any]]]:
    """Per (task, controller) its episodes that ran, by unit (map, slip, layout, seed)."""
    out: dict[tuple[str, str], dict[tuple, Mapping[str, Any]]] = {}
    for r in records:
        if ran(r) and r.get("layout") is not None:
            unit = (r["map"], r["slip"], int(r["layout"]), r["seed"])
            out.setdefault((r["env_id"], r["controller"]), {})[unit] = r
    return out


def _pooled(
    units: Mapping[tuple[str, str], Mapping[tuple, Mapping[str, Any]]], label: str, tasks: Sequence[str]
) -> dict[tuple, Mapping[str, Any]]:
    """``label``'s units of every task in ``tasks``, each key led by its task; empty unless it ran
    in every one of them (a pooled comparison over some tasks only is no comparison of the design)."""
    if not all(units.get((env_id, label)) for env_id in tasks):
        return {}
    return {(env_id, *key): r for env_id in tasks for key, r in units[env_id, label].items()}


def _cluster(record: Mapping[str, Any], pooled: bool) -> Any:
    """A unit's cluster: its layout (:func:`~evaluation.run.suite_runs.cluster_of`), and in a
    pooled comparison its task with it (layout 3 of one task and of the other are two layouts)."""
    return (record["env_id"], cluster_of(record)) if pooled else cluster_of(record)


def _compare(measure: Measure, a: dict[Any, list], b: dict[Any, list]) -> LayoutComparison:
    compare = paired_rates_by_layout if measure.binary else paired_means_by_layout
    return compare([a[k] for k in a], [b[k] for k in a])


def _row(
    measure: Measure, env_id: str, a: str, b: str, comparison: LayoutComparison, pairs: list[tuple[Any, Any]]
) -> dict[str, Any]:
    """A table row: the comparison's fields, and for a rate the counts of the 2x2 table."""
    row: dict[str, Any] = {"env_id": env_id, "a": a, "b": b, "n": comparison.units, **comparison.to_dict()}
    row["test"] = "layout sign-flip"
    if measure.binary:
        both = sum(1 for x, y in pairs if x and y)
        only_a = sum(1 for x, y in pairs if x and not y)
        only_b = sum(1 for x, y in pairs if y and not x)
        row.update(
            rate_a=comparison.mean_a,
            rate_b=comparison.mean_b,
            both_success=both,
            only_a=only_a,
            only_b=only_b,
            both_fail=len(pairs) - both - only_a - only_b,
            # rliable's probability of improvement on paired binary outcomes
            prob_improvement=(only_a + 0.5 * (len(pairs) - only_a - only_b)) / len(pairs),
        )
    return row


def measure_table(
    records: Sequence[Mapping[str, Any]],
    measure: Measure,
    pairs: Sequence[tuple[str, str, str]] | None = None,
    design: str = EVERY_PAIR,
) -> dict[str, Any]:
    """One measure's paired table over a suite run's records, its family corrected and its power.

    Parameters
    ----------
    records : sequence of dict
        A suite run's episode records (each read once: :func:`evaluation.episodes.distinct.read_once`).
    measure : Measure
        What the table compares (one of :data:`MEASURES`).
    pairs : sequence of tuple of str, optional
        The family's comparisons, each (task, a, b), declared from the run's design before any
        test (default: every pair, :func:`declared_pairs`; :func:`~evaluation.stats.designs.reference_pairs` for a page that
        tests fewer). Holm's correction and the power statement run over exactly these. A pair
        whose task is :data:`~evaluation.stats.designs.ALL` (:func:`~evaluation.stats.designs.pooled_reference_pairs`) is compared on the units of
        every task of ``records``, each (task, layout) a cluster of its own, and only where both
        controllers ran in every task (else it counts in ``m`` as ``p = 1``).
    design : str
        What ``pairs`` are, for the family's name (default :data:`EVERY_PAIR`).

    Returns
    -------
    dict
        ``measure``, ``label``, ``unit``, ``where``; ``family`` (the
        :class:`~evaluation.stats.families.FamilyResult` as a dict: name, size ``m``, alpha and every
        declared comparison's raw and Holm-adjusted p); ``power`` (the
        :class:`~evaluation.stats.families.PowerStatement` as a dict with its sentence; None when no pair
        shares a unit); ``rows``: one per pair with shared units (units where both episodes have
        a value, repeats counted once), with ``p_holm`` and ``rejected`` from the family.
    """
    pairs = declared_pairs(records) if pairs is None else list(pairs)
    # declared from the design before any p-value is computed
    family = HypothesisFamily(
        f"{_scope(records)}: {measure.label}, {design}", tuple(pair_label(*p) for p in pairs)
    )
    units = _units(records)
    tasks = list(dict.fromkeys(r["env_id"] for r in records))
    p_values: dict[str, float] = {}
    same: dict[str, Any] = {}
    rows: dict[str, dict[str, Any]] = {}
    comparisons = []
    for env_id, a, b in pairs:
        label = pair_label(env_id, a, b)
        pooled = env_id == ALL
        if pooled:
            mine, theirs = _pooled(units, a, tasks), _pooled(units, b, tasks)
        else:
            mine, theirs = units.get((env_id, a), {}), units.get((env_id, b), {})
        shared = distinct_units(sorted(set(mine) & set(theirs)), mine, theirs)
        by_layout_a: dict[Any, list] = {}
        by_layout_b: dict[Any, list] = {}
        kept, values = [], []
        for key in shared:
            x, y = measure.read(mine[key]), measure.read(theirs[key])
            if x is None or y is None:
                continue
            layout = _cluster(mine[key], pooled)
            by_layout_a.setdefault(layout, []).append(x)
            by_layout_b.setdefault(layout, []).append(y)
            kept.append(key)
            values.append((x, y))
        if not kept:
            p_values[label] = math.nan  # counted in m as p = 1 (HypothesisFamily.correct)
            continue
        comparison = _compare(measure, by_layout_a, by_layout_b)
        comparisons.append(comparison)
        p_values[label] = comparison.p_value
        same[label] = paired_identity(env_id, kept, mine, theirs)
        rows[label] = _row(measure, env_id, a, b, comparison, values)
    corrected = family.correct(p_values, same=same)
    for test in corrected.tests:
        if test.comparison in rows:
            rows[test.comparison].update(p_holm=test.p_holm, rejected=test.rejected)
    power = power_statement(comparisons, family) if comparisons else None
    return {
        "measure": measure.key,
        "label": measure.label,
        "unit": measure.unit,
        "where": measure.where,
        "family": corrected.to_dict(),
        "power": None if power is None else power.to_dict(),
        "rows": list(rows.values()),
    }


def suite_tables(
    records: Sequence[Mapping[str, Any]],
    pairs: Sequence[tuple[str, str, str]] | None = None,
    design: str = EVERY_PAIR,
) -> list[dict[str, Any]]:
    """Every measure's table (:func:`measure_table`, each its own family of ``pairs``: default
    every pair), outcomes first; empty without a suite, and without a pair to test (a run of one
    controller, or a page whose other controllers are still running)."""
    if not is_suite_run(records):
        return []
    pairs = declared_pairs(records) if pairs is None else list(pairs)
    if not pairs:
        return []
    return [measure_table(records, measure, pairs, design) for measure in MEASURES]


def layout_summary(records: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Per (task, controller) of a suite run, every measure over its distinct episodes that ran:
    a rate with :func:`suite_rate_interval`, a metric's mean with its two-stage bootstrap interval
    over layouts (:func:`~evaluation.stats.clustered.layout_mean_interval`), and the episodes and layouts
    it counts. Empty without a suite."""
    if not is_suite_run(records):
        return []
    rows = []
    for env_id in dict.fromkeys(r["env_id"] for r in records):
        for name in dict.fromkeys(r["controller"] for r in records if r["env_id"] == env_id):
            own = distinct_records(
                [r for r in records if r["env_id"] == env_id and r["controller"] == name and ran(r)]
            )
            row: dict[str, Any] = {"env_id": env_id, "controller": name}
            for measure in MEASURES:
                clusters = _clusters(own, measure.read)
                interval_of = suite_rate_interval if measure.binary else suite_mean_interval
                value, interval = interval_of(own, measure.read)
                row[measure.key] = {
                    "value": value,
                    "ci": interval,
                    "episodes": sum(len(c) for c in clusters),
                    "layouts": len(clusters),
                }
            rows.append(row)
    return rows


#: the suite breakdowns of a run's report: the record field and its groups, in report order
BREAKDOWNS = {"layout_tier": TIERS, "layout_family": FAMILIES}


def breakdown(records: list[dict[str, Any]], by: str) -> list[dict[str, Any]]:
    """A suite run's success per (task, controller, group of ``by``): ``layout_tier`` (easy,
    medium, hard) or ``layout_family`` (clutter, passages, rooms); empty for a run without a suite.

    Each row counts the group's distinct episodes that ran, its layouts, and the success rate
    with the interval of the leaderboard (the wider of Wilson's and the bootstrap over layouts).
    """
    groups = BREAKDOWNS[by]
    rows = []
    suite_records = [r for r in records if r.get(by) is not None]
    for env_id in dict.fromkeys(r["env_id"] for r in suite_records):
        for name in dict.fromkeys(r["controller"] for r in suite_records if r["env_id"] == env_id):
            own = distinct_records(
                [r for r in suite_records if r["env_id"] == env_id and r["controller"] == name and ran(r)]
            )
            for group in groups:
                recs = [r for r in own if r[by] == group]
                won = sum(bool(r["success"]) for r in recs)
                rows.append(
                    {
                        "env_id": env_id,
                        "controller": name,
                        "by": by,
                        "group": group,
                        "layouts": len({cluster_of(r) for r in recs}),
                        "episodes": len(recs),
                        "successes": won,
                        "success_rate": won / len(recs) if recs else float("nan"),
                        "success_ci": suite_rate_interval(recs)[1],
                    }
                )
    return rows
