"""``adopt --confirm``'s record (``data/tuning/NAME/confirmation.json``) is read instead of
rerunning only when it is of the study's best configuration as it is now: a study redone whose
best has the same trial number but other options is confirmed afresh; a torn or foreign record
is rerun and rewritten."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from controllers.tuning.studies import STUDY_FILE
from evaluation.tune.confirm import CONFIRMATION_FILE, confirm

#: a finished task=both study's header fields, as the tuner writes them (one layout per task)
_HEADER = {
    "kind": "koopnav-study",
    "task": "both",
    "split": "validation",
    "suites": ["koopnav-bench-v1/target_reaching/validation@0", "koopnav-bench-v1/formation/validation@0"],
    "seed": 0,
    "budget": {"configurations": 2, "layouts_per_task": 1, "episodes_per_layout": 1},
    "slip": "high",
    "env_kwargs": {},
}
_TRIAL = {
    "episodes": 2,
    "layouts": {"a": [0], "b": [0]},
    "seeds": [0],
    "params": {},
    "errors": 0,
    "mean_time_to_goal": 10.0,
    "wall_seconds": 1.0,
    "budget_so_far": {},
}


def _study(studies: Path, name: str, best: dict[str, Any]) -> None:
    """``studies/NAME/study.jsonl``: trial 0 the defaults (1 of 2), trial 1 ``best`` (2 of 2)."""
    folder = studies / name
    folder.mkdir(parents=True, exist_ok=True)
    lines = [
        {**_HEADER, "controller": name},
        {"trial": 0, "options": {}, "score": 0.25, "successes": 1, **_TRIAL},
        {"trial": 1, "options": best, "score": 0.5, "successes": 2, **_TRIAL},
    ]
    (folder / STUDY_FILE).write_text("".join(json.dumps(line) + "\n" for line in lines))


class Evaluator:
    """The evaluator's stand-in: ``winner``'s options succeed on every unit, any other
    configuration on layouts divisible by 4; every call's options are kept."""

    def __init__(self, winner: dict[str, Any]) -> None:
        self.winner = winner
        self.calls: list[dict[str, Any]] = []

    def __call__(self, controller, options, task, split, layouts, episodes, seed, **kwargs):
        self.calls.append(dict(options))
        wins = dict(options) == self.winner
        return [
            {"suite": label, "layout": layout, "seed": seed + layout, "success": wins or layout % 4 == 0}
            for label in ("a", "b")
            for layout in layouts
        ]


def test_a_record_of_another_best_configuration_with_the_same_trial_number_is_not_read(
    tmp_path: Path,
) -> None:
    studies = tmp_path / "studies"
    _study(studies, "dwa", {"goal_gain": 0.9})
    first = Evaluator({"goal_gain": 0.9})
    confirmed = confirm("dwa", 20, studies, evaluator=first)
    assert confirmed.confirmed and first.calls == [{"goal_gain": 0.9}, {}]
    # the same study read again: its record is read, nothing run
    unused = Evaluator({})
    assert confirm("dwa", 20, studies, evaluator=unused).recorded and unused.calls == []
    # the study redone (another search space, same seed and budget): its best is trial 1 again,
    # with other options, which do no better than the defaults on the fresh layouts
    _study(studies, "dwa", {"goal_gain": 1.3})
    again = Evaluator({"goal_gain": 0.9})
    result = confirm("dwa", 20, studies, evaluator=again)
    assert again.calls == [{"goal_gain": 1.3}, {}], "trial 1's old confirmation was read for new options"
    assert not result.recorded and not result.confirmed and result.best_successes == result.defaults_successes
    record = json.loads((studies / "dwa" / CONFIRMATION_FILE).read_text())
    assert record["best_options"] == {"goal_gain": 1.3} and record["confirmed"] is False


def test_a_record_without_the_best_options_is_matched_by_trial_as_before(tmp_path: Path) -> None:
    """The records written before the options were recorded (consensus's and dwa's committed
    ones) are read by trial number, layouts, settings and rule."""
    studies = tmp_path / "studies"
    _study(studies, "dwa", {"goal_gain": 0.9})
    confirm("dwa", 20, studies, evaluator=Evaluator({"goal_gain": 0.9}))
    path = studies / "dwa" / CONFIRMATION_FILE
    record = json.loads(path.read_text())
    del record["best_options"]
    path.write_text(json.dumps(record))
    unused = Evaluator({})
    assert confirm("dwa", 20, studies, evaluator=unused).recorded and unused.calls == []


def test_a_torn_or_foreign_record_is_rerun_and_rewritten(tmp_path: Path) -> None:
    studies = tmp_path / "studies"
    _study(studies, "dwa", {"goal_gain": 0.9})
    expected = confirm("dwa", 20, studies, evaluator=Evaluator({"goal_gain": 0.9}))
    path = studies / "dwa" / CONFIRMATION_FILE
    whole = path.read_text()
    for bad in (
        whole[: len(whole) // 2],
        "[1, 2]",
        '"text"',
        json.dumps({**json.loads(whole), "layouts": [25]}),
    ):
        path.write_text(bad)
        rerun = Evaluator({"goal_gain": 0.9})
        result = confirm("dwa", 20, studies, evaluator=rerun)
        assert rerun.calls == [{"goal_gain": 0.9}, {}], bad[:40]
        assert result == expected and not result.recorded
        assert path.read_text() == whole
