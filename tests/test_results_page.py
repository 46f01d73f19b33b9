"""docs/make_results_md.py: the regenerate commands it prints and the team-size table."""

from __future__ import annotations

import importlib.util
import json
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_PATH = ROOT / "docs" / "make_results_md.py"


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


def _published_runs() -> dict[str, str]:
    """data/publish.sh's runs as bash expands them: NAME -> evaluate.py's arguments (the script's
    definitions only; nothing is run)."""
    script = (ROOT / "data" / "publish.sh").read_text(encoding="utf-8")
    definitions = script[: script.index("\nrun() {")]
    show = 'for name in "${!RUNS[@]}"; do printf "%s\\t%s\\n" "$name" "${RUNS[$name]}"; done'
    printed = subprocess.run(
        ["bash", "-c", f"{definitions}\n{show}", str(ROOT / "data" / "publish.sh")],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return dict(line.split("\t", 1) for line in printed.splitlines())


def test_the_pages_regenerate_commands_are_the_published_runs(page):
    """Every run whose command docs/results.md prints (the changing-uncertainty and team-size
    archives of data/pages.json): the command rebuilt from its archive is the one data/publish.sh
    ran, flag for flag (the N = 16 run's --max-episode-steps 300 was left out)."""
    entry = next(
        e for e in json.loads((ROOT / "data" / "pages.json").read_text()) if e["page"] == "docs/results.md"
    )
    args = entry["args"]
    archives, option = [], ""
    for arg in args:  # the values of --uncertainty and --scaling (the sections that print commands)
        option = arg if arg.startswith("--") else option
        archives += [arg] if option in ("--uncertainty", "--scaling") and arg != option else []
    runs = _published_runs()
    assert len(archives) == 9 and "data/scale_n16.tar.xz" in archives
    for archive in archives:
        name = Path(archive).name.removesuffix(".tar.xz")
        config = page.load_results(str(ROOT / archive))["config"]
        assert page._command(config) == f"python evaluate.py {runs[name]}", name


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


def test_the_unequal_data_note_gives_each_learned_policys_budget_from_its_metadata(page):
    """The note gives the policies of the page's `rl-ppo-set` and `ippo` rows, now `rl-ppo-set-v0`
    and `ippo-v0`, the budgets their metadata record (it once gave `rl-ppo-set` ippo's 18 M
    robot-steps per task)."""
    note = " ".join(page._unequal_data({"config": {"calibration": {"budget": 1_000_000}}}))
    for folder, label in (("ippo_v0", "`ippo-v0`"), ("set_v0", "`rl-ppo-set-v0`")):
        budgets = []
        for task in ("target_reaching", "formation"):
            meta = json.loads((ROOT / "baselines" / "policies" / folder / task / "metadata.json").read_text())
            steps = meta["timesteps"] if "timesteps" in meta else meta["frames"] * meta["n_robots"]
            budgets.append(f"{round(steps / 1e6)} M")
        said = f"{budgets[0]} per task" if budgets[0] == budgets[1] else " and ".join(budgets)
        assert f"{label} ({said})" in note, (label, said, note)
