"""A run's results with their formats: :class:`Results` is the run's data
(:class:`~evaluation.stats.run_data.RunData`) plus its Markdown and HTML reports
(:mod:`evaluation.reports.sections`, :mod:`evaluation.reports.html`), JSON, CSV and figures
(:mod:`evaluation.reports.figures`), and the files they are written to. A sweep's robustness profiles
(:mod:`evaluation.stats.robustness`) are written the same way by :func:`write_profiles`: both go
through one writer of a report's files; several runs' documents pool into one :class:`Results`
(:func:`pooled_results`), and a run's evaluator command is rebuilt from its configuration
(:func:`evaluate_command`). The renderers read the data classes, not this module, so nothing
imports back here."""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import evaluation.reports.sections as report
import koopman_envs
from evaluation.episodes.distinct import read_once
from evaluation.episodes.records import json_safe
from evaluation.reports.figures import save_figures, save_profile_figures
from evaluation.reports.html import render_html, render_page, write_page
from evaluation.stats.robustness import AxisProfile
from evaluation.stats.run_data import RunData
from koopman_envs.files import write_atomic
from koopman_envs.params import PARAMS

__all__ = [
    "PROFILES_TITLE",
    "Results",
    "SCHEMA_VERSION",
    "evaluate_command",
    "json_safe",
    "pooled_results",
    "profiles_json",
    "write_profiles",
]

SCHEMA_VERSION = 2

#: the title of a sweep's report (robustness.md and robustness.html)
PROFILES_TITLE = "KoopNav robustness profiles"


class Results(RunData):
    """A run's records, cells and configuration (:class:`~evaluation.stats.run_data.RunData`) with
    their formats: Markdown, JSON, CSV and the report files."""

    # ------------------------------------------------------------------ Markdown views
    def leaderboard_table(self) -> str:
        """The leaderboard as a Markdown table (see :func:`evaluation.reports.sections.leaderboard_rows`)."""
        return report.markdown_table(report.leaderboard_rows(self))

    def terminal_summary(self, paths: dict[str, Path]) -> str:
        """The compact leaderboard a terminal gets, and where the full report is."""
        return report.terminal_summary(self, paths)

    def to_markdown(self) -> str:
        """The report (:func:`evaluation.reports.sections.sections`) as Markdown."""
        return report.markdown(report.sections(self))

    def to_json(self) -> str:
        """Versioned JSON document (see ``docs/results.schema.json``)."""
        doc = {
            "schema_version": SCHEMA_VERSION,
            "package_version": koopman_envs.__version__,
            "config": self.config,
            "leaderboard": self.leaderboard(),
            "paired_comparisons": self.paired(),
            # a suite run's success per layout tier and family (absent from other runs' files)
            **({"suite_breakdown": self.suite_breakdown()} if self.config.get("suite") else {}),
            # a suite run's rates and metrics over layouts, and its tested tables (one family each)
            **(
                {"suite_summary": self.layout_summary, "suite_tests": self.suite_tables}
                if self.config.get("suite")
                else {}
            ),
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
            # a suite run's layout columns (absent from other runs' files)
            *(("layout", "layout_family", "layout_tier") if self.config.get("suite") else ()),
            "status",
            "success",
            "strict_success",
            "success_excusing_unavoidable",
            "collision",
            "collision_at_fault",
            "steps",
            "time_to_goal",
            "final_distance",
            "path_length",
            "control_effort",
            "formation_rms",
            "straight_distance",
            "accel_rms",
            "jerk_rms",
            "near_obstacle_share",
            "path_ratio",
            "min_clearance",
            "clearance_min_m",
            "solve_ms_median",
            "solve_ms_p95",
            "solver_failures",
            "error",
        ]
        writer = csv.DictWriter(buffer, fieldnames=fields, extrasaction="ignore")
        writer.writeheader()
        for rec in self.records:
            row = dict(rec)
            for key in (
                "final_distance",
                "path_length",
                "control_effort",
                "straight_distance",
                "accel_rms",
                "jerk_rms",
                "near_obstacle_share",
            ):
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
        (see :func:`evaluation.reports.html.render_html`).
        """
        files = {
            "markdown": ("results.md", self.to_markdown() + "\n"),
            "json": ("results.json", self.to_json() + "\n"),
            "csv": ("results.csv", self.to_csv()),
        }
        return _write_report(
            out_dir,
            files,
            lambda folder: save_figures(self, folder),
            ("index.html", lambda figures: render_html(self, out_dir, figures)),
        )


def profiles_json(axes: Sequence[AxisProfile]) -> str:
    """The profiles as the JSON document ``robustness.json`` holds: per axis its key, levels,
    reference, summary per controller and every row."""
    data = [
        {
            "key": p.key,
            "levels": p.levels,
            "reference": p.reference,
            "summary": p.summary,
            "rows": [asdict(r) for r in p.rows],
        }
        for p in axes
    ]
    return json.dumps(json_safe(data), indent=1)


def write_profiles(axes: Sequence[AxisProfile], out: str | os.PathLike, command: str = "") -> dict[str, Path]:
    """Write a sweep's report under ``out``, as :meth:`Results.write` writes a run's.

    Parameters
    ----------
    axes : sequence of AxisProfile
        The profiles (:func:`evaluation.stats.robustness.profiles`).
    out : str or path-like
        The sweep's output directory (created if missing).
    command : str, optional
        The command that ran the sweep, quoted at the top of the report.

    Returns
    -------
    dict
        ``markdown``, ``json`` and ``html``: the paths of ``robustness.md``, ``robustness.json``
        and ``robustness.html`` (self-contained, with the figures ``figures/robustness_*.png``).
    """
    sections = report.robustness_sections(axes, command)
    files = {
        "markdown": ("robustness.md", f"# {PROFILES_TITLE}\n\n" + report.markdown(sections) + "\n"),
        "json": ("robustness.json", profiles_json(axes) + "\n"),
    }
    return _write_report(
        out,
        files,
        lambda folder: save_profile_figures(axes, folder),
        ("robustness.html", lambda figures: render_page(PROFILES_TITLE, sections, figures)),
    )


def _write_report(
    out_dir: str | os.PathLike,
    files: Mapping[str, tuple[str, str]],
    draw: Callable[[Path], list[Path]],
    page: tuple[str, Callable[[list[Path]], str]],
) -> dict[str, Path]:
    """The one writer of a report's files, a run's or a sweep's: each format's text, the figures
    drawn into ``out_dir/figures``, then the page that embeds them (:func:`evaluation.reports.html.write_page`).

    ``files`` maps a format to its (file name, text), ``draw`` writes the figures into the folder
    it is given and returns their paths, and ``page`` is the page's (file name, renderer of the
    figures' paths). Returns every format's path, the page's as ``html``, in that order.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {}
    for kind, (name, text) in files.items():
        # whole or not at all: a full disk leaves the previous file, and the error names the file
        paths[kind] = write_atomic(out / name, text)
    figures = draw(out / "figures")
    name, render = page
    paths["html"] = write_page(out / name, render(figures))
    return paths


