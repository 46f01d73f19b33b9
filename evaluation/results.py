"""What a run produced, and its reports: Markdown, JSON, CSV and figures, all with intervals."""

from __future__ import annotations

import csv
import io
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import koopman_envs
from evaluation.plan import safe_file_name
from evaluation.aggregate import Cell, aggregate, leaderboard, paired_comparisons
from evaluation.statistics import wilson_interval
from koopman_envs.tasks.base import TASKS

__all__ = ["Results", "SCHEMA_VERSION", "json_safe", "task_label"]

SCHEMA_VERSION = 2
_LABELS = {spec.env_id: spec.label for spec in TASKS.values()}


def task_label(env_id: str) -> str:
    """Report name of a task ("formation"), or the id itself for an unknown one."""
    return _LABELS.get(env_id, env_id)


def json_safe(value: Any) -> Any:
    """NaN and inf become null (JSON has no such numbers); tuples become lists."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value


def _pct(rate: float, ci: tuple[float, float] | list[float]) -> str:
    """``80% [49-94]``: a rate with its interval, in percent."""
    if rate is None or math.isnan(rate):
        return "-"
    return f"{100 * rate:.0f}% [{100 * ci[0]:.0f}-{100 * ci[1]:.0f}]"


def _count(k: int, n: int, ci: tuple[float, float]) -> str:
    """``8/10 [49-94%]``."""
    if n == 0:
        return "-"
    return f"{k}/{n} [{100 * ci[0]:.0f}-{100 * ci[1]:.0f}%]"


def _mean_ci(mean: float, low: float, high: float) -> str:
    if mean is None or math.isnan(mean):
        return "-"
    return f"{mean:.1f} [{low:.1f}-{high:.1f}]"


def _mean_sd(mean: float, sd: float, runs: int) -> str:
    if runs == 0 or math.isnan(mean):
        return "-"
    return f"{mean:.1f}" if runs == 1 else f"{mean:.1f}+-{sd:.1f}"


def _p_value(p: float) -> str:
    return "<0.001" if p < 1e-3 else f"{p:.3f}"


#: A report table: its header and its rows, every cell already formatted as text.
Table = tuple[list[str], list[list[str]]]

LEADERBOARD_NOTE = (
    "Success: every robot settled within tolerance without collision. Collision-free: the paper's SR. "
    "Intervals: 95% Wilson for rates, 95% bootstrap for mean final distances (team mean per run). "
    "Final distances over settled runs and over collision-free runs (the paper's convention)."
)
PAIRED_NOTE = (
    "Success of a minus success of b on the episodes both ran (same map, slip and seed): "
    "Newcombe's 95% interval for paired proportions and the exact McNemar test on the discordant pairs."
)
TABLES_NOTE = (
    "Success and SR: k/n [95% Wilson interval]. Robots: mean+-SD over collision-free runs (the paper's "
    "convention). Team: mean over robots per run, mean [95% bootstrap interval]."
)


def _markdown(table: Table) -> str:
    """A :data:`Table` as a Markdown table."""
    header, rows = table
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


@dataclass
class Results:
    """Everything a run produced: episode records, cells, and the run configuration."""

    records: list[dict[str, Any]]
    config: dict[str, Any]
    cells: list[Cell] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not self.cells:
            self.cells = aggregate(self.records)

    @property
    def failed_episodes(self) -> list[dict[str, Any]]:
        """Records of episodes that raised."""
        return [r for r in self.records if r["status"] != "ok"]

    def cell(self, env_id: str, controller: str, map_name: str, slip: str) -> Cell:
        """One cell by its coordinates."""
        for c in self.cells:
            if (c.env_id, c.controller, c.map, c.slip) == (env_id, controller, map_name, slip):
                return c
        raise KeyError((env_id, controller, map_name, slip))

    def leaderboard(self) -> list[dict[str, Any]]:
        """One row per (task, controller), ranked; see :func:`evaluation.aggregate.leaderboard`."""
        return leaderboard(self.cells, self.records)

    def paired(self) -> list[dict[str, Any]]:
        """Paired comparisons of every two controllers of a task on their shared seeds."""
        return paired_comparisons(self.records)

    def table_keys(self) -> list[tuple[str, str]]:
        """(env id, controller) of every per-controller table, in report order."""
        return [(env_id, name) for env_id in dict.fromkeys(c.env_id for c in self.cells)
                for name in dict.fromkeys(c.controller for c in self.cells if c.env_id == env_id)]  # fmt: skip

    # ------------------------------------------------------------------ tables
    def paper_rows(self, env_id: str, controller: str) -> Table:
        """Header and formatted rows of one controller's paper-style table (one row per map and slip)."""
        cells = [c for c in self.cells if c.env_id == env_id and c.controller == controller]
        n = max((len(c.distance_collision_free.per_robot) for c in cells), default=0)
        header = ["Map", "Slip", "Success", "SR (collision-free)", *(f"Robot {i + 1} [cm]" for i in range(n)),
                  "team, collision-free [cm]", "team, settled [cm]"]  # fmt: skip
        rows = []
        for c in cells:
            free = c.distance_collision_free
            settled = c.distance_settled
            rows.append([
                c.map, c.slip, _count(c.successes, c.valid, c.success_ci),
                _count(c.collision_free, c.valid, c.collision_free_ci),
                *(_mean_sd(m, s, free.runs) for m, s in free.per_robot),
                _mean_ci(free.team_mean, free.team_low, free.team_high),
                _mean_ci(settled.team_mean, settled.team_low, settled.team_high),
            ])  # fmt: skip
        return header, rows

    def paper_table(self, env_id: str, controller: str) -> str:
        """The paper-style table of one controller: rates with intervals, distances in both conventions."""
        table = self.paper_rows(env_id, controller)
        if not table[1]:
            return ""
        return f"**{controller}, {task_label(env_id)}**\n\n" + _markdown(table)

    def paired_rows(self) -> Table:
        """Header and formatted rows of the paired comparisons (success rate of a minus b)."""
        header = ["Task", "a", "b", "Pairs", "Success a", "Success b", "a - b [95% CI]", "only a / only b",
                  "McNemar p"]  # fmt: skip
        rows = []
        for r in self.paired():
            rows.append([
                task_label(r["env_id"]), r["a"], r["b"], str(r["n"]), f"{100 * r['rate_a']:.0f}%",
                f"{100 * r['rate_b']:.0f}%",
                f"{100 * r['difference']:+.0f} [{100 * r['low']:+.0f}, {100 * r['high']:+.0f}]",
                f"{r['only_a']} / {r['only_b']}", _p_value(r["p_value"]),
            ])  # fmt: skip
        return header, rows

    def paired_table(self) -> str:
        """Markdown table of the paired comparisons (success rate of a minus b)."""
        table = self.paired_rows()
        return _markdown(table) if table[1] else ""

    def leaderboard_rows(self) -> Table:
        """Header and formatted rows of the leaderboard (ranked within each task)."""
        header = ["Rank", "Task", "Controller", "Episodes", "Success [95% CI]", "Collision-free [95% CI]",
                  "Final dist., settled [cm]", "Final dist., collision-free [cm]", "Solver", "Solve median [ms]",
                  "Solver failures"]  # fmt: skip
        rows = []
        rank, last_env = 0, None
        for row in self.leaderboard():
            rank = 1 if row["env_id"] != last_env else rank + 1
            last_env = row["env_id"]
            solve = "-" if math.isnan(row["solve_ms_median"]) else f"{row['solve_ms_median']:.1f}"
            rows.append([
                str(rank), task_label(row["env_id"]), row["controller"], str(row["episodes"]),
                _pct(row["success_rate"], row["success_ci"]),
                _pct(row["collision_free_rate"], row["collision_free_ci"]),
                _mean_ci(row["final_distance_cm"], *row["final_distance_ci"]),
                _mean_ci(row["final_distance_collision_free_cm"], *row["final_distance_collision_free_ci"]),
                row.get("solver") or "-", solve, str(row["solver_failures"]),
            ])  # fmt: skip
        return header, rows

    def leaderboard_table(self) -> str:
        """Markdown leaderboard with intervals."""
        return _markdown(self.leaderboard_rows())

    def terminal_summary(self, paths: dict[str, Path]) -> str:
        """The compact leaderboard a terminal gets (rank, controller, episodes, success with its
        interval, settled final distance, solver and its median time) and where the full report is."""
        header, rows = self.leaderboard_rows()
        keep = [header.index(name) for name in ("Rank", "Task", "Controller", "Episodes", "Success [95% CI]",
                                                "Final dist., settled [cm]", "Solver", "Solve median [ms]")]  # fmt: skip
        table = _markdown(([header[i] for i in keep], [[row[i] for i in keep] for row in rows]))
        cells = sorted({(c.map, c.slip) for c in self.cells})
        note = (f"{len(self.records)} episodes over {len(cells)} map/slip cells "
                f"({', '.join(f'{m} {s}' for m, s in cells)}); success = every robot settled within tolerance "
                "without collision; 95% Wilson intervals. Few episodes per controller give wide intervals: "
                "a smoke test, not a ranking.")  # fmt: skip
        lines = [table, "", note]
        reports = [str(paths[k]) for k in ("markdown", "html") if k in paths]
        if reports:
            lines.append(f"Full report (paired comparisons on shared seeds, per-cell tables, figures): "
                         f"{', '.join(reports)}")  # fmt: skip
        return "\n".join(lines)

    def calibration_note(self) -> str:
        """The sentence on the calibration budget every controller was offered ("" when the config has none)."""
        calibration = self.config.get("calibration", {})
        if not calibration:
            return ""
        return (f"Calibration: every controller was offered the same plant (the env's robots in an open field, "
                f"slip means hidden) with a budget of {calibration.get('budget'):,} team-transitions, seed "
                f"{calibration.get('seed')}; the per-cell tables list what each used.")  # fmt: skip

    def calibration_used(self) -> str:
        """Calibration data each controller used ("" when none did)."""
        used = [c for c in self.cells if c.calibration_transitions is not None]
        if not used:
            return ""
        return "Calibration data used (team-transitions): " + ", ".join(
            sorted({f"{c.controller} {c.calibration_transitions:,}" for c in used}))  # fmt: skip

    def to_markdown(self) -> str:
        """Leaderboard, paired comparisons and every paper-style table, as Markdown."""
        out = ["## Leaderboard", "", self.leaderboard_table(), "", LEADERBOARD_NOTE]
        if self.calibration_note():
            out += ["", self.calibration_note()]
        paired = self.paired_table()
        if paired:
            out += ["", "## Paired comparisons", "", PAIRED_NOTE, "", paired]
        out += ["", "## Per-controller tables", "", TABLES_NOTE, ""]
        for env_id, name in self.table_keys():
            out += [self.paper_table(env_id, name), ""]
        if self.calibration_used():
            out += [self.calibration_used()]
        if self.failed_episodes:
            out += ["", "## Episodes that raised", ""]
            out += [f"- `{r['key']}`: {r['error']}" for r in self.failed_episodes]
        return "\n".join(out)

    def to_json(self) -> str:
        """Versioned JSON document (see ``docs/results.schema.json``)."""
        doc = {
            "schema_version": SCHEMA_VERSION,
            "package_version": koopman_envs.__version__,
            "config": self.config,
            "leaderboard": self.leaderboard(),
            "paired_comparisons": self.paired(),
            "cells": [c.to_dict() for c in self.cells],
            "episodes": [
                {k: v for k, v in r.items() if k not in ("trajectory", "obstacles", "traceback", "solve_ms")}
                for r in self.records
            ],
        }
        return json.dumps(json_safe(doc), indent=1)

    def to_csv(self) -> str:
        """One row per episode."""
        buffer = io.StringIO()
        fields = ["key", "env_id", "controller", "map", "slip", "trial", "seed", "status", "success", "collision",
                  "steps", "time_to_goal", "final_distance", "path_length", "control_effort", "formation_rms",
                  "solve_ms_median", "solve_ms_p95", "solver_failures", "error"]  # fmt: skip
        writer = csv.DictWriter(buffer, fieldnames=fields, extrasaction="ignore")
        writer.writeheader()
        for rec in self.records:
            row = dict(rec)
            for key in ("final_distance", "path_length", "control_effort"):
                if isinstance(row.get(key), list):
                    row[key] = ";".join(f"{v:.5f}" for v in row[key])
            writer.writerow(row)
        return buffer.getvalue()

    # ------------------------------------------------------------------ figures
    def save_figures(self, out_dir: Path) -> list[Path]:
        """One sample trajectory per cell, and success rate by slip (95% Wilson bars) per task."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        from matplotlib.patches import Circle

        out_dir.mkdir(parents=True, exist_ok=True)
        written = []
        samples = [r for r in self.records if r["status"] == "ok" and r.get("trajectory")]
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
        for env_id in dict.fromkeys(c.env_id for c in self.cells):
            fig = Figure(figsize=(5.5, 3.5), dpi=100)
            FigureCanvasAgg(fig)
            ax = fig.add_subplot(1, 1, 1)
            slips = list(dict.fromkeys(c.slip for c in self.cells if c.env_id == env_id))
            names = list(dict.fromkeys(c.controller for c in self.cells if c.env_id == env_id))
            for k, name in enumerate(names):
                rates, lows, highs = [], [], []
                for slip in slips:
                    cells = [c for c in self.cells if (c.env_id, c.controller, c.slip) == (env_id, name, slip)]
                    valid = sum(c.valid for c in cells)
                    won = sum(c.successes for c in cells)
                    low, high = wilson_interval(won, valid)
                    rate = won / valid if valid else float("nan")
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

    def write(self, out_dir: str | os.PathLike) -> dict[str, Path]:
        """Write results.md, results.json, results.csv, figures/ and index.html under ``out_dir``.

        ``index.html`` is one self-contained page with every table and figure
        (see :func:`evaluation.html.write_html`).
        """
        from evaluation.html import write_html  # it imports this module

        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"markdown": out / "results.md", "json": out / "results.json", "csv": out / "results.csv"}
        paths["markdown"].write_text(self.to_markdown() + "\n", encoding="utf-8")
        paths["json"].write_text(self.to_json() + "\n", encoding="utf-8")
        paths["csv"].write_text(self.to_csv(), encoding="utf-8")
        figures = self.save_figures(out / "figures")
        paths["html"] = write_html(self, out, figures)
        return paths
