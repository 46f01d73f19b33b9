"""The record schema (evaluation.records.record_problem) and the published JSON schema
(docs/results.schema.json) describe the same episode records: what one requires the other
requires, every real record passes both, and a value the code refuses is one the JSON schema
refuses too where it states the field."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from evaluation.records import STATUSES, record_problem

ROOT = Path(__file__).resolve().parents[1]
SCHEMA = json.loads((ROOT / "docs" / "results.schema.json").read_text())
EPISODE_SCHEMA = SCHEMA["properties"]["episodes"]["items"]
BASELINE = json.loads((ROOT / ".ci" / "baseline" / "results.json").read_text())


def test_the_json_schema_requires_what_the_code_requires() -> None:
    from evaluation.records import _COMMON_SCHEMA

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


def test_a_collision_of_several_kinds_and_an_error_record_pass() -> None:
    ran = {**BASELINE["episodes"][0], "success": False, "collision": "obstacle+robot"}
    assert record_problem(ran) is None
    raised = {k: BASELINE["episodes"][0][k] for k in EPISODE_SCHEMA["required"]}
    raised.update(status="error", error="RuntimeError: x")
    assert record_problem(raised) is None
