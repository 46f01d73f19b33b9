"""docs/make_results_md.py: the regenerate commands it prints and the team-size table."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[1] / "docs" / "make_results_md.py"


@pytest.fixture(scope="module")
def page():
    spec = importlib.util.spec_from_file_location("make_results_md", _PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _config(n_robots: int, max_steps: int = 600) -> dict:
    return {
        "env_ids": ["KoopNav-TargetReaching-v0"],
        "maps": {"KoopNav-TargetReaching-v0": ["random"]},
        "slips": ["nominal"],
        "episodes": 3,
        "max_episode_steps": max_steps,
        "env_settings": {
            "goal_tolerance": 0.1,
            "max_episode_steps": max_steps,
            "start_noise": 0.05,
            "n_robots": n_robots,
        },
        "controller_configs": [
            {"label": "fast", "name": "nominal-nmpc", "options": {"horizon": 10}},
            {"label": "consensus", "name": "consensus", "options": {}},
        ],
    }


def test_regenerate_command_carries_env_keywords_time_limit_and_options(page):
    command = page._command(_config(16, max_steps=300))
    assert "--env-kwargs n_robots=16" in command
    assert "--max-episode-steps 300" in command
    assert "nominal-nmpc:horizon=10,label=fast" in command
    # settings with their own flags are not repeated as env keywords; the default time limit is implied
    default = page._command(_config(3))
    assert "goal_tolerance" not in default and "--max-episode-steps" not in default


def _cell(controller: str, successes: int) -> dict:
    summary = {"runs": successes, "team_mean": 1.0, "team_low": 0.5, "team_high": 1.5, "per_robot": []}
    return {
        "controller": controller,
        "episodes": 3,
        "errors": 0,
        "successes": successes,
        "collision_free": 3,
        "success_ci": [0.1, 0.9],
        "collision_free_ci": [0.4, 1.0],
        "final_distance_cm": {"settled": summary},
        "time_to_goal_s": 9.0,
        "solve_ms_median": 40.0,
        "solve_ms_p95": 90.0,
        "solver_failures": 0,
    }


def test_scaling_table_has_a_row_per_team_size_and_names_what_was_not_run(page):
    small = {"config": _config(3), "cells": [_cell("nominal-nmpc", 2), _cell("consensus", 1)]}
    large = {"config": _config(16, 300), "cells": [_cell("consensus", 3)]}
    text = "\n".join(page.scaling_section([large, small]))
    rows = [line for line in text.splitlines() if line.startswith("| 3 ") or line.startswith("| 16 ")]
    assert [row.split("|")[1].strip() for row in rows] == ["3", "3", "16"]  # sorted by N
    assert "| 3 | nominal-nmpc | 2/3 [10-90%]" in text and "40.0 / 90.0" in text
    assert "Not in this table at N = 16: nominal-nmpc" in text
    assert "Not in this table at N = 3" not in text
