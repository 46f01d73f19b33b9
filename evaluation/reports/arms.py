"""Arms of an experiment across published runs (docs/compute.md, docs/make_compute_md.py): one
controller's episodes of one run, keyed by episode (task, map, slip, seed), read back from their
archives (:func:`load_arms`), each arm summarised (:func:`arm_stats`), two arms paired on the
episodes both ran (:func:`shared_comparison`, :func:`replicated`) and a declared family of such
comparisons Holm-adjusted together (:func:`tested_family`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evaluation.reports.publications import extracted_archive
from evaluation.reports.published import results_from_log
from evaluation.stats.statistics import PairedComparison, holm_adjusted, paired_comparison

__all__ = [
    "Arm",
    "ArmKey",
    "TestedPair",
    "arm_stats",
    "episode_key",
    "load_arms",
    "ok_records",
    "replicated",
    "shared_comparison",
    "tested_family",
]

#: an episode's pairing key: task, map, slip, seed
ArmKey = tuple[str, str, str, int]
#: an arm's records by episode key
ArmRecords = dict[ArmKey, dict[str, Any]]


@dataclass(frozen=True)
class Arm:
    """One arm: where its records are and what differs from the experiment's baseline arm."""

    name: str
    archive: str  # the archive's stem (data/<archive>.tar.xz)
    level: str  # the sweep level's folder, "" for a run without a sweep
    label: str  # the controller label in that run
    what: str


def ok_records(archive: Path, level: str) -> list[dict[str, Any]]:
    """The episode records of ``archive``'s run that ended without an error.

    Parameters
    ----------
    archive : Path
        A published archive (``data/NAME.tar.xz``).
    level : str
        Its sweep level's folder, or ``""`` for a run without a sweep.

    Returns
    -------
    list of dict
        The records of status ``ok``, read as every page reads a log
        (:func:`evaluation.reports.published.results_from_log`: each record checked, an episode
        logged twice read once, two records of it that disagree refused by name).
    """
    with extracted_archive(archive) as run:
        log = run / "sweep" / level / "episodes.jsonl" if level else run / "episodes.jsonl"
        rows = results_from_log(log).records
    return [r for r in rows if r.get("status") == "ok"]


def episode_key(record: Mapping[str, Any]) -> ArmKey:
    """An episode record's pairing key: (task, map, slip, seed)."""
    return (record["env_id"], record["map"], record["slip"], int(record["seed"]))


def load_arms(arms: Sequence[Arm], archives: Mapping[str, Path]) -> dict[str, ArmRecords]:
    """Every arm's records by episode key, each archive (and sweep level) read once.

    Parameters
    ----------
    arms : sequence of Arm
        The experiment's arms.
    archives : mapping of str to Path
        Archive stem -> its path.

    Returns
    -------
    dict
        Arm name -> its records by :func:`episode_key`.

    Raises
    ------
    ValueError
        An arm's archive is not among ``archives`` (naming it and those given).
    """
    cache: dict[tuple[str, str], list[dict[str, Any]]] = {}
    out = {}
    for arm in arms:
        if arm.archive not in archives:
            raise ValueError(f"no archive {arm.archive}.tar.xz among {sorted(archives)}")
        source = (arm.archive, arm.level)
        if source not in cache:
            cache[source] = ok_records(archives[arm.archive], arm.level)
        out[arm.name] = {episode_key(r): r for r in cache[source] if r["controller"] == arm.label}
    return out


def shared_comparison(a: ArmRecords, b: ArmRecords) -> PairedComparison:
    """Paired comparison of two arms on the episodes both ran (success, a minus b).

    Raises
    ------
    ValueError
        The two arms share no episode.
    """
    keys = sorted(set(a) & set(b))
    if not keys:
        raise ValueError("two arms share no episode")
    return paired_comparison([a[k]["success"] for k in keys], [b[k]["success"] for k in keys])


def arm_stats(records: ArmRecords) -> dict[str, Any]:
    """An arm's outcomes: success, failure kinds, clearance of the successes and how often the
    margins were widened.

    Parameters
    ----------
    records : dict
        The arm's records by episode key.

    Returns
    -------
    dict
        ``n``, ``success`` (count), ``kinds`` (failures by obstacle contact, robot contact only,
        time limit), ``median_clearance_cm`` of the successes (NaN for none), ``skim`` (successes
        within 1 cm of an obstacle) and ``tightened`` (the share of decisions whose margins the
        chance constraints widened).
    """
    rows = list(records.values())
    wins = [r for r in rows if r["success"]]
    clearances = sorted(
        r["min_clearance"]["obstacle"] for r in wins if r["min_clearance"]["obstacle"] is not None
    )
    tightened = sum(r.get("controller_extra", {}).get("tightened", 0) for r in rows)
    decisions = sum(r.get("decisions") or r["steps"] for r in rows)
    kinds = {"obstacle": 0, "robot": 0, "time limit": 0}
    for r in rows:
        if not r["success"]:  # a contact names its kinds, "obstacle+robot" for both at once
            hit = r["collision"] or ""
            kinds["obstacle" if "obstacle" in hit else "robot" if hit else "time limit"] += 1
    return {
        "n": len(rows),
        "success": len(wins),
        "kinds": kinds,
        "median_clearance_cm": 100 * clearances[len(clearances) // 2] if clearances else float("nan"),
        "skim": sum(c < 0.01 for c in clearances),
        "tightened": tightened / decisions if decisions else 0.0,
    }


def replicated(a: ArmRecords, b: ArmRecords) -> tuple[int, int, float]:
    """How ``b`` repeats ``a`` on their shared episodes.

    Returns
    -------
    (int, int, float)
        How many end alike (outcome, collision and step count), how many were shared, and the
        largest difference of a final pose coordinate.
    """
    keys = sorted(set(a) & set(b))
    same = sum(
        1 for k in keys if all(a[k][f] == b[k][f] for f in ("success", "collision", "truncated", "steps"))
    )
    largest = max(
        (float(np.max(np.abs(np.subtract(a[k]["final_poses"], b[k]["final_poses"])))) for k in keys),
        default=0.0,
    )
    return same, len(keys), largest


@dataclass(frozen=True)
class TestedPair:
    """One comparison of a declared family with its Holm-adjusted p-value."""

    a: str
    b: str
    question: str
    result: PairedComparison
    holm: float
    alpha: float = 0.05

    @property
    def significant(self) -> bool:
        """Whether the difference is significant within its family: its Holm-adjusted p-value is
        below ``alpha`` (strictly)."""
        return self.holm < self.alpha


def tested_family(
    arms: Mapping[str, ArmRecords],
    comparisons: Sequence[tuple[str, str, str]],
    alpha: float = 0.05,
) -> dict[tuple[str, str], TestedPair]:
    """Every comparison of a family declared before the runs, Holm-adjusted together.

    Parameters
    ----------
    arms : mapping of str to dict
        Arm name -> its records by episode key (those to compare, already selected).
    comparisons : sequence of (str, str, str)
        (arm a, arm b, the question the pair answers).
    alpha : float
        The family's significance level (Holm-adjusted).

    Returns
    -------
    dict
        (a, b) -> its :class:`TestedPair`, in the family's order.
    """
    results = [shared_comparison(arms[a], arms[b]) for a, b, _ in comparisons]
    adjusted = holm_adjusted([r.p_value for r in results])
    return {
        (a, b): TestedPair(a, b, question, result, holm, alpha)
        for (a, b, question), result, holm in zip(comparisons, results, adjusted)
    }
