"""The figures of the reports (matplotlib, no display), one colour per controller in every figure
(:func:`colour_of`).

A run's: one sample trajectory per cell (with the movers' paths when the episode had movers), and
success rate by slip setting with 95% Wilson bars per task (the legend beside the axes, off the
bars). A sweep's robustness profiles (:mod:`evaluation.stats.robustness`): small multiples by
controller family, identical twins drawn once, units on every axis, and categorical levels as
points with intervals (a line between two presets means nothing).
"""

from __future__ import annotations

import json
import zlib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from evaluation.episodes.records import ran
from evaluation.reports.sections import task_label
from evaluation.run.plan import safe_file_name
from evaluation.stats.aggregate import pooled_rate
from evaluation.stats.robustness import AxisProfile, LevelRow
from evaluation.stats.run_data import RunData
from koopman_envs.files import write_atomic
from koopman_envs.settings import MoverConfig, parse_movers

__all__ = [
    "FAMILIES",
    "axis_label",
    "colour_of",
    "family_of",
    "save_figures",
    "save_profile_figures",
    "save_success_figures",
    "twins",
]

#: movers in a trajectory figure: path colour (dark and dotted, as in the env's frames)
_MOVER_COLOUR = "0.25"
#: most legend rows in one column beside the success chart
_LEGEND_ROWS = 18

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
    # slot 17: the colour mpc-cbf had from its name's checksum before it was listed
    "mpc-cbf",
    "ippo",
    "rl-ppo-set-physics",
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


# --------------------------------------------------------------------------- a run's figures
def _figure(size: tuple[float, float]) -> tuple[Any, Any]:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=100)
    FigureCanvasAgg(fig)
    return fig, fig.add_subplot(1, 1, 1)


def _mover_radius(rec: dict[str, Any]) -> float:
    """The movers' radius [m] of the episode (its ``movers`` keyword; the default radius when it
    says none or cannot be read)."""
    try:
        return parse_movers("movers", json.loads(rec.get("env_kwargs") or "{}").get("movers")).radius
    except (TypeError, ValueError, AttributeError):
        return MoverConfig().radius


def _draw_movers(ax: Any, paths: Any, radius: float) -> None:
    """The movers' paths (T, C, 2): dotted lines, a small ring where each started and a hatched
    disc of the movers' size where it was at the end (as in the env's frames)."""
    from matplotlib.patches import Circle

    movers = np.asarray(paths, dtype=float)
    if movers.ndim != 3 or not movers.size:
        return
    for c in range(movers.shape[1]):
        ax.plot(movers[:, c, 0], movers[:, c, 1], ls=":", lw=1.0, color=_MOVER_COLOUR, zorder=1.5,
                label="movers" if c == 0 else None)  # fmt: skip
        ax.add_patch(Circle(movers[-1, c], radius, facecolor="0.75", edgecolor=_MOVER_COLOUR, hatch="////",
                            lw=1.0, zorder=1.6))  # fmt: skip
    ax.plot(*movers[0].T, "o", ms=3, mfc="none", mec=_MOVER_COLOUR, zorder=1.6)


def _trajectory_figure(rec: dict[str, Any], path: Path) -> Any:
    from matplotlib.patches import Circle

    fig, ax = _figure((4, 4))
    for x, y, rad in rec["obstacles"] or ():
        ax.add_patch(Circle((x, y), rad, color="0.5"))
    if rec.get("mover_trajectory"):
        _draw_movers(ax, rec["mover_trajectory"], _mover_radius(rec))
    traj = np.asarray(rec["trajectory"])
    for i in range(traj.shape[1]):
        # robot i in the colour the env's frames give it (C0..C6: tab:blue .. tab:pink)
        line = ax.plot(traj[:, i, 0], traj[:, i, 1], lw=1.5, color=f"C{i % 7}", zorder=2)[0]
        ax.plot(*rec["targets"][i][:2], "x", color=line.get_color(), ms=8)
        ax.plot(*traj[0, i], "s", color=line.get_color(), ms=4)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]", fontsize=8)
    ax.set_ylabel("y [m]", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)
    if rec.get("mover_trajectory"):
        ax.legend(fontsize=7, loc="best", framealpha=0.8)
    outcome = "success" if rec["success"] else (rec["collision"] or "time limit")
    ax.set_title(f"{rec['controller']} | {rec['map']} | {rec['slip']} | {outcome}", fontsize=8)
    fig.tight_layout()
    write_atomic(path, fig.savefig)
    return fig


