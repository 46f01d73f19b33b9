"""Sim-to-sim transfer: one protocol run on two plants, compared episode for episode.

The sim-to-sim protocol (issue 62, docs/sim2sim_results.md) runs the same controllers, cells and
seeds on the kinematic plant and on the physics plant (``--plant mujoco``), each swept over the
friction level (``--sweep slip=nominal,high``: carpet and ice on the physics plant; gravel,
``low``, is left out for its calibration cost, docs/physics.md).
Two runs are the same protocol when their settings differ by the plant only
(:func:`check_same_protocol`); then per friction level:

- :func:`plant_differences`: every controller's success on the second plant against the first on
  the units both ran (env, map, slip, trial: the same layout, starts and seed), the paired
  difference with Newcombe's interval and the exact McNemar test, Holm-adjusted within the level
  (:func:`evaluation.stats.robustness.level_costs`, the axis being the plant);
- :func:`orderings`: which controller beats which on each plant (the run's own paired table,
  :meth:`evaluation.stats.run_data.RunData.paired`, Holm-adjusted over its pairs) and whether the
  verdict holds on the other plant;
- :func:`rank_agreement`: whether the controllers' ranking by success transfers at all, the
  pairwise rule being silent at small samples: Kendall's tau-b between the two plants' success
  rates, with a percentile bootstrap interval that resamples (task, layout) clusters
  (:func:`kendall_tau_b`); :func:`significant_changes`: the controllers whose own
  difference between the plants is significant.

A run may be partial (published as it runs): :func:`run_progress` counts each controller's
episodes against what the run's header plans
(:func:`evaluation.stats.progress.planned_episodes`), and :func:`restricted`
keeps the controllers complete on both plants, the only ones any of the above may see.

Statistics only: docs/make_sim2sim_md.py writes the page.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from evaluation.episodes.distinct import episode_identity
from evaluation.episodes.log_weights import PRESETS_KEY, WEIGHTS_KEY
from evaluation.episodes.records import ran
from evaluation.episodes.runlog import run_signature
from evaluation.run.suite_runs import cluster_of
from evaluation.stats.progress import Progress, planned_episodes
from evaluation.stats.robustness import LevelCost, level_costs
from evaluation.stats.run_data import RunData
from evaluation.stats.statistics import wilson_interval

__all__ = [
    "RANK_RESAMPLES",
    "RANK_SEED",
    "TRANSFER_ALPHA",
    "Ordering",
    "PlantRow",
    "RankAgreement",
    "check_same_protocol",
    "kendall_tau_b",
    "ordering_verdict",
    "orderings",
    "plant_differences",
    "rank_agreement",
    "restricted",
    "run_progress",
    "significant_changes",
]

#: the family-wise level at which an ordering counts as a verdict (Holm-adjusted p below it)
TRANSFER_ALPHA = 0.05

#: the bootstrap of :func:`rank_agreement`: resamples and seed (fixed, so a page is byte-stable)
RANK_RESAMPLES = 2000
RANK_SEED = 0

#: the env settings that may differ between the two runs of one sim-to-sim comparison
_MAY_DIFFER = ("plant",)


@dataclass(frozen=True)
class PlantRow:
    """One controller at one friction level on both plants, on the units both ran.

    Attributes
    ----------
    controller : str
        The configuration's label.
    pairs : int
        Paired units (distinct ones: a repeated pair of episodes counts once).
    first, second : float
        Success rates on the first (kinematic) and second (physics) plant, in [0, 1].
    first_interval, second_interval : tuple of float
        Their 95% Wilson intervals.
    difference, low, high : float
        ``second - first`` and its 95% Newcombe interval.
    p_value, p_holm : float
        Exact McNemar p and its Holm adjustment over the level's controllers.
    discordant : int
        The discordant pairs (the controller succeeded on one plant alone).
    family_size : int
        ``m``, the distinct tests the Holm adjustment ran over (0: not known).
    """

    controller: str
    pairs: int
    first: float
    first_interval: tuple[float, float]
    second: float
    second_interval: tuple[float, float]
    difference: float
    low: float
    high: float
    p_value: float
    p_holm: float
    discordant: int = 0
    family_size: int = 0


@dataclass(frozen=True)
class Ordering:
    """The verdict on one pair of controllers of one task at one friction level, on each plant.

    ``first`` and ``second`` are +1 where ``a`` succeeds significantly more often than ``b`` on
    that plant (Holm-adjusted p < :data:`TRANSFER_ALPHA`), -1 where ``b`` does, 0 without a verdict.
    """

    env_id: str
    a: str
    b: str
    first: int
    second: int

    @property
    def verdict(self) -> str:
        """``"holds"``, ``"lost"`` (no verdict on the second plant), ``"reversed"``, ``"new"``
        (a verdict on the second plant only) or ``"none"`` (on neither)."""
        return ordering_verdict(self.first, self.second)


def ordering_verdict(first: int, second: int) -> str:
    """What became of the first plant's verdict ``first`` (+1, -1 or 0) on the second plant."""
    if first == 0:
        return "none" if second == 0 else "new"
    if second == first:
        return "holds"
    return "lost" if second == 0 else "reversed"