def pooled_results(docs: Sequence[Mapping[str, Any]]) -> Results:
    """Every document's episodes in one :class:`Results`, each episode once.

    Parameters
    ----------
    docs : sequence of mapping
        Results documents (``episodes``, ``config``, and ``source``: where each was read, for the
        messages); the first one's configuration is the pool's.

    Returns
    -------
    Results
        The pooled run: an episode in two documents alike counts once.

    Raises
    ------
    ValueError
        Two documents disagree about an episode (naming both places,
        :func:`evaluation.episodes.distinct.read_once`).
    """
    records = [r for d in docs for r in d["episodes"]]
    places = [f"{d['source']} episodes[{i}]" for d in docs for i in range(len(d["episodes"]))]
    return Results(read_once(records, "the pooled results", places), docs[0]["config"])


def evaluate_command(config: Mapping[str, Any]) -> str:
    """The evaluate.py command line of a run, from its recorded configuration.

    Parameters
    ----------
    config : mapping
        A run's configuration (a results document's ``config``, or one rebuilt from an archive's
        episode log).

    Returns
    -------
    str
        ``python evaluate.py --env ... --maps ... --slips ... --episodes N [--env-kwargs ...]
        [--max-episode-steps N] --controllers ...``: each controller with its options and label,
        the env keywords beyond those with their own flags, the time limit where it is not the
        default.
    """
    maps = sorted({m for names in config["maps"].values() for m in names})
    controllers = []
    for c in config["controller_configs"]:
        options = dict(c["options"])
        if c["label"] != c["name"]:
            options["label"] = c["label"]
        # values as the CLI parses them (JSON scalars; text as is)
        text = {k: v if isinstance(v, str) else json.dumps(v) for k, v in options.items()}
        controllers.append(
            c["name"] + (":" + ",".join(f"{k}={v}" for k, v in text.items()) if options else "")
        )
    # env keywords beyond those with their own flags (goal tolerance, time limit, start noise)
    own_flags = ("goal_tolerance", "max_episode_steps", "start_noise")
    extra = {k: v for k, v in config.get("env_settings", {}).items() if k not in own_flags}
    env_kwargs = (
        (" --env-kwargs " + " ".join(f"{k}={json.dumps(v)}" for k, v in extra.items())) if extra else ""
    )
    # the time limit as the run recorded it: env_settings always has it (a config rebuilt from
    # an archive's episode log has no top-level copy)
    steps = config.get("env_settings", {}).get("max_episode_steps", config.get("max_episode_steps"))
    if steps not in (None, PARAMS.max_episode_steps):
        env_kwargs += f" --max-episode-steps {steps}"
    return (
        f"python evaluate.py --env {' '.join(config['env_ids'])} --maps {' '.join(maps)} "
        f"--slips {' '.join(config['slips'])} --episodes {config['episodes']}{env_kwargs} "
        f"--controllers {' '.join(controllers)}"
    )
