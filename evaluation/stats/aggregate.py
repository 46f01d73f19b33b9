"""From episode records to cells, leaderboard rows and paired comparisons, each with its interval.

Conventions (the same in every report):

- **success**: every robot settled within tolerance without collision; **SR**: the paper's
  success rate, no collision. Both with 95% Wilson intervals over the cell's valid episodes.
- **final distances** in two labelled conventions: over *collision-free* runs (the paper's, so
  a run that ends 80 cm off its slot counts) and over *settled* (successful) runs. Per robot:
  mean and SD; for the team (mean over robots per run): mean with a 95% bootstrap interval.
- **paired comparisons**: two controllers on the same cells meet the same seeds, so their
  outcomes pair up episode by episode; the difference in success rate gets Newcombe's paired
  interval and an exact McNemar p-value.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from evaluation.episodes.distinct import distinct_records, distinct_units, paired_identity
from evaluation.episodes.records import is_degraded, ran
from evaluation.run.suite_runs import cluster_of
from evaluation.stats.statistics import (
    bootstrap_mean_interval,
    cluster_bootstrap_rate,
    holm_adjusted,
    paired_comparison,
    wilson_interval,
)
from evaluation.stats.suite_statistics import (
    OUTCOMES,
    is_suite_run,
    measure_table,
    suite_mean_interval,
    suite_rate_interval,
)
from koopman_envs import CollisionKind, path_ratio, smallest_clearance

__all__ = [
    "Cell",
    "DistanceSummary",
    "aggregate",
    "leaderboard",
    "paired_comparisons",
    "pooled_rate",
]


def _finite(values: Iterable[Any]) -> list[float]:
    return [float(v) for v in values if v is not None and math.isfinite(v)]


def _nan_reduce(reduce, values: Iterable[Any]) -> float:
    """``reduce`` over the finite values, NaN when there are none (without numpy's warning)."""
    finite = _finite(values)
    return float(reduce(finite)) if finite else float("nan")


def _cell_p95(records: list[dict[str, Any]]) -> float:
    """95th percentile of the decision time over every step of the cell's episodes [ms].

    Records written before per-step times were kept fall back to the largest per-episode p95.
    """
    steps = [t for r in records for t in (r.get("solve_ms") or [])]
    if steps:
        return float(np.percentile(steps, 95))
    return _nan_reduce(np.max, [r.get("solve_ms_p95") for r in records])


@dataclass
class DistanceSummary:
    """Final distances [cm] of one cell under one convention.

    Attributes
    ----------
    runs : int
        Runs the convention counts.
    per_robot : list of (mean, SD)
        Per robot over those runs (NaN when there are none).
    team_mean, team_low, team_high : float
        Mean over runs of the per-run mean over robots, with its 95% bootstrap interval.
    """

    runs: int
    per_robot: list[tuple[float, float]]
    team_mean: float
    team_low: float
    team_high: float

    @classmethod
    def of(cls, records: list[dict[str, Any]], n_robots: int) -> DistanceSummary:
        """Summary of the final distances of ``records`` (metres in, centimetres out)."""
        per_robot = []
        for i in range(n_robots):
            values = np.array([100 * r["final_distance"][i] for r in records], dtype=float)
            if values.size == 0:
                per_robot.append((float("nan"), float("nan")))
            else:
                per_robot.append(
                    (float(values.mean()), float(values.std(ddof=1)) if values.size > 1 else 0.0)
                )
        team = [100 * float(np.mean(r["final_distance"])) for r in records]
        low, high = bootstrap_mean_interval(team)
        return cls(len(records), per_robot, float(np.mean(team)) if team else float("nan"), low, high)


@dataclass
class Cell:
    """Aggregated metrics of one (env, controller, map, slip) cell."""

    env_id: str
    controller: str
    map: str
    slip: str
    episodes: int
    successes: int
    collision_free: int
    errors: int
    distance_collision_free: DistanceSummary
    distance_settled: DistanceSummary
    time_to_goal_s: float
    path_length_m: float
    control_effort: float
    formation_rms_cm: float
    solve_ms_median: float
    solve_ms_p95: float
    solver_failures: int
    calibration_transitions: int | None = None
    degraded: int = 0
    #: episodes that ran and repeat an earlier one of the cell bit for bit (not counted in any rate)
    duplicates: int = 0
    error_messages: list[str] = field(default_factory=list)

    @property
    def valid(self) -> int:
        """Distinct episodes that ran (did not raise): what every rate counts
        (:mod:`evaluation.episodes.distinct`)."""
        return self.episodes - self.errors - self.duplicates

    @property
    def success_rate(self) -> float:
        """Fraction of valid episodes that ended in success."""
        return self.successes / self.valid if self.valid else float("nan")

    @property
    def success_ci(self) -> tuple[float, float]:
        """95% Wilson interval of the success rate."""
        return wilson_interval(self.successes, self.valid)

    @property
    def collision_free_rate(self) -> float:
        """The paper's SR: fraction of valid episodes without collision."""
        return self.collision_free / self.valid if self.valid else float("nan")

    @property
    def collision_free_ci(self) -> tuple[float, float]:
        """95% Wilson interval of the SR."""
        return wilson_interval(self.collision_free, self.valid)

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form with the rates and intervals spelled out."""
        out = {
            k: v for k, v in self.__dict__.items() if k not in ("distance_collision_free", "distance_settled")
        }
        out.update(
            success_rate=self.success_rate,
            success_ci=list(self.success_ci),
            collision_free_rate=self.collision_free_rate,
            collision_free_ci=list(self.collision_free_ci),
            final_distance_cm={
                "collision_free": self.distance_collision_free.__dict__,
                "settled": self.distance_settled.__dict__,
            },
        )
        return out


def aggregate(records: Iterable[dict[str, Any]]) -> list[Cell]:
    """Cells from episode records, in the order they first appear."""
    by_cell: dict[tuple, list[dict]] = {}
    for rec in records:
        by_cell.setdefault((rec["env_id"], rec["controller"], rec["map"], rec["slip"]), []).append(rec)
    cells = []
    for (env_id, name, map_name, slip), recs in by_cell.items():
        ran_here = [r for r in recs if ran(r)]
        ok = distinct_records(ran_here)  # an identical rerun is not a sample
        won = [r for r in ok if r["success"]]
        free = [r for r in ok if r["collision"] is None]
        n_robots = len(ok[0]["final_distance"]) if ok else 0
        calibrations = [r["calibration"] for r in ok if r.get("calibration")]
        cells.append(
            Cell(
                env_id=env_id,
                controller=name,
                map=map_name,
                slip=slip,
                episodes=len(recs),
                successes=len(won),
                collision_free=len(free),
                errors=len(recs) - len(ran_here),
                duplicates=len(ran_here) - len(ok),
                degraded=sum(is_degraded(r) for r in recs),
                distance_collision_free=DistanceSummary.of(free, n_robots),
                distance_settled=DistanceSummary.of(won, n_robots),
                time_to_goal_s=_nan_reduce(np.mean, [r["time_to_goal"] for r in won]),
                path_length_m=_nan_reduce(np.mean, [float(np.mean(r["path_length"])) for r in ok]),
                control_effort=_nan_reduce(np.mean, [float(np.mean(r["control_effort"])) for r in ok]),
                formation_rms_cm=_nan_reduce(
                    np.mean, [100 * r["formation_rms"] for r in ok if r["formation_rms"] is not None]
                ),
                # timings are not outcome samples: every episode that ran
                solve_ms_median=_nan_reduce(np.median, [r["solve_ms_median"] for r in ran_here]),
                solve_ms_p95=_cell_p95(ran_here),
                solver_failures=sum(r["solver_failures"] for r in ok),
                calibration_transitions=max(
                    (int(c.get("transitions", 0)) for c in calibrations), default=None
                ),
                error_messages=sorted({r["error"] for r in recs if not ran(r)}),
            )
        )
    return cells


def collisions_by_kind(records: Iterable[dict[str, Any]]) -> dict[str, int]:
    """Episodes that ended in a collision of each kind (``obstacle``, ``robot``, ``workspace``,
    ``mover``; an episode whose collision combined kinds, ``"robot+mover"``, counts in each)."""
    counts = dict.fromkeys(CollisionKind.NAMES.values(), 0)
    for record in records:
        for kind in (record.get("collision") or "").split("+"):
            if kind in counts:
                counts[kind] += 1
    return counts


def pooled_rate(cells: Iterable[Cell], outcome: str = "successes") -> tuple[float, list[float], int]:
    """A rate pooled over cells: (rate, 95% Wilson interval, valid episodes).

    ``outcome`` is the count pooled: ``"successes"`` or ``"collision_free"``. The rate is NaN
    without valid episodes.
    """
    cells = list(cells)
    valid = sum(c.valid for c in cells)
    count = sum(getattr(c, outcome) for c in cells)
    return (count / valid if valid else float("nan")), list(wilson_interval(count, valid)), valid


def _clustered_interval(
    wilson: list[float],
    records: list[dict[str, Any]],
    outcome: Callable[[Mapping[str, Any]], bool] | None = None,
) -> list[float]:
    """The wider of the Wilson interval over distinct episodes and a bootstrap over the clusters
    of :func:`~evaluation.run.suite_runs.cluster_of` (``outcome``: what counts, default success). In a
    suite run the clusters are layouts (the sample) and the bootstrap is two-stage, layouts then
    episodes within them (:func:`evaluation.stats.suite_statistics.suite_rate_interval`); in other runs they
    are trials (a seed's episodes share its layout, start and slip draws across cells;
    :func:`~evaluation.stats.statistics.cluster_bootstrap_rate`). Wilson covers small samples, where a
    bootstrap of a rate at 0 or 1 has no width; the bootstrap covers the dependence between a
    cluster's episodes, which Wilson assumes away."""
    outcome = outcome or (lambda r: bool(r["success"]))
    # the one place of a rate's clustered interval (the leaderboard's and the suite breakdowns')
    if is_suite_run(records):
        return suite_rate_interval(records, outcome)[1]
    clusters: dict[Any, list[bool]] = {}
    for r in records:
        clusters.setdefault(cluster_of(r), []).append(outcome(r))
    _, low, high = cluster_bootstrap_rate(clusters.values())
    if math.isnan(low):
        return wilson
    return [min(wilson[0], low), max(wilson[1], high)]


def episode_metrics(records: list[dict[str, Any]]) -> dict[str, float]:
    """The metrics robotics papers report, over episodes that ran (NaN where none has them;
    records written before a metric existed lack it):

    - ``time_to_goal_s``: mean over the successes;
    - ``path_ratio``: mean over the successes of the robots' mean path length over
      straight-line distance (robots that start within 10 cm of their target left out; a
      failed episode's path ends early, so it would flatter the ratio);
    - ``min_clearance_cm``: median over episodes of the episode's smallest surface clearance
      to an obstacle, a team-mate or a mover (negative: a collision);
    - ``accel_rms``: mean over episodes and robots of the RMS linear command rate [m/s^2].
    """
    ratios, clearances, accels = [], [], []
    for r in records:
        ratio = path_ratio(r.get("path_length"), r.get("straight_distance")) if r["success"] else None
        if ratio is not None:
            ratios.append(ratio)
        low = smallest_clearance(r.get("min_clearance"))
        if low is not None:
            clearances.append(100 * low)
        if r.get("accel_rms"):
            accels.append(float(np.mean(r["accel_rms"])))
    return {
        "time_to_goal_s": _nan_reduce(np.mean, [r["time_to_goal"] for r in records if r["success"]]),
        "path_ratio": _nan_reduce(np.mean, ratios),
        "min_clearance_cm": _nan_reduce(np.median, clearances),
        "accel_rms": _nan_reduce(np.mean, accels),
    }


def _suite_intervals(recs: list[dict[str, Any]], free_ci: list[float]) -> tuple[list[float], ...]:
    """A leaderboard row's collision-free interval and its final distances' (settled, then
    collision-free): in a suite run every one resamples layouts, then episodes within them;
    otherwise Wilson's and bootstraps over episodes."""
    if not is_suite_run(recs):
        settled = [_team_cm(r) for r in recs if r["success"]]
        free = [_team_cm(r) for r in recs if r["collision"] is None]
        return free_ci, list(bootstrap_mean_interval(settled)), list(bootstrap_mean_interval(free))
    return (
        _clustered_interval(free_ci, recs, lambda r: r["collision"] is None),
        suite_mean_interval(recs, lambda r: _team_cm(r) if r["success"] else None)[1],
        suite_mean_interval(recs, lambda r: _team_cm(r) if r["collision"] is None else None)[1],
    )


def leaderboard(cells: list[Cell], records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (task, controller), ranked by success rate, then mean final distance.

    Rates pool the controller's cells (Wilson intervals over all its valid episodes); the final
    distance is the team mean over its settled runs with a bootstrap interval over those runs.
    """
    rows = []
    for env_id in dict.fromkeys(c.env_id for c in cells):
        for name in dict.fromkeys(c.controller for c in cells if c.env_id == env_id):
            own = [c for c in cells if c.env_id == env_id and c.controller == name]
            success_rate, success_ci, valid = pooled_rate(own, "successes")
            free_rate, free_ci, _ = pooled_rate(own, "collision_free")
            recs = distinct_records(
                [r for r in records if r["env_id"] == env_id and r["controller"] == name and ran(r)]
            )
            settled = [_team_cm(r) for r in recs if r["success"]]
            every = [_team_cm(r) for r in recs]
            free_runs = [_team_cm(r) for r in recs if r["collision"] is None]
            success_ci = _clustered_interval(success_ci, recs)
            free_ci, (d_low, d_high), (f_low, f_high) = _suite_intervals(recs, free_ci)
            rows.append(
                {
                    "env_id": env_id,
                    "controller": name,
                    "episodes": valid,
                    "episodes_run": sum(c.episodes for c in own),
                    "success_rate": success_rate,
                    "success_ci": success_ci,
                    "collision_free_rate": free_rate,
                    "collision_free_ci": free_ci,
                    "final_distance_cm": float(np.mean(settled)) if settled else float("nan"),
                    "final_distance_ci": [d_low, d_high],
                    "final_distance_collision_free_cm": float(np.mean(free_runs))
                    if free_runs
                    else float("nan"),
                    "final_distance_collision_free_ci": [f_low, f_high],
                    # over every episode: what breaks a tie in success (rank_key)
                    "final_distance_all_cm": float(np.mean(every)) if every else float("nan"),
                    **episode_metrics(recs),
                    "solve_ms_median": _nan_reduce(np.median, [c.solve_ms_median for c in own]),
                    # the optimizer(s) behind the row's decisions, as the controllers reported them
                    "solver": ", ".join(
                        sorted(
                            {
                                str(r["controller_extra"]["solver"])
                                for r in recs
                                if (r.get("controller_extra") or {}).get("solver")
                            }
                        )
                    )
                    or None,
                    "solver_failures": sum(c.solver_failures for c in own),
                    # compute-aware runs: decisions longer than the period (over every episode run)
                    "deadline_misses": sum(
                        int(r.get("deadline_misses") or 0)
                        for r in records
                        if r["env_id"] == env_id and r["controller"] == name and ran(r)
                    ),
                    "decisions": sum(
                        int(r.get("decisions") or 0)
                        for r in records
                        if r["env_id"] == env_id and r["controller"] == name and ran(r)
                    ),
                    "collisions_by_kind": collisions_by_kind(recs),
                    "errors": sum(c.errors for c in own),
                    "degraded": sum(c.degraded for c in own),
                }
            )

    def rank_key(row: dict[str, Any]) -> tuple:
        # success first; a tie goes to the smaller final distance over every episode, so that of
        # two controllers that never succeed the one that gets closer ranks first (the settled
        # distance, NaN without a success, cannot tell a controller that never moves from one that
        # tries)
        dist = row["final_distance_all_cm"]
        rate = row["success_rate"]
        return (row["env_id"], -rate if not math.isnan(rate) else 1.0, dist if not math.isnan(dist) else 1e9)

    return sorted(rows, key=rank_key)


def _team_cm(record: Mapping[str, Any]) -> float:
    """An episode's team final distance: the mean over robots [cm]."""
    return 100 * float(np.mean(record["final_distance"]))


def paired_comparisons(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Every pair of controllers of a task, paired on their shared (map, slip, seed) episodes.

    Only episodes that ran for both controllers count, and a seed whose two episodes repeat an
    earlier seed's of the same cell counts once (:func:`evaluation.episodes.distinct.distinct_units`).
    Returns one plain-JSON row per pair with ``a``, ``b``, the cells they share and
    :class:`~evaluation.stats.statistics.PairedComparison` fields (Newcombe's interval, McNemar's exact
    test), Holm's adjustment over the rows in ``p_holm`` and the family's size ``m`` (its distinct
    tests) in ``family_size``.

    A suite run's records (they carry ``layout``) pair on (layout, seed) units with the layout as
    the unit: the rows of its success table (:func:`evaluation.stats.suite_statistics.measure_table`: the
    two-stage bootstrap interval, the layout sign-flip test, Holm within the declared family).
    """
    if is_suite_run(records):
        return measure_table(records, OUTCOMES[0])["rows"]
    outcomes: dict[tuple[str, str], dict[tuple, dict[str, Any]]] = {}
    for r in records:
        if ran(r):
            unit = (r["map"], r["slip"], r["seed"])
            outcomes.setdefault((r["env_id"], r["controller"]), {})[unit] = r
    rows = []
    identities = []
    env_ids = list(dict.fromkeys(env for env, _ in outcomes))
    for env_id in env_ids:
        names = [name for env, name in outcomes if env == env_id]
        for i, a in enumerate(names):
            for b in names[i + 1 :]:
                mine, theirs = outcomes[(env_id, a)], outcomes[(env_id, b)]
                shared = distinct_units(sorted(set(mine) & set(theirs)), mine, theirs)
                if not shared:
                    continue
                comparison = paired_comparison(
                    [bool(mine[k]["success"]) for k in shared], [bool(theirs[k]["success"]) for k in shared]
                )
                cells = sorted({(m, s) for m, s, _ in shared})
                identities.append(paired_identity(env_id, shared, mine, theirs))
                rows.append(
                    {
                        "env_id": env_id,
                        "a": a,
                        "b": b,
                        "cells": [list(c) for c in cells],
                        **comparison.to_dict(),
                        # rliable's probability of improvement on paired binary outcomes: P(a
                        # succeeds where b fails) + half the ties
                        "prob_improvement": (
                            comparison.only_a + 0.5 * (comparison.n - comparison.only_a - comparison.only_b)
                        )
                        / comparison.n,
                    }
                )
    # the table's tests as one family (a test on the same data as another, a bit-identical
    # twin's, counted once): Holm's adjustment beside the raw p
    for row, adjusted in zip(rows, holm_adjusted((r["p_value"] for r in rows), same=identities), strict=True):
        row["p_holm"] = adjusted
        row["family_size"] = len(set(identities))  # m: the distinct tests Holm ran over
    return rows
