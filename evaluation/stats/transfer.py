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
  verdict holds on the other plant.

Statistics only: docs/make_sim2sim_md.py writes the page.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from evaluation.episodes.runlog import run_signature
from evaluation.stats.robustness import LevelCost, level_costs
from evaluation.stats.run_data import RunData
from evaluation.stats.statistics import wilson_interval

__all__ = [
    "TRANSFER_ALPHA",
    "Ordering",
    "PlantRow",
    "check_same_protocol",
    "ordering_verdict",
    "orderings",
    "plant_differences",
]

#: the family-wise level at which an ordering counts as a verdict (Holm-adjusted p below it)
TRANSFER_ALPHA = 0.05

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
    for key in sorted(set(first) | set(second)):
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