def _success_figure(results: RunData, env_id: str, path: Path) -> Any:
    cells = [c for c in results.cells if c.env_id == env_id]
    slips = list(dict.fromkeys(c.slip for c in cells))
    names = list(dict.fromkeys(c.controller for c in cells))
    columns = 1 if len(names) <= _LEGEND_ROWS else 2
    fig, ax = _figure((5.5 + 1.6 * columns, 3.6))
    dodge = min(0.06, 0.7 / max(len(names), 1))  # the points of one slip setting stay beside it
    for k, name in enumerate(names):
        rates, lows, highs = [], [], []
        for slip in slips:
            rate, (low, high), valid = pooled_rate(c for c in cells if (c.controller, c.slip) == (name, slip))
            rates.append(100 * rate)
            lows.append(100 * (rate - low) if valid else 0.0)
            highs.append(100 * (high - rate) if valid else 0.0)
        x = np.arange(len(slips)) + (k - (len(names) - 1) / 2) * dodge
        ax.errorbar(x, rates, yerr=[lows, highs], fmt="osD^v<>ph*"[k % 10], ms=4, capsize=3, color=colour_of(name),
                    label=name)  # fmt: skip
    ax.set_xticks(np.arange(len(slips)), slips)
    ax.set_ylim(-5, 105)
    ax.set_ylabel("success rate [%] (95% Wilson)")
    ax.set_xlabel("slip setting")
    ax.set_title(task_label(env_id), fontsize=9)
    # beside the axes, so that no entry hides a bar
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, frameon=False,
              ncols=columns)  # fmt: skip
    ax.grid(alpha=0.3)
    fig.tight_layout()
    write_atomic(path, fig.savefig)
    return fig


def save_figures(results: RunData, out_dir: Path) -> list[Path]:
    """Write the figures of ``results`` under ``out_dir`` (created if missing); return their paths.

    ``traj_<cell>.png``: the recorded trajectory of each cell that has one (obstacles, paths,
    starts as squares, targets as crosses; with movers their paths dotted, each ending in a
    disc); ``success_by_slip_<env>.png``: each controller's success rate per slip setting, pooled
    over maps, with its 95% Wilson interval.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for rec in results.records:
        if ran(rec) and rec.get("trajectory"):
            name = safe_file_name(rec["env_id"], rec["controller"], rec["map"], rec["slip"])
            path = out_dir / f"traj_{name}.png"
            _trajectory_figure(rec, path)
            written.append(path)
    for env_id in dict.fromkeys(c.env_id for c in results.cells):
        path = out_dir / f"success_by_slip_{env_id}.png"
        _success_figure(results, env_id, path)
        written.append(path)
    return written


def save_success_figures(results: RunData, out_dir: Path, prefix: str = "") -> list[Path]:
    """Only the success-rate figures of :func:`save_figures` (one per task, named
    ``<prefix>success_by_slip_<env>.png``), for a page that shows no trajectories."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for env_id in dict.fromkeys(c.env_id for c in results.cells):
        path = out_dir / f"{prefix}success_by_slip_{env_id}.png"
        _success_figure(results, env_id, path)
        written.append(path)
    return written


# --------------------------------------------------------------------------- a sweep's figures
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
        write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=110))  # noqa: B023 - called at once
        plt.close(fig)
        paths.append(path)
    return paths
