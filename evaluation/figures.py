"""A run's figures (matplotlib, no display): one sample trajectory per cell, and success rate by
slip setting with 95% Wilson bars per task."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from evaluation.aggregate import pooled_rate
from evaluation.plan import safe_file_name
from evaluation.records import ran
from evaluation.report import task_label
from evaluation.run_data import RunData

__all__ = ["save_figures"]


def save_figures(results: RunData, out_dir: Path) -> list[Path]:
    """Write the figures of ``results`` under ``out_dir`` (created if missing); return their paths.

    ``traj_<cell>.png``: the recorded trajectory of each cell that has one (obstacles, paths,
    starts as squares, targets as crosses); ``success_by_slip_<env>.png``: each controller's
    success rate per slip setting, pooled over maps, with its 95% Wilson interval.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    samples = [r for r in results.records if ran(r) and r.get("trajectory")]
    for rec in samples:
        fig = Figure(figsize=(4, 4), dpi=100)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot(1, 1, 1)
        for x, y, rad in rec["obstacles"]:
            ax.add_patch(Circle((x, y), rad, color="0.5"))
        traj = np.asarray(rec["trajectory"])
        for i in range(traj.shape[1]):
            line = ax.plot(traj[:, i, 0], traj[:, i, 1], lw=1.5)[0]
            ax.plot(*rec["targets"][i][:2], "x", color=line.get_color(), ms=8)
            ax.plot(*traj[0, i], "s", color=line.get_color(), ms=4)
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        outcome = "success" if rec["success"] else (rec["collision"] or "time limit")
        ax.set_title(f"{rec['controller']} | {rec['map']} | {rec['slip']} | {outcome}", fontsize=8)
        name = safe_file_name(rec["env_id"], rec["controller"], rec["map"], rec["slip"])
        path = out_dir / f"traj_{name}.png"
        fig.tight_layout()
        fig.savefig(path)
        written.append(path)
    cells = results.cells
    for env_id in dict.fromkeys(c.env_id for c in cells):
        fig = Figure(figsize=(5.5, 3.5), dpi=100)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot(1, 1, 1)
        slips = list(dict.fromkeys(c.slip for c in cells if c.env_id == env_id))
        names = list(dict.fromkeys(c.controller for c in cells if c.env_id == env_id))
        for k, name in enumerate(names):
            rates, lows, highs = [], [], []
            for slip in slips:
                rate, (low, high), valid = pooled_rate(
                    c for c in cells if (c.env_id, c.controller, c.slip) == (env_id, name, slip)
                )
                rates.append(100 * rate)
                lows.append(100 * (rate - low) if valid else 0.0)
                highs.append(100 * (high - rate) if valid else 0.0)
            # dodge the markers so that overlapping intervals stay readable
            x = np.arange(len(slips)) + (k - (len(names) - 1) / 2) * 0.06
            ax.errorbar(x, rates, yerr=[lows, highs], marker="o", capsize=3, label=name)
        ax.set_xticks(np.arange(len(slips)), slips)
        ax.set_ylim(-5, 105)
        ax.set_ylabel("success rate [%] (95% Wilson)")
        ax.set_xlabel("slip setting")
        ax.set_title(task_label(env_id), fontsize=9)
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        path = out_dir / f"success_by_slip_{env_id}.png"
        fig.savefig(path)
        written.append(path)
    return written
