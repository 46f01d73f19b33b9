"""Robustness profiles: how each controller degrades along a swept uncertainty (``--sweep``).

Per axis, controller and level: the success rate with its Wilson interval and the mean final
distance (per episode, the mean over robots) with its bootstrap interval; the paired difference
to a reference controller on the same episodes (success: Newcombe interval and exact McNemar
p; final distance: bootstrap interval of the per-episode differences). Per axis and controller,
two summaries with bootstrap intervals: the area under the success curve (the mean success over
the levels, per episode unit, resampled by unit so the levels stay paired) and the tail (the
mean final distance of the worst 10% of the sweep's episodes).

An episode *unit* is (env, map, slip, trial): the same seed, layout and slip draws at every level.

Statistics only: :mod:`evaluation.reports.sections.profiles` makes them a report,
:mod:`evaluation.reports.figures` draws them, and :func:`evaluation.reports.results.write_profiles` writes the
files, as for any run.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from evaluation.episodes.distinct import distinct_records, distinct_units, paired_identity, signature
from evaluation.episodes.records import ran
from evaluation.stats.run_data import RunData
from evaluation.stats.statistics import (
    bootstrap_mean_interval,
    bootstrap_tail_interval,
    holm_adjusted,
    paired_comparison,
    tail_mean,
    wilson_interval,
)
from koopman_envs.checks import check_choice

__all__ = ["TAIL_SHARE", "AxisProfile", "LevelCost", "LevelRow", "level_costs", "profiles"]

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
    #: ``m``: the distinct paired tests of the sweep (every axis) that Holm's adjustment ran over
    family_size: int = 0

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


def _by_unit(results: RunData, controller: str, slip_axis: bool) -> dict[Unit, dict[str, Any]]:
    return {_unit(r, slip_axis): r for r in results.records if r["controller"] == controller and ran(r)}


def _level_row(
    controller: str, level: Any, mine: dict, reference: dict | None, context: Hashable = None
) -> tuple[LevelRow, Hashable]:
    """The row of ``controller`` at ``level`` and the identity of its paired test against the
    reference (None without one): tests on the same data count once in the Holm family."""
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
    identity: Hashable = None
    if reference is not None:
        # units sharing a cell whose two episodes repeat an earlier unit's count once
        shared = distinct_units(sorted(set(mine) & set(reference)), mine, reference, cell_of=lambda u: u[:3])
        if shared:
            identity = paired_identity(context, shared, mine, reference)
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
                "discordant": test.only_a + test.only_b,
                "distance_difference": float(np.mean(gaps)),
                "distance_low": g_low,
                "distance_high": g_high,
            }
    return row, identity


def profiles(
    sweep: Mapping[str, Sequence[tuple[Any, RunData]]], reference: str | None = None
) -> list[AxisProfile]:
    """The robustness profile of every axis of a sweep.

    Parameters
    ----------
    sweep : mapping
        Axis key -> [(level, that level's run), ...], as :func:`evaluation.experiments.sweep.run_sweep` and
        :func:`evaluation.experiments.sweep.load_sweep` return it (a run is read for its records and config).
    reference : str, optional
        The controller every other is paired against (default: the first controller of the run).

    Returns
    -------
    list of AxisProfile
        One per axis, in order; every paired test also carries Holm's adjustment over every
        paired test of the sweep (``p_holm``).

    Raises
    ------
    ValueError
        ``reference`` is not one of the run's controllers.
    """
    out = []
    tests_identities: list[Hashable] = []
    for key, levels in sweep.items():
        controllers = list(levels[0][1].config["controllers"])
        ref = reference or controllers[0]
        check_choice("--reference", ref, controllers, sep=" ", among="the run's controllers")
        slip_axis = key == "slip"
        profile = AxisProfile(key, [level for level, _ in levels], ref)
        identities = []
        for controller in controllers:
            per_level = [_by_unit(results, controller, slip_axis) for _, results in levels]
            ref_level = [_by_unit(results, ref, slip_axis) for _, results in levels]
            for (level, results), mine, theirs in zip(levels, per_level, ref_level, strict=True):
                row, identity = _level_row(
                    controller, level, mine, None if controller == ref else theirs, (key, level)
                )
                if row.paired:
                    identities.append(identity)
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
        tests_identities.extend(identities)
    # every paired test of the sweep as one family (a test on the same data as another, a
    # bit-identical twin's, counted once): Holm's adjustment beside the raw p
    tests = [row.paired for profile in out for row in profile.rows if row.paired]
    adjusted_p = holm_adjusted((t["p_value"] for t in tests), same=tests_identities)
    for test, adjusted in zip(tests, adjusted_p, strict=True):
        test["p_holm"] = adjusted
    for profile in out:
        profile.family_size = len(set(tests_identities))
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


@dataclass
class LevelCost:
    """What a level of an axis costs one controller: its success there against its success at
    the axis's first level, on the episode units both share (paired; rates in [0, 1])."""

    key: str
    controller: str
    level: Any
    first: Any
    pairs: int
    first_success: float
    success: float
    difference: float
    low: float
    high: float
    p_value: float
    #: Holm's adjustment over every distinct level cost of the sweep (a twin's test counted once)
    p_holm: float = math.nan
    #: the discordant pairs (one level succeeded alone)
    discordant: int = 0
    #: ``m``: the distinct level costs of the sweep that Holm's adjustment ran over
    family_size: int = 0


def level_costs(sweep: Mapping[str, Sequence[tuple[Any, RunData]]]) -> list[LevelCost]:
    """Every controller's cost of every level of every axis against the axis's first level:
    the paired difference in success (Newcombe interval, exact McNemar p) on the shared units
    (distinct ones: a unit whose two episodes repeat an earlier one's of its cell counts once),
    with Holm's adjustment over all of them (e.g. what seeing through a lidar costs each
    controller against exact state, ``--lidar``)."""
    out = []
    identities: list[Hashable] = []
    for key, levels in sweep.items():
        slip_axis = key == "slip"
        first_level, first_run = levels[0]
        for controller in first_run.config["controllers"]:
            first = _by_unit(first_run, controller, slip_axis)
            for level, results in levels[1:]:
                mine = _by_unit(results, controller, slip_axis)
                shared = distinct_units(sorted(set(mine) & set(first)), mine, first, cell_of=lambda u: u[:3])
                if not shared:
                    continue
                now = [bool(mine[u]["success"]) for u in shared]
                before = [bool(first[u]["success"]) for u in shared]
                test = paired_comparison(now, before)
                identities.append(paired_identity((key, level), shared, mine, first))
                out.append(
                    LevelCost(
                        key,
                        controller,
                        level,
                        first_level,
                        len(shared),
                        float(np.mean(before)),
                        float(np.mean(now)),
                        test.difference,
                        test.low,
                        test.high,
                        test.p_value,
                        discordant=test.only_a + test.only_b,
                    )
                )
    # a test on the same data as another (a bit-identical twin's) is one test of the family
    for cost, adjusted in zip(out, holm_adjusted((c.p_value for c in out), same=identities), strict=True):
        cost.p_holm = adjusted
        cost.family_size = len(set(identities))
    return out
