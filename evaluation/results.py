"""What a run produced (``Results``: episode records, cells, configuration) and its files:
Markdown and HTML reports (:mod:`evaluation.report`, :mod:`evaluation.html`), JSON, CSV and
figures (:mod:`evaluation.figures`)."""

from __future__ import annotations

import csv
import io
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import koopman_envs
from evaluation import report
from evaluation.aggregate import Cell, aggregate, leaderboard, paired_comparisons
from evaluation.figures import save_figures
from evaluation.html import write_html
from evaluation.records import ran

__all__ = ["Results", "SCHEMA_VERSION", "json_safe"]

SCHEMA_VERSION = 2


def json_safe(value: Any) -> Any:
    """NaN and inf become null (JSON has no such numbers); tuples become lists."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value


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
        return [r for r in self.records if not ran(r)]

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
        return [
            (env_id, name)
            for env_id in dict.fromkeys(c.env_id for c in self.cells)
            for name in dict.fromkeys(c.controller for c in self.cells if c.env_id == env_id)
        ]

    # ------------------------------------------------------------------ Markdown views
    def leaderboard_table(self) -> str:
        """The leaderboard as a Markdown table (see :func:`evaluation.report.leaderboard_rows`)."""
        return report.markdown_table(report.leaderboard_rows(self))

    def terminal_summary(self, paths: dict[str, Path]) -> str:
        """The compact leaderboard a terminal gets, and where the full report is."""
        return report.terminal_summary(self, paths)

    def to_markdown(self) -> str:
        """The report (:func:`evaluation.report.sections`) as Markdown."""
        return report.markdown(report.sections(self))

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
        fields = [
            "key",
            "env_id",
            "controller",
            "map",
            "slip",
            "trial",
            "seed",
            "status",
            "success",
            "collision",
            "steps",
            "time_to_goal",
            "final_distance",
            "path_length",
            "control_effort",
            "formation_rms",
            "solve_ms_median",
            "solve_ms_p95",
            "solver_failures",
            "error",
        ]
        writer = csv.DictWriter(buffer, fieldnames=fields, extrasaction="ignore")
        writer.writeheader()
        for rec in self.records:
            row = dict(rec)
            for key in ("final_distance", "path_length", "control_effort"):
                if isinstance(row.get(key), list):
                    row[key] = ";".join(f"{v:.5f}" for v in row[key])
            writer.writerow(row)
        return buffer.getvalue()

    def write(self, out_dir: str | os.PathLike) -> dict[str, Path]:
        """Write results.md, results.json, results.csv, figures/ and index.html under ``out_dir``.

        ``index.html`` is one self-contained page with every table and figure
        (see :func:`evaluation.html.write_html`).
        """
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"markdown": out / "results.md", "json": out / "results.json", "csv": out / "results.csv"}
        paths["markdown"].write_text(self.to_markdown() + "\n", encoding="utf-8")
        paths["json"].write_text(self.to_json() + "\n", encoding="utf-8")
        paths["csv"].write_text(self.to_csv(), encoding="utf-8")
        figures = save_figures(self, out / "figures")
        paths["html"] = write_html(self, out, figures)
        return paths
