"""A study's ``confirmation.json`` is read as every file KoopNav reads back: bounded, depth-checked,
and a torn or foreign record is refused by name by the page's reader (``decision``) and rerun by
``adopt --confirm`` (``_recorded``); a nested one raised RecursionError before."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from evaluation.tune.confirm import CONFIRMATION_FILE, _recorded
from evaluation.tune.report import decision

RECORD = {
    "controller": "consensus",
    "best_trial": 17,
    "layouts": [25, 100],
    "units": 150,
    "best_successes": 70,
    "defaults_successes": 45,
    "p_value": 4.999750012499375e-05,
    "exact": False,
    "confirmed": True,
}
NESTED = "[" * 100_000 + "]" * 100_000


def _study(tmp_path: Path, text: str) -> Path:
    folder = tmp_path / "consensus"
    folder.mkdir()
    (folder / CONFIRMATION_FILE).write_text(text, encoding="utf-8")
    return folder


def test_the_pages_reader_gives_the_records_verdict(tmp_path: Path) -> None:
    _study(tmp_path, json.dumps(RECORD))
    assert decision("consensus", "adopted", tmp_path) == (
        "adopted, confirmed (70 against the defaults' 45 of 150 fresh validation episodes, p <= 5e-05)"
    )
    assert decision("consensus", "no: the defaults won", tmp_path) == "no: the defaults won"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (NESTED, "nested"),
        ("[1, 2]", "not a confirmation record"),
        (json.dumps({**RECORD, "units": "many"}), "not a confirmation record"),
        (
            json.dumps({k: v for k, v in RECORD.items() if k != "p_value"}),
            "not a confirmation record.*p_value",
        ),
        (json.dumps({**RECORD, "confirmed": "yes"}), "confirmed='yes'; allowed: true or false"),
        ('{"controller": "consensus", "best_tr', "confirmation.json"),
    ],
    ids=["nested", "a-list", "units-text", "no-p", "confirmed-text", "torn"],
)
def test_the_pages_reader_refuses_a_torn_or_foreign_record_by_name(
    tmp_path: Path, text: str, message: str
) -> None:
    _study(tmp_path, text)
    with pytest.raises(ValueError, match=message) as raised:
        decision("consensus", "adopted", tmp_path)
    assert "consensus" in str(raised.value) and CONFIRMATION_FILE in str(raised.value)


@pytest.mark.parametrize(
    "text", [NESTED, "[1, 2]", '{"controller": "consensus", "best_tr'], ids=["nested", "a-list", "torn"]
)
def test_adopt_reruns_a_confirmation_whose_record_is_torn_or_foreign(tmp_path: Path, text: str) -> None:
    folder = _study(tmp_path, text)
    assert _recorded(folder / CONFIRMATION_FILE, "consensus", 17, {}, {}) is None