def _config_differences(first: Mapping[str, Any], second: Mapping[str, Any]) -> list[str]:
    """The settings of two run configurations that differ, beyond the plant: of what a resume
    checks (:func:`evaluation.episodes.runlog.run_signature`, everything that changes what an
    episode does; the workers and the backend do not)."""
    first, second = run_signature(dict(first)), run_signature(dict(second))
    differ = []
    # the learned controllers' weights and the tuned presets are compared when both runs record
    # them (a run logged before they were recorded has none: evaluation.run.weights)
    keys = set(first) | set(second)
    for digests in (WEIGHTS_KEY, PRESETS_KEY):
        if digests not in first or digests not in second:
            keys.discard(digests)
    for key in sorted(keys):
        a, b = first.get(key), second.get(key)
        if key == "env_settings":
            a = {k: v for k, v in (a or {}).items() if k not in _MAY_DIFFER}
            b = {k: v for k, v in (b or {}).items() if k not in _MAY_DIFFER}
        if a != b:
            differ.append(key)
    return differ


def check_same_protocol(first: Mapping[str, Any], second: Mapping[str, Any]) -> None:
    """Refuse two runs that are not one protocol on two plants.

    Parameters
    ----------
    first, second : dict
        The two runs' configurations (a level's ``Results.config``).

    Raises
    ------
    ValueError
        A setting other than the plant differs (each named), or both runs are on one plant.
    """
    differ = _config_differences(first, second)
    if differ:
        raise ValueError(
            f"the two runs differ in {differ}, not only in the plant: a sim-to-sim pair must run the "
            "same controllers, cells, seeds and settings on both plants"
        )
    plants = [(config.get("env_settings") or {}).get("plant", "kinematic") for config in (first, second)]
    if plants[0] == plants[1]:
        raise ValueError(f"both runs are on the {plants[0]!r} plant; give one run per plant")


def _row(cost: LevelCost) -> PlantRow:
    """A :class:`PlantRow` from the level cost of the second plant against the first."""
    # level_costs' rates are means of booleans over its units, so these counts are exact
    before, now = round(cost.first_success * cost.pairs), round(cost.success * cost.pairs)
    return PlantRow(
        cost.controller,
        cost.pairs,
        cost.first_success,
        wilson_interval(before, cost.pairs),
        cost.success,
        wilson_interval(now, cost.pairs),
        cost.difference,
        cost.low,
        cost.high,
        cost.p_value,
        cost.p_holm,
        cost.discordant,
        cost.family_size,
    )


