"""The placeholder numbers of a published sweep (docs/make_prose_md.py): a controller's paired
difference to the sweep's reference at a level (``vsref``), what a level costs a controller
against the axis's first level (``cost``), each with its Holm-adjusted p over the family its page
corrects, and the size of that family (``sweep_tests``), as the sweep's page computes them
(:func:`evaluation.stats.robustness.profiles`, :func:`evaluation.stats.robustness.level_costs`).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the page scripts beside this one

from prose_numbers import Options, Runs, check_args, interval_text, p_text, signed_points  # noqa: E402

from evaluation.reports.sections.blocks import level_text  # noqa: E402
from evaluation.stats.robustness import LevelCost  # noqa: E402

__all__ = ["SWEEP_NUMBERS"]


def _level(value: Any, text: str) -> bool:
    return level_text(value) == text


def _vsref(runs: Runs, args: Sequence[str]) -> dict[str, float]:
    check_args("vsref", args, 3)
    name, controller, level = args
    key, _, value = level.partition("=")
    for profile in runs.sweep(name).profiles:
        for row in profile.rows:
            if (
                profile.key == key
                and row.controller == controller
                and _level(row.level, value)
                and row.paired
            ):
                return row.paired
    raise ValueError(f"no paired row of {controller!r} at {level!r} in sweep {name!r}")


def vsref(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``vsref SWEEP CONTROLLER KEY=LEVEL``: CONTROLLER's success minus the sweep's reference
    controller's at that level, paired, in points with Newcombe's interval (the sweep page's
    robustness table)."""
    row = _vsref(runs, args)
    return interval_text(row["success_difference"], row["success_low"], row["success_high"])


def vsref_points(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``vsref_points SWEEP CONTROLLER KEY=LEVEL``: that difference to the reference in points
    without sign, ``12`` (the prose says which way)."""
    return f"{abs(100 * _vsref(runs, args)['success_difference']):.0f}"


def vsref_holm(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``vsref_holm SWEEP CONTROLLER KEY=LEVEL``: that comparison's Holm-adjusted p over every
    paired test of the sweep, as its page corrects, ``Holm p = 0.004``."""
    return p_text(_vsref(runs, args)["p_holm"])


def _cost(runs: Runs, args: Sequence[str]) -> LevelCost:
    check_args("cost", args, 3)
    name, controller, level = args
    key, _, value = level.partition("=")
    for cost in runs.sweep(name).costs:
        if cost.key == key and cost.controller == controller and _level(cost.level, value):
            return cost
    raise ValueError(f"no level cost of {controller!r} at {level!r} in sweep {name!r}")


def cost(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``cost SWEEP CONTROLLER KEY=LEVEL``: CONTROLLER's success at that level minus at the
    axis's first level, paired, in points with Newcombe's interval (the page's level costs)."""
    c = _cost(runs, args)
    return interval_text(c.difference, c.low, c.high)


def cost_points(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``cost_points SWEEP CONTROLLER KEY=LEVEL``: that level cost in points without sign,
    ``24`` (the prose says which way)."""
    return f"{abs(100 * _cost(runs, args).difference):.0f}"


def cost_change(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``cost_change SWEEP CONTROLLER KEY=LEVEL``: that level cost in points with its sign,
    ``-18`` (``span min``/``span max`` over controllers: ``within -6 and +2 points``)."""
    return signed_points(_cost(runs, args).difference)


def cost_holm(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``cost_holm SWEEP CONTROLLER KEY=LEVEL``: that level cost's Holm-adjusted p over every
    level cost of the sweep, as its page corrects, ``Holm p = 0.010``."""
    return p_text(_cost(runs, args).p_holm)


def sweep_tests(runs: Runs, args: Sequence[str], options: Options) -> str:
    """``sweep_tests SWEEP``: the paired tests against the reference over every level of the
    sweep (the family ``vsref_holm`` corrects over), a bit-identical twin's test counted once as
    its page counts it, ``6``."""
    check_args("sweep_tests", args, 1)
    tests = [
        row.paired | {"level": row.level}
        for p in runs.sweep(args[0]).profiles
        for row in p.rows
        if row.paired
    ]
    # a twin's test is on the same episodes: every one of its numbers equals its base's
    keys = ("level", "pairs", "success_difference", "p_value", "distance_difference")
    same = {tuple(test[k] for k in keys) for test in tests if not math.isnan(test["p_value"])}
    return str(len(same))


#: every sweep number function by name
SWEEP_NUMBERS = {
    f.__name__: f
    for f in (vsref, vsref_points, vsref_holm, cost, cost_points, cost_change, cost_holm, sweep_tests)
}
