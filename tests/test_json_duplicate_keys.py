"""A key given twice in one JSON object is refused by name wherever KoopNav parses JSON
(:func:`koopman_envs.checks.parse_json`): ``json.loads`` keeps the last one silently, so
``--env-kwargs 'movers={"count":1,"count":2}'`` ran with 2 movers and exited 0."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from evaluation.exit_codes import BAD_INPUT_EXIT
from koopman_envs.checks import parse_json

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ('{"count": 1, "count": 2}', "count"),
        ('[{"a": 1}, {"b": {"c": 1, "d": 2, "c": 3}}]', "c"),
        ('{"x": {"y": 1}, "x": {"y": 1}}', "x"),  # the same value twice is still two keys
    ],
)
def test_a_key_given_twice_is_refused_by_name(text: str, key: str) -> None:
    with pytest.raises(ValueError, match=rf"^the text: key '{key}' given twice in one JSON object") as raised:
        parse_json(text, "the text")
    assert not isinstance(raised.value, json.JSONDecodeError)  # not mistaken for plain text


def test_distinct_keys_and_equal_keys_in_different_objects_are_accepted() -> None:
    text = '{"a": {"k": 1}, "b": {"k": 2}, "c": [{"k": 3}, {"k": 4}]}'
    assert parse_json(text, "the text") == {"a": {"k": 1}, "b": {"k": 2}, "c": [{"k": 3}, {"k": 4}]}


def test_the_evaluator_refuses_a_duplicate_env_keyword_key_before_any_episode(tmp_path: Path) -> None:
    done = subprocess.run(
        [sys.executable, str(ROOT / "evaluate.py"), "--env-kwargs", 'movers={"count":1,"count":2}',
         "--controllers", "consensus", "--out", str(tmp_path / "run")],
        capture_output=True, text=True, cwd=tmp_path, timeout=300,
    )  # fmt: skip
    assert done.returncode == BAD_INPUT_EXIT, done.stderr
    assert "key 'count' given twice" in done.stderr
    assert not (tmp_path / "run" / "episodes.jsonl").exists()
