"""The committed store of mutation verdicts (issue 59): evaluation/mutation.py and .ci/mutation.sh.

A verdict is reused only against the tree it was decided against (the mutated module, every test
file of its selection, mutmut's version, the script's settings); a torn or foreign store is refused
by name. The last test runs the script for real (mutmut 3) on a repository of one tiny module, each
run in a fresh clone as on a new machine, with only the store carried between them.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from evaluation.mutation import Against, Store, main, read_store, status_of, write_store
from koopman_envs.files import FileRefused

from helpers.mutation_repo import MUTMUT_MISSING, TINY, git, run_script, score_line, tiny_source

TARGET = "evaluation/episodes/records.py"
TESTS = ["tests/test_records.py", "tests/test_other.py::test_one", "tests/test_other.py::test_two"]


def _tree(root: Path) -> Path:
    for name, text in {
        TARGET: "def grade(x):\n    if x > 2:\n        return x * 3\n    return x - 1\n",
        "tests/test_records.py": "def test_grade():\n    assert True\n",
        "tests/test_other.py": "def test_one():\n    pass\n",
    }.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root


def _against(root: Path, settings: str = "[tool.mutmut]\n", mutmut: str = "3.8.1") -> Against:
    return Against.of_tree(root, TARGET, TESTS, settings, mutmut=mutmut)


def test_the_store_round_trips_and_trusts_only_its_own_tree(tmp_path: Path) -> None:
    against = _against(_tree(tmp_path / "tree"))
    assert sorted(against.tests) == ["tests/test_other.py", "tests/test_records.py"]
    store = Store(
        "records", {"m.x_grade__mutmut_1": (1, against.digest), "m.x_grade__mutmut_2": (0, "f" * 64)}, 6
    )
    store.against = against.as_json()
    path = tmp_path / "data/mutation/records.json"
    write_store(path, store)
    back = read_store(path, "records")
    assert back == store
    assert back.trusted(against) == {"m.x_grade__mutmut_1": 1}
    records = json.loads(path.read_text())["verdicts"]
    assert [(r["name"], r["status"]) for r in records] == [
        ("m.x_grade__mutmut_1", "killed"),
        ("m.x_grade__mutmut_2", "survived"),
    ]
    assert read_store(tmp_path / "missing.json", "records") == Store("records")


@pytest.mark.parametrize(
    "change",
    ["a test file", "a test file given by test id", "the module", "the settings", "mutmut"],
)
def test_a_verdict_is_stale_when_what_it_was_decided_against_changes(tmp_path: Path, change: str) -> None:
    root = _tree(tmp_path)
    before = _against(root)
    store = Store("records", {"m.x_grade__mutmut_1": (1, before.digest)}, 1)
    assert store.trusted(_against(root)) == {"m.x_grade__mutmut_1": 1}
    settings, mutmut = "[tool.mutmut]\n", "3.8.1"
    if change == "a test file":
        (root / "tests/test_records.py").write_text("def test_grade():\n    assert 1\n")
    elif change == "a test file given by test id":
        (root / "tests/test_other.py").write_text("def test_one():\n    pass\n\n")
    elif change == "the module":
        (root / TARGET).write_text((root / TARGET).read_text().replace("x > 2", "x > 3"))
    elif change == "the settings":
        settings = "[tool.mutmut]\ntimeout_multiplier = 15.0\n"
    else:
        mutmut = "3.8.2"
    after = _against(root, settings, mutmut)
    assert after.digest != before.digest
    assert store.trusted(after) == {}


def _section(selection: list[str], timeout: str = "60.0") -> str:
    """A [tool.mutmut] section as the script writes it, with ``selection``."""
    entries = ", ".join(f'"{entry}"' for entry in selection)
    return f"[tool.mutmut]\npytest_add_cli_args_test_selection = [{entries}]\ntimeout_multiplier = {timeout}\nmodule records\n"


@pytest.mark.parametrize(
    ("change", "kills_kept"),
    [
        ("a test file added", True),
        ("a test id added", True),
        ("an old test file changed", False),
        ("an old entry narrowed to one test", False),
        ("another setting", False),
        ("the module", False),
        ("mutmut", False),
        ("a store of before the rule", False),
    ],
)
def test_a_kill_is_kept_when_tests_are_only_added(tmp_path: Path, change: str, kills_kept: bool) -> None:
    """A killed verdict outlives a selection that only grew (each test that killed it still runs,
    unchanged); a survivor never does, and any other change makes both stale."""
    root = _tree(tmp_path)
    (root / "tests/test_new.py").write_text("def test_new():\n    pass\n")
    selection = ["tests/test_records.py", "tests/test_other.py::test_one"]
    before = Against.of_tree(root, TARGET, selection, _section(selection), mutmut="3.8.1")
    store = Store(
        "records", {"m.x_grade__mutmut_1": (1, before.digest), "m.x_grade__mutmut_2": (0, before.digest)}, 2
    )
    store.against = before.as_json()
    if change == "a store of before the rule":
        old = {k: v for k, v in before.as_json().items() if k not in ("rest", "selection")}
        digest = Against(**{**old, "tests": before.tests}).digest  # the old record's own digest
        store = Store("records", {"m.x_grade__mutmut_1": (1, digest)}, 1, old)
    after_selection, timeout, mutmut = [*selection, "tests/test_new.py"], "60.0", "3.8.1"
    if change == "a test id added":
        after_selection = [*selection, "tests/test_other.py::test_two"]
    elif change == "an old test file changed":
        (root / "tests/test_records.py").write_text("def test_grade():\n    assert 1\n")
    elif change == "an old entry narrowed to one test":
        after_selection = [
            "tests/test_records.py::test_grade",
            "tests/test_other.py::test_one",
            "tests/test_new.py",
        ]
    elif change == "another setting":
        timeout = "15.0"
    elif change == "the module":
        (root / TARGET).write_text((root / TARGET).read_text().replace("x > 2", "x > 3"))
    elif change == "mutmut":
        mutmut = "3.8.2"
    after = Against.of_tree(root, TARGET, after_selection, _section(after_selection, timeout), mutmut=mutmut)
    assert after.digest != before.digest
    assert store.trusted(after) == ({"m.x_grade__mutmut_1": 1} if kills_kept else {})
    assert store.trusted(before) == (  # the tree it was decided against trusts every verdict
        {"m.x_grade__mutmut_1": 1, "m.x_grade__mutmut_2": 0} if change != "a store of before the rule" else {}
    )


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('{"format": "koopnav-mutation-verdicts", "version": 1, "mod', "torn or not JSON"),
        ("[1, 2]", "not a koopnav-mutation-verdicts file"),
        ('{"format": "mutmut", "version": 1}', "not a koopnav-mutation-verdicts file"),
        ('{"format": "koopnav-mutation-verdicts", "version": 2}', "version 2; allowed: 1"),
        (
            '{"format": "koopnav-mutation-verdicts", "version": 1, "module": "runlog", "mutants": 0, "verdicts": []}',
            "made for module 'runlog', not 'records'",
        ),
        (
            '{"format": "koopnav-mutation-verdicts", "version": 1, "module": "records", "mutants": 1,'
            ' "verdicts": [{"name": "m", "exit_code": 2, "status": "killed", "against": "a"}]}',
            "verdict 0 is not a mutant's name, final exit code",
        ),
        (
            '{"format": "koopnav-mutation-verdicts", "version": 1, "module": "records", "mutants": 1,'
            ' "verdicts": [{"name": "m", "exit_code": 1, "status": "survived", "against": "a"}]}',
            "verdict 0 is not",
        ),
    ],
)
def test_a_torn_or_foreign_store_is_refused_by_name(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "records.json"
    path.write_text(text)
    with pytest.raises(ValueError, match="records.json") as refused:
        read_store(path, "records")
    assert message in str(refused.value)


def test_a_store_that_is_no_file_is_refused_by_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "records.json").mkdir()
    with pytest.raises(FileRefused, match="mutation store .*records.json"):
        read_store(tmp_path / "records.json", "records")
    assert main(["report", str(tmp_path / "records.json")]) == 2
    assert "records.json" in capsys.readouterr().err
    assert main(["rerun"]) == 2
    assert "command 'rerun'; allowed: restore, save, report" in capsys.readouterr().err


def test_report_prints_the_score_and_the_mutants_not_killed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    store = Store(
        "records", {"m.f__mutmut_1": (1, "a"), "m.f__mutmut_2": (0, "a"), "m.f__mutmut_3": (36, "a")}, 4
    )
    write_store(tmp_path / "records.json", store)
    assert main(["report", str(tmp_path / "records.json")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("records: 1/4 killed (25.0%), 1 without a verdict")
    assert out[1:] == ["  survived: m.f__mutmut_2", "  timeout: m.f__mutmut_3"]
    assert status_of(2) == "not final (2)"


def _run(source: Path, store: Path) -> subprocess.CompletedProcess[str]:
    return run_script(source, store)  # every run a fresh clone: a new machine


def _score(result: subprocess.CompletedProcess[str]) -> str:
    return score_line(result).split(" in ")[0]


@pytest.mark.skipif(MUTMUT_MISSING is not None, reason=str(MUTMUT_MISSING))
def test_a_run_on_a_new_machine_reuses_the_stored_verdicts_until_a_test_file_changes(tmp_path: Path) -> None:
    source, store = tiny_source(tmp_path / "source"), tmp_path / "store"

    first = _run(source, store)
    assert first.returncode == 0, first.stdout + first.stderr
    assert _score(first) == "records: 5/6 killed (83.3%)"
    assert "0 verdicts restored" in first.stdout
    saved = json.loads((store / "records.json").read_text())
    assert saved["module"] == "records" and saved["mutants"] == 6
    assert sorted(r["status"] for r in saved["verdicts"]) == ["killed"] * 5 + ["survived"]
    assert saved["against"]["tests"].keys() == {"tests/test_records.py"}

    # a new clone: every verdict restored from the store, mutmut not started, the same score
    again = _run(source, store)
    assert again.returncode == 0, again.stdout + again.stderr
    assert "6 verdicts restored" in again.stdout
    assert "every one of the 6 mutants has a verdict: mutmut is not started" in again.stdout
    assert _score(again) == _score(first)
    assert "survived: evaluation.episodes.records.x_grade__mutmut_" in again.stdout

    # a test file of the selection edited: every verdict is stale and the mutants are tested again
    (source / "tests/test_records.py").write_text(
        TINY["tests/test_records.py"] + "    assert grade(2) == 1\n"
    )
    git(source, "commit", "-qam", "a stronger test")
    edited = _run(source, store)
    assert edited.returncode == 0, edited.stdout + edited.stderr
    assert "0 verdicts restored from" in edited.stdout and "6 stale verdicts" in edited.stdout
    assert _score(edited) == "records: 6/6 killed (100.0%)"
    resaved = json.loads((store / "records.json").read_text())
    assert {r["against"] for r in resaved["verdicts"]} != {r["against"] for r in saved["verdicts"]}

    # a torn store: refused by name, nothing run
    (store / "records.json").write_text((store / "records.json").read_text()[:50])
    torn = _run(source, store)
    assert torn.returncode == 2
    assert f"mutation store '{store}/records.json' refused: torn" in torn.stderr
