"""A run's figures (matplotlib, no display): one sample trajectory per cell (with the movers' paths
when the episode had movers), and success rate by slip setting with 95% Wilson bars per task (one
colour per controller, the same in every figure: :func:`evaluation.profile_figures.colour_of`;
the legend beside the axes, off the bars)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from evaluation.aggregate import pooled_rate
from evaluation.plan import safe_file_name
from evaluation.profile_figures import colour_of
from evaluation.records import ran
from evaluation.report import task_label
from evaluation.run_data import RunData
from koopman_envs.movers import MoverConfig, parse_movers

__all__ = ["save_figures", "save_success_figures"]

#: movers in a trajectory figure: path colour (dark and dotted, as in the env's frames)
_MOVER_COLOUR = "0.25"
#: most legend rows in one column beside the success chart
_LEGEND_ROWS = 18


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
    fig.savefig(path)
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
    fig.savefig(path)
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