def plant_differences(first: RunData, second: RunData) -> list[PlantRow]:
    """Every controller's success on ``second``'s plant against ``first``'s, paired on the units
    both ran (one friction level; Holm's adjustment over the level's controllers).

    Parameters
    ----------
    first, second : RunData
        The same friction level of the two runs (:func:`check_same_protocol`).

    Returns
    -------
    list of PlantRow
        One per controller of ``first`` with a shared unit, in the run's order.
    """
    check_same_protocol(first.config, second.config)
    costs = level_costs({"plant": [("first", first), ("second", second)]})
    return [_row(cost) for cost in costs]


def _verdicts(run: RunData, alpha: float) -> dict[tuple[str, str, str], int]:
    """(task, a, b) -> +1, -1 or 0 from the run's paired table (Holm-adjusted over its pairs)."""
    out = {}
    for row in run.paired():
        significant = not math.isnan(row["p_holm"]) and row["p_holm"] < alpha
        sign = (row["difference"] > 0) - (row["difference"] < 0)
        out[(row["env_id"], row["a"], row["b"])] = sign if significant else 0
    return out


def orderings(first: RunData, second: RunData, alpha: float = TRANSFER_ALPHA) -> list[Ordering]:
    """Every pair of controllers of each task compared on both plants (one friction level).

    Parameters
    ----------
    first, second : RunData
        The same friction level of the two runs (:func:`check_same_protocol`).
    alpha : float
        The Holm-adjusted p below which a paired difference is a verdict.

    Returns
    -------
    list of Ordering
        One per pair compared on both plants, in the first run's table order.
    """
    check_same_protocol(first.config, second.config)
    before, after = _verdicts(first, alpha), _verdicts(second, alpha)
    return [Ordering(*key, sign, after[key]) for key, sign in before.items() if key in after]


# --------------------------------------------------------------------------- partial runs
def run_progress(run: RunData) -> dict[str, Progress]:
    """Controller -> its episodes logged (each once, whatever its status: an error is an
    outcome) of those the run's header plans over its tasks, for every controller it declares."""
    config = run.config
    done: dict[str, set[tuple]] = {}
    for record in run.records:
        done.setdefault(record["controller"], set()).add(episode_identity(record))
    planned = sum(planned_episodes(config, env_id) for env_id in config["env_ids"])
    return {label: Progress(len(done.get(label, ())), planned) for label in config["controllers"]}


def restricted(run: RunData, controllers: Sequence[str]) -> RunData:
    """``run`` with the records of ``controllers`` only (its header unchanged)."""
    keep = set(controllers)
    return type(run)([r for r in run.records if r["controller"] in keep], run.config)


# --------------------------------------------------------------------------- rank agreement
@dataclass(frozen=True)
class RankAgreement:
    """Kendall's tau-b between the controllers' success rates on two plants.

    Attributes
    ----------
    tau : float
        On the data (NaN when either plant's rates are all tied).
    low, high : float
        Its percentile bootstrap interval (:data:`RANK_RESAMPLES` resamples of the clusters with
        replacement, each controller's rate recomputed on both plants from the same resample).
    controllers, clusters : int
        How many controllers were ranked, over how many clusters.
    resamples : int
        The resamples with a tau (a resample where a plant's rates all tie has none).
    """

    tau: float
    low: float
    high: float
    controllers: int
    clusters: int
    resamples: int


