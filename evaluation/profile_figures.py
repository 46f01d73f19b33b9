"""The robustness profiles as figures a reader can read: small multiples by controller family,
one colour per controller in every figure, identical twins drawn once, units on every axis, and
categorical levels as points with intervals (a line between two presets means nothing).

Used by :func:`evaluation.robustness.write_robustness`; matplotlib only.
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

# the profiles are evaluation.robustness's AxisProfile and LevelRow (not imported: that module
# imports this one)
AxisProfile = Any
LevelRow = Any

__all__ = ["FAMILIES", "axis_label", "colour_of", "family_of", "save_profile_figures", "twins"]

#: the families a figure's rows group controllers into, in order
FAMILIES = ("central NMPCs", "distributed NMPCs", "consensus and filters", "learned policies")

#: units of the swept keys (the axis labels)
_UNITS = {
    "pose_noise.xy": "localization noise, x and y [m]",
    "pose_noise.heading": "localization noise, heading [rad]",
    "actuation_delay": "actuation delay [periods of 0.1 s]",
    "comm.latency": "message latency [periods of 0.1 s]",
    "comm.drop": "message loss [probability]",
    "comm.range": "radio range [m]",
    "movers.count": "moving obstacles [count]",
    "movers.speed": "mover speed [m/s]",
    "lidar.noise": "lidar noise [m]",
    "uncertainty": "uncertainty preset",
    "slip": "slip setting",
    "n_robots": "team size [robots]",
}

#: the built-in controllers in a fixed order: each keeps its palette slot in every figure
_FIXED = (
    "koopman-nmpc",
    "nominal-nmpc",
    "koopman-nmpc-robust",
    "nominal-nmpc-robust",
    "adaptive-koopman-nmpc",
    "dmpc-koopman",
    "dmpc-nominal",
    "dmpc-koopman-robust",
    "dmpc-nominal-robust",
    "consensus",
    "consensus-free",
    "rl-ppo",
    "rl-ppo-set",
    "rl-ppo-set-realistic",
    "rl-ppo-set-movers",
    "orca",
    "dwa",
)


def family_of(label: str) -> str:
    """The family of a controller by its label (:data:`FAMILIES`)."""
    name = label.split(":")[-1]
    if label.startswith("rl-") or "ppo" in name or "mappo" in name:
        return FAMILIES[3]
    if name.startswith("dmpc"):
        return FAMILIES[1]
    if "nmpc" in name and not label.startswith("safe:"):
        return FAMILIES[0]
    return FAMILIES[2]


def colour_of(label: str) -> Any:
    """The controller's colour, the same in every figure: a fixed slot for the built-in ones, a
    slot from the label's checksum for any other."""
    import matplotlib

    palette = matplotlib.colormaps["tab20"]
    slot = _FIXED.index(label) if label in _FIXED else zlib.crc32(label.encode()) % 20
    # the strong shade of each of the ten hues first, then the light ones
    return palette((2 * slot) % 20 + (slot // 10) % 2)


def axis_label(key: str) -> str:
    """The x-axis label of a swept key, with its unit."""
    return _UNITS.get(key, key)


def _signature(curve: Sequence[LevelRow]) -> tuple:
    return tuple((r.episodes, r.successes, round(r.distance, 9)) for r in curve)


def twins(profile: AxisProfile) -> list[list[str]]:
    """The controllers of ``profile`` grouped by identical curves (every level the same episodes,
    successes and mean distance): each group is drawn as one series."""
    groups: dict[tuple, list[str]] = {}
    for controller in profile.controllers:
        groups.setdefault(_signature(profile.curve(controller)), []).append(controller)
    return list(groups.values())


def _numeric(levels: Sequence[Any]) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in levels)


def _draw(
    axis: Any, x: np.ndarray, y: list[float], low: list[float], high: list[float], style: dict, lines: bool
) -> None:
    values = np.asarray(y, dtype=float)
    err = np.vstack([values - np.asarray(low, dtype=float), np.asarray(high, dtype=float) - values])
    err = np.nan_to_num(np.maximum(err, 0.0))
    if lines:
        axis.plot(x, values, **style)
        axis.fill_between(x, low, high, alpha=0.10, color=style["color"])
    else:  # categorical levels: points with interval bars
        axis.errorbar(
            x,
            values,
            yerr=err,
            fmt=style["marker"],
            color=style["color"],
            capsize=2,
            ms=4,
            label=style["label"],
        )


def save_profile_figures(axes: Sequence[AxisProfile], out_dir: Path) -> list[Path]:
    """One figure per axis: a row per controller family present, success (Wilson interval) and
    final distance (bootstrap interval) against the level; twins merged, named in the legend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for profile in axes:
        groups = twins(profile)
        families = [f for f in FAMILIES if any(family_of(g[0]) == f for g in groups)]
        lines = _numeric(profile.levels)
        x = np.asarray(profile.levels, dtype=float) if lines else np.arange(len(profile.levels), dtype=float)
        fig, grid = plt.subplots(
            len(families), 2, figsize=(10, 2.7 * len(families) + 0.6), squeeze=False, sharex=True
        )
        for row, family in enumerate(families):
            left, right = grid[row]
            members = [g for g in groups if family_of(g[0]) == family]
            for number, group in enumerate(members):
                curve = profile.curve(group[0])
                offset = 0.0 if lines else (number - (len(members) - 1) / 2) * 0.06
                style = {
                    "color": colour_of(group[0]),
                    "marker": "osD^v<>p*h"[number % 10],
                    "label": " = ".join(group),
                    "ms": 4,
                }
                _draw(
                    left,
                    x + offset,
                    [100 * r.success for r in curve],
                    [100 * r.success_low for r in curve],
                    [100 * r.success_high for r in curve],
                    style,
                    lines,
                )
                _draw(
                    right,
                    x + offset,
                    [r.distance for r in curve],
                    [r.distance_low for r in curve],
                    [r.distance_high for r in curve],
                    {**style, "label": None},
                    lines,
                )
            left.set_ylim(-3, 103)
            left.set_ylabel(f"{family}\nsuccess [%]", fontsize=8)
            right.set_ylabel("final distance [cm]", fontsize=8)
            left.legend(fontsize=6, frameon=False, loc="best")
            for axis in (left, right):
                axis.grid(alpha=0.3)
                axis.tick_params(labelsize=7)
        for axis in grid[-1]:
            axis.set_xlabel(axis_label(profile.key), fontsize=8)
            axis.set_xticks(x, [str(v) for v in profile.levels])  # the levels run, nothing between
        fig.suptitle(
            f"Robustness to {axis_label(profile.key)}: success (95% Wilson) and final distance (95% bootstrap)",
            fontsize=9,
        )
        fig.tight_layout()
        path = out_dir / f"robustness_{profile.key.replace('.', '_')}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths
