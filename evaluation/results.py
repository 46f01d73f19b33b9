"""A run's results with their formats: :class:`Results` is the run's data
(:class:`~evaluation.run_data.RunData`) plus its Markdown and HTML reports
(:mod:`evaluation.report`, :mod:`evaluation.html`), JSON, CSV and figures
(:mod:`evaluation.figures`), and the files they are written to. The renderers read the data
class, not this one, so nothing imports back here."""

from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

import evaluation.report as report
import koopman_envs
from evaluation.figures import save_figures
from evaluation.html import write_html
from evaluation.records import json_safe
from evaluation.run_data import RunData

__all__ = ["Results", "SCHEMA_VERSION", "json_safe"]

SCHEMA_VERSION = 2


class Results(RunData):
    """A run's records, cells and configuration (:class:`~evaluation.run_data.RunData`) with
    their formats: Markdown, JSON, CSV and the report files."""

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
                {
                    k: v
                    for k, v in r.items()
                    if k not in ("trajectory", "mover_trajectory", "obstacles", "traceback", "solve_ms")
                }
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
            "straight_distance",
            "accel_rms",
            "min_clearance",
            "solve_ms_median",
            "solve_ms_p95",
            "solver_failures",
            "error",
        ]
        writer = csv.DictWriter(buffer, fieldnames=fields, extrasaction="ignore")
        writer.writeheader()
        for rec in self.records:
            row = dict(rec)
            for key in ("final_distance", "path_length", "control_effort", "straight_distance", "accel_rms"):
                if isinstance(row.get(key), list):
                    row[key] = ";".join(f"{v:.5f}" for v in row[key])
            if isinstance(row.get("min_clearance"), dict):
                row["min_clearance"] = ";".join(
                    f"{kind}={'' if v is None else f'{v:.5f}'}" for kind, v in row["min_clearance"].items()
                )
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