def kendall_tau_b(x: Any, y: Any) -> Any:
    """Kendall's tau-b of ``x`` and ``y`` along their last axis (rows are separate samples):
    ``(concordant - discordant) / sqrt((pairs - ties in x) (pairs - ties in y))``; NaN where
    either is constant. As ``scipy.stats.kendalltau``'s default, vectorised over rows."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if x.shape != y.shape or x.shape[-1] < 2:
        raise ValueError(f"kendall_tau_b needs two equal shapes of 2 or more items; got {x.shape}, {y.shape}")
    i, j = np.triu_indices(x.shape[-1], 1)
    dx, dy = np.sign(x[..., i] - x[..., j]), np.sign(y[..., i] - y[..., j])
    denominator = np.sqrt((dx * dx).sum(-1) * (dy * dy).sum(-1))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(denominator > 0, (dx * dy).sum(-1) / denominator, np.nan)


def _task_cluster(record: Mapping[str, Any]) -> Hashable:
    """An episode's cluster for :func:`rank_agreement`: its task and its layout (or its trial's
    seed outside a suite: :func:`~evaluation.run.suite_runs.cluster_of`), so that layout 3 of
    one task and of the other are two clusters."""
    return (record["env_id"], cluster_of(record))


def rank_agreement(
    first: RunData,
    second: RunData,
    controllers: Sequence[str],
    resamples: int = RANK_RESAMPLES,
    seed: int = RANK_SEED,
    confidence: float = 0.95,
) -> RankAgreement:
    """How well ``controllers``' ranking by success on ``first``'s plant agrees with ``second``'s.

    Each controller's success rate on each plant over the units both plants ran (env, map,
    trial: the same episode on both), every task pooled; Kendall's tau-b of the two rates over
    the controllers (1: the same order, -1: reversed; ties as tau-b counts them). Its interval
    resamples the clusters (:func:`_task_cluster`) with replacement, the same resample on both plants
    and for every controller (a layout is hard for all), seeded: the same data give the same
    interval.

    Raises
    ------
    ValueError
        Fewer than two controllers, or ``resamples`` below 1.
    """
    labels = list(dict.fromkeys(controllers))
    if len(labels) < 2:
        raise ValueError(f"rank agreement needs two or more controllers; got {labels}")
    if resamples < 1:
        raise ValueError(f"resamples must be 1 or more; got {resamples}")
    column = {label: k for k, label in enumerate(labels)}

    def outcomes(run: RunData) -> dict[tuple, dict[str, Any]]:
        return {
            (r["controller"], r["env_id"], r["map"], int(r["trial"])): r
            for r in run.records
            if r["controller"] in column and ran(r)
        }

    before, after = outcomes(first), outcomes(second)
    shared = sorted(set(before) & set(after), key=repr)
    clusters = list(dict.fromkeys(sorted((_task_cluster(before[u]) for u in shared), key=repr)))
    row = {c: n for n, c in enumerate(clusters)}
    # successes on each plant and episodes, per (cluster, controller): integers, so every sum is exact
    wins = np.zeros((2, len(clusters), len(labels)))
    counts = np.zeros((len(clusters), len(labels)))
    for unit in shared:
        at = row[_task_cluster(before[unit])], column[unit[0]]
        counts[at] += 1
        wins[(0, *at)] += bool(before[unit]["success"])
        wins[(1, *at)] += bool(after[unit]["success"])
    with np.errstate(invalid="ignore", divide="ignore"):
        tau = float(kendall_tau_b(wins[0].sum(0) / counts.sum(0), wins[1].sum(0) / counts.sum(0)))
        rng = np.random.default_rng(seed)
        drawn = rng.integers(0, len(clusters), size=(resamples, len(clusters))) if clusters else None
        taus = np.empty(0)
        if drawn is not None:
            weights = np.stack([np.bincount(d, minlength=len(clusters)) for d in drawn]).astype(float)
            n = weights @ counts
            taus = kendall_tau_b((weights @ wins[0]) / n, (weights @ wins[1]) / n)
            taus = taus[~np.isnan(taus)]
    tail = 100 * (1 - confidence) / 2
    low, high = math.nan, math.nan
    if taus.size:
        low, high = (float(v) for v in np.percentile(taus, [tail, 100 - tail]))
    return RankAgreement(tau, low, high, len(labels), len(clusters), int(taus.size))


def significant_changes(rows: Sequence[PlantRow], alpha: float = TRANSFER_ALPHA) -> list[PlantRow]:
    """The rows whose own difference between the plants is significant: Holm-adjusted p (over
    the level's controllers, :func:`plant_differences`) below ``alpha``."""
    return [row for row in rows if not math.isnan(row.p_holm) and row.p_holm < alpha]
