"""--check floors read statistically (the Wilson interval), and rules of controllers that cannot be
built here skipped with the reason unless --strict."""

from __future__ import annotations

import copy

import pytest

import evaluate as ev
import evaluation.reports.thresholds as thresholds
from evaluation.reports.results import Results


@pytest.fixture(scope="module")
def three_of_four() -> Results:
    """Four episodes of one cell, three successes (rate 0.75, Wilson 95% [0.30, 0.95])."""
    run = ev.evaluate(
        ev.RunSpec(
            "KoopNav-TargetReaching-v0",
            ["consensus"],
            maps=["map1"],
            slips=["nominal"],
            episodes=1,
            env_kwargs={"max_episode_steps": 30},
        ),
        workers=1,
    )
    (template,) = run.records
    records = []
    for trial, success in enumerate([True, True, False, True]):
        record = copy.deepcopy(template)
        record.update(
            trial=trial, seed=trial, key=f"{template['key']}#{trial}", success=success, collision=None
        )
        record["final_poses"][0][0] += trial  # four distinct episodes (identical ones count once)
        records.append(record)
    return Results(records, run.config)


def _toml(tmp_path, body: str):
    path = tmp_path / "floors.toml"
    path.write_text(body)
    return path


def test_a_floor_fails_only_when_the_interval_lies_below_it(tmp_path, three_of_four) -> None:
    (cell,) = three_of_four.cells
    assert cell.success_rate == 0.75 and cell.success_ci[1] == pytest.approx(0.954, abs=1e-3)
    rule = '[[cell]]\ncontroller = "consensus"\nmin_success_rate = 0.9\n'
    assert (
        thresholds.check_thresholds(three_of_four, _toml(tmp_path, rule)).problems == []
    )  # default: interval
    point = thresholds.check_thresholds(three_of_four, _toml(tmp_path, 'reading = "point"\n' + rule))
    assert point.reading == "point" and len(point.problems) == 1 and "0.75 < 0.90" in point.problems[0]
    strict_floor = '[[cell]]\ncontroller = "consensus"\nmin_success_rate = 0.99\n'
    (problem,) = thresholds.check_thresholds(three_of_four, _toml(tmp_path, strict_floor)).problems
    assert "95% interval [0.30, 0.95] entirely below 0.99" in problem


def test_a_rule_of_a_controller_not_installed_is_skipped_unless_strict(
    tmp_path, three_of_four, monkeypatch
) -> None:
    monkeypatch.setattr(
        thresholds, "_unusable", lambda name: "needs the [rl] extra" if name == "rl-ppo" else None
    )
    body = '[[cell]]\ncontroller = "rl-ppo"\nmin_success_rate = 0.5\n'
    check = thresholds.check_thresholds(three_of_four, _toml(tmp_path, body))
    assert check.problems == [] and check.skipped == [
        "{'controller': 'rl-ppo', 'min_success_rate': 0.5}: skipped (needs the [rl] extra)"
    ]
    strict = thresholds.check_thresholds(three_of_four, _toml(tmp_path, body), strict=True)
    assert len(strict.problems) == 1 and "--strict" in strict.problems[0]
    # a rule that matches nothing for another reason still fails
    other = thresholds.check_thresholds(
        three_of_four, _toml(tmp_path, '[[cell]]\nmap = "map7"\nmin_success_rate = 0.5\n')
    )
    assert other.problems == ["no evaluated cell matches {'map': 'map7', 'min_success_rate': 0.5}"]


def test_a_bad_reading_is_named(tmp_path, three_of_four) -> None:
    with pytest.raises(ValueError, match=r"reading='median' is not one of \['interval', 'point'\]"):
        thresholds.check_thresholds(
            three_of_four, _toml(tmp_path, 'reading = "median"\n[[cell]]\nmin_success_rate = 0.5\n')
        )
