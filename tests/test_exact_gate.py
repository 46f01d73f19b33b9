"""The gate field for field (issue 61): evaluation/reports/reproduced.py's exact_differences, the
command python -m evaluation.exact and bash .ci/leaderboard.sh --exact, on the committed baseline's
records."""

from __future__ import annotations

import copy
import json
import os
import subprocess
from pathlib import Path
from typing import Any

import pytest

from evaluation.exact import main
from evaluation.reports import exact_differences, load_baseline, within_run

ROOT = Path(__file__).resolve().parents[1]
BASELINE = ROOT / ".ci" / "baseline" / "results.json"


@pytest.fixture(scope="module")
def baseline() -> dict[str, Any]:
    return load_baseline(BASELINE)


def _copy(baseline: dict[str, Any]) -> list[dict[str, Any]]:
    return copy.deepcopy(baseline["episodes"])


def test_an_identical_copy_has_no_difference(baseline) -> None:
    comparison = exact_differences(_copy(baseline), baseline["episodes"])
    assert comparison.equal and comparison.problems() == []
    assert comparison.compared == len(baseline["episodes"]) == 800


def test_one_changed_field_is_named_with_both_values(baseline) -> None:
    run = _copy(baseline)
    changed = run[5]
    changed["final_distance"] = [*changed["final_distance"][:-1], changed["final_distance"][-1] + 1e-15]
    comparison = exact_differences(run, baseline["episodes"])
    assert not comparison.equal and comparison.compared == 800
    assert [(d.episode, d.field) for d in comparison.differing] == [
        (f"{changed['key']!r} (seed {changed['seed']})", "final_distance")
    ]
    [line] = comparison.problems()
    assert line.startswith(
        f"{changed['key']!r} (seed 5) differs in final_distance (final_distance: baseline ["
    )


def test_the_timings_are_not_compared(baseline) -> None:
    run = _copy(baseline)
    for record in run:
        record["wall_seconds"] += 1.0
        record["solve_ms_median"] = 123.0
        if isinstance(record.get("calibration"), dict):
            record["calibration"]["seconds"] = 99.0
        if record.get("controller_extra"):
            record["controller_extra"] = {
                k: 7.0 if "_ms_" in k else v for k, v in record["controller_extra"].items()
            }
    assert any(isinstance(r.get("calibration"), dict) for r in run)
    assert any("_ms_" in k for r in run for k in r.get("controller_extra") or {})
    assert exact_differences(run, baseline["episodes"]).equal


def test_a_missing_and_an_extra_episode_are_refused_by_name(baseline) -> None:
    run = _copy(baseline)
    gone = run.pop(7)
    other = copy.deepcopy(run[0])
    other["seed"] = 1000
    run.append(other)
    comparison = exact_differences(run, baseline["episodes"])
    assert comparison.compared == 799 and comparison.differing == ()
    assert comparison.missing == (f"{gone['key']!r} (seed 7)",)
    assert comparison.extra == (f"{other['key']!r} (seed 1000)",)
    assert comparison.problems() == [
        f"missing from the run: {gone['key']!r} (seed 7)",
        f"not in the baseline: {other['key']!r} (seed 1000)",
    ]


def test_within_run_keeps_the_baseline_episodes_a_subset_planned(baseline) -> None:
    config = {
        **baseline["config"],
        "controller_configs": [{"label": "consensus", "name": "consensus", "options": {}}],
        "maps": {"KoopNav-TargetReaching-v0": ["map2"]},
        "episodes": 3,
    }
    kept = within_run(baseline["episodes"], config)
    assert sorted((r["controller"], r["map"], r["trial"]) for r in kept) == [
        ("consensus", "map2", t) for t in range(3)
    ]


def _write_run(path: Path, baseline: dict[str, Any], episodes: list[dict[str, Any]], **config: Any) -> Path:
    doc = {**baseline, "config": {**baseline["config"], **config}, "episodes": episodes}
    path.write_text(json.dumps(doc))
    return path


def test_the_command_exits_101_naming_every_difference(baseline, tmp_path, capsys) -> None:
    run = _copy(baseline)
    run[3]["steps"] += 1
    run.pop(0)
    assert main([str(_write_run(tmp_path / "run.json", baseline, run)), str(BASELINE)]) == 101
    err = capsys.readouterr().err
    assert "does not reproduce the baseline" in err and "(2 episodes; 799 paired)" in err
    assert f"missing from the run: {baseline['episodes'][0]['key']!r} (seed 0)" in err
    steps = baseline["episodes"][3]["steps"]
    assert f"differs in steps (steps: baseline {steps}, run {steps + 1})" in err


def test_the_command_passes_an_equal_run_and_a_subset_only_with_subset(baseline, tmp_path, capsys) -> None:
    assert main([str(_write_run(tmp_path / "all.json", baseline, _copy(baseline))), str(BASELINE)]) == 0
    assert "800 episodes equal to the baseline's field for field" in capsys.readouterr().out
    consensus = [r for r in _copy(baseline) if r["controller"] == "consensus"]
    subset = _write_run(
        tmp_path / "subset.json",
        baseline,
        consensus,
        controllers=["consensus"],
        controller_configs=[{"label": "consensus", "name": "consensus", "options": {}}],
    )
    assert main([str(subset), str(BASELINE), "--subset"]) == 0
    assert "40 episodes equal" in capsys.readouterr().out
    assert main([str(subset), str(BASELINE)]) == 101
    assert "(760 episodes; 40 paired)" in capsys.readouterr().err


def test_the_command_refuses_bad_input(baseline, tmp_path, capsys) -> None:
    assert main([str(tmp_path / "absent.json"), str(BASELINE)]) == 2
    assert "run" in capsys.readouterr().err
    other = _write_run(tmp_path / "other.json", baseline, _copy(baseline), tolerance=0.05)
    other_doc = json.loads(other.read_text())
    other_doc["config"]["env_settings"] = {**other_doc["config"]["env_settings"], "goal_tolerance": 0.05}
    other.write_text(json.dumps(other_doc))
    assert main([str(other), str(BASELINE)]) == 2
    assert "the baseline was run with other settings (env_settings:" in capsys.readouterr().err


@pytest.mark.slow
def test_a_rerun_of_consensus_reproduces_its_baseline_rows_field_for_field(tmp_path) -> None:
    """bash .ci/leaderboard.sh --exact on consensus's 40 gate episodes (about 35 CPU-s): the gate
    passes and every episode equals the committed baseline's, timings aside."""
    environment = {**os.environ, "KOOPNAV_GATE_ARGS": "--controllers consensus"}
    environment.pop("KOOPNAV_GATE_EPISODES", None)
    run = subprocess.run(
        ["bash", str(ROOT / ".ci" / "leaderboard.sh"), "--exact", str(tmp_path / "gate")],
        env=environment,
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-3000:]
    assert "baseline gate passed" in run.stdout
    assert "40 episodes equal to the baseline's field for field, timings aside" in run.stdout
