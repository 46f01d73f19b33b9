"""The record schema (evaluation.episodes.records.record_problem) and the published JSON schema
(docs/results.schema.json) describe the same episode records: what one requires the other
requires, every real record passes both, and a value the code refuses is one the JSON schema
refuses too where it states the field."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from evaluation.episodes.records import STATUSES, record_problem

ROOT = Path(__file__).resolve().parents[1]
SCHEMA = json.loads((ROOT / "docs" / "results.schema.json").read_text())
EPISODE_SCHEMA = SCHEMA["properties"]["episodes"]["items"]
BASELINE = json.loads((ROOT / ".ci" / "baseline" / "results.json").read_text())


def test_the_json_schema_requires_what_the_code_requires() -> None:
    from evaluation.episodes.records import _COMMON_SCHEMA

    assert set(EPISODE_SCHEMA["required"]) == set(_COMMON_SCHEMA)
    assert EPISODE_SCHEMA["properties"]["status"]["enum"] == list(STATUSES)


def test_every_committed_record_passes_both() -> None:
    jsonschema = pytest.importorskip("jsonschema")
    validator = jsonschema.Draft202012Validator(EPISODE_SCHEMA)
    assert len(BASELINE["episodes"]) > 100
    for record in BASELINE["episodes"]:
        assert record_problem(record) is None, record["key"]
        validator.validate(record)


@pytest.mark.parametrize(
    "field, value",
    [
        ("success", "false"),
        ("success", None),
        ("status", "maybe"),
        ("collision", 3),
        ("final_distance", ["0.1"]),
        ("final_poses", [[0.0, 0.0]]),
        ("error", 5),
        ("min_clearance", {"wall": 0.1}),
        ("min_clearance", {"robot": "0.1"}),
        ("accel_rms", [-1.0]),
        ("straight_distance", ["1"]),
        ("strict_success", "true"),
        ("strict_success", None),
        ("success_excusing_unavoidable", 1),
        ("collision_at_fault", "no"),
        ("clearance_min_m", "0.03"),
        ("clearance_min_m", [0.03]),
    ],
)
def test_values_the_code_refuses_the_json_schema_refuses(field, value) -> None:
    jsonschema = pytest.importorskip("jsonschema")
    record = copy.deepcopy(BASELINE["episodes"][0])
    record[field] = value
    assert record_problem(record) is not None
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(record, EPISODE_SCHEMA)


@pytest.mark.parametrize(
    "record, problem",
    [
        ([], "a JSON list, not an episode record"),
        ({"key": "k"}, "an object without the episode fields"),
        ({**BASELINE["episodes"][0], "status": "error"}, "an 'error' record without its 'error' text"),
        ({**BASELINE["episodes"][0], "trial": -1}, "field 'trial' is -1; allowed: an integer >= 0"),
        ({**BASELINE["episodes"][0], "seed": True}, "field 'seed' is True; allowed: an integer >= 0"),
        ({**BASELINE["episodes"][0], "steps": float("nan")}, "field 'steps' is nan"),
        (
            {**BASELINE["episodes"][0], "final_distance": [float("inf")] * 3},
            "field 'final_distance' is [inf, inf, inf]",
        ),
        (
            {**BASELINE["episodes"][0], "collision": "obstacle+obstacle"},
            "field 'collision' is 'obstacle+obstacle'",
        ),
        (
            {**BASELINE["episodes"][0], "final_poses": [[0.0, 0.0, 0.0]]},
            "'final_poses' holds 1 robots and 'final_distance' 3",
        ),
        ({**BASELINE["episodes"][0], "map": ""}, "field 'map' is ''; allowed: a non-empty string"),
    ],
)
def test_each_problem_is_named(record, problem) -> None:
    assert problem in record_problem(record)


#: the fields recorded beside success since the fault rule (docs/movers.md) and the strict success
NEW_OUTCOME_FIELDS = (
    "strict_success",
    "success_excusing_unavoidable",
    "collision_at_fault",
    "clearance_min_m",
)


@pytest.mark.parametrize("field", NEW_OUTCOME_FIELDS)
def test_the_new_outcome_fields_are_optional_but_typed(field: str) -> None:
    """Records written before the fields load; a record with one of the wrong type does not."""
    jsonschema = pytest.importorskip("jsonschema")
    # a record as written before the fields (the committed baseline's first, without them)
    old = {key: value for key, value in BASELINE["episodes"][0].items() if key not in NEW_OUTCOME_FIELDS}
    assert record_problem(old) is None
    new = {**old, "success": False, "collision": "mover", "collision_at_fault": False}
    new.update(strict_success=False, success_excusing_unavoidable=True, clearance_min_m=-0.01)
    assert record_problem(new) is None
    jsonschema.validate(new, EPISODE_SCHEMA)
    assert f"field {field!r} is 'x'" in record_problem({**old, field: "x"})


@pytest.mark.parametrize(
    "change, problem",
    [
        (
            dict(success=False, collision=None, strict_success=True),
            "field 'strict_success' is True with success False and collision None (a strict success is a success)",
        ),
        (
            dict(success=True, collision=None, success_excusing_unavoidable=False),
            "field 'success_excusing_unavoidable' is False with success True",
        ),
        (
            dict(success=False, collision=None, collision_at_fault=True),
            "field 'collision_at_fault' is True with success False and collision None (a collision at fault",
        ),
    ],
)
def test_fields_that_contradict_the_outcome_are_named(change, problem) -> None:
    assert problem in record_problem({**BASELINE["episodes"][0], **change})


def test_a_collision_of_several_kinds_and_an_error_record_pass() -> None:
    ran = {**BASELINE["episodes"][0], "success": False, "collision": "obstacle+robot"}
    assert record_problem(ran) is None
    raised = {k: BASELINE["episodes"][0][k] for k in EPISODE_SCHEMA["required"]}
    raised.update(status="error", error="RuntimeError: x")
    assert record_problem(raised) is None
