"""The sim-to-sim page's families are the tests it reports (issue 62): a fine-tuned row
(:data:`evaluation.experiments.sim2sim.FINE_TUNED`) is no transfer, so neither the Holm
adjustment of the controllers' own plant differences nor the pairwise verdicts count it; the page
states the family it applied ("Holm over the level's N controllers" with N the table's rows)."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

from evaluation.experiments import sim2sim
from evaluation.reports.results import Results
from evaluation.stats.statistics import holm_adjusted, paired_comparison

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_sim2sim_md import changes_sentence, level_section  # noqa: E402  (docs/ is no package)

ENV = "KoopNav-TargetReaching-v0"
#: per controller, its successes on the kinematic and on the physics plant over the same 8 seeds
OUTCOMES = {
    "a": ([1] * 8, [0] * 8),
    "b": ([1] * 8, [1, 1, 1, 1, 0, 0, 0, 0]),
    "tuned": ([1] * 8, [0, 0, 0, 0, 0, 0, 1, 1]),
}


def _run(plant: str) -> Results:
    config = {
        "env_ids": [ENV],
        "controllers": list(OUTCOMES),
        "maps": {ENV: ["map1"]},
        "slips": ["nominal"],
        "episodes": 8,
        "seed": 0,
        "env_settings": {"plant": plant},
    }
    side = 0 if plant == "kinematic" else 1
    records = [
        {
            "env_id": ENV,
            "controller": name,
            "map": "map1",
            "slip": "nominal",
            "layout": None,
            "trial": trial,
            "seed": trial,
            "status": "ok",
            "success": bool(ok),
            "collision": None,
            "truncated": not ok,
            "steps": 10 + trial,
            "final_distance": [0.05 + 0.01 * trial, 0.1],
            "time_to_goal": 2.0 if ok else None,
            "path_length": [1.0, 1.0],
            "control_effort": [0.5, 0.5],
            "formation_rms": None,
            "solve_ms_median": 1.0,
            "solve_ms_p95": 1.0,
            "solver_failures": 0,
        }
        for name, outcomes in OUTCOMES.items()
        for trial, ok in enumerate(outcomes[side])
    ]
    return Results(records, config)


@pytest.fixture()
def level(monkeypatch) -> sim2sim.Level:
    monkeypatch.setitem(sim2sim.FINE_TUNED, "tuned", "a")
    return sim2sim.level_data("nominal", _run("kinematic"), _run("mujoco"))


def test_the_plant_differences_are_holm_adjusted_over_the_transferred_controllers(level) -> None:
    assert [row.controller for row in level.rows] == ["a", "b", "tuned"]
    assert [row.controller for row in level.transferred] == ["a", "b"]
    raw = [
        paired_comparison([bool(v) for v in physics], [bool(v) for v in kinematic]).p_value
        for kinematic, physics in (OUTCOMES["a"], OUTCOMES["b"])
    ]
    # Holm over a and b alone (on main: over a, b and the fine-tuned row, which triples a's p)
    assert [row.p_holm for row in level.transferred] == pytest.approx(holm_adjusted(raw))
    assert [row.p_value for row in level.transferred] == pytest.approx(raw)


def test_the_page_states_the_family_it_applied(level) -> None:
    assert "Holm over the level's 2 controllers" in changes_sentence(level)
    section = level_section(level)
    assert "Holm's adjustment over the level's 2 tests" in section
    plant_table = section.split("**Fine-tuned")[0]  # the fine-tuned row has its own table after it
    table = [line for line in plant_table.splitlines() if re.match(r"\| (a|b|tuned) \|", line)]
    assert [line.split(" | ")[0] for line in table] == ["| a", "| b"]


def test_no_pairwise_verdict_is_of_a_fine_tuned_row(level) -> None:
    assert {(o.a, o.b) for o in level.found} == {("a", "b")}


def test_the_published_page_states_the_family_of_its_table() -> None:
    """docs/sim2sim_results.md: each level's "Holm over the level's N tests" is its table's rows."""
    text = (ROOT / "docs" / "sim2sim_results.md").read_text(encoding="utf-8")
    for section in re.split(r"^## ", text, flags=re.M)[1:]:
        rows = re.findall(r"^\| [\w-]+ \| \d+ \| \d+% \[", section.split("**Fine-tuned")[0], re.M)
        stated = re.search(r"Holm's adjustment over the level's (\d+) tests", section)
        assert stated is not None and int(stated[1]) == len(rows), section[:40]
