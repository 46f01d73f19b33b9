"""``python -m evaluation.forget LABEL ... -- DIR ...``: the ``--`` separates labels from
directories (argparse's two greedy lists would read every directory but the last as a label and
drop nothing from it, silently: the bug this guards)."""

from __future__ import annotations

import json
from pathlib import Path

from evaluation.forget import main as forget_main


def _run(path: Path, labels: list[str]) -> Path:
    path.mkdir()
    lines = [{"kind": "koopnav-run"}] + [{"controller": label, "seed": i} for i, label in enumerate(labels)]
    (path / "episodes.jsonl").write_text("".join(json.dumps(line) + "\n" for line in lines))
    return path


def _controllers(path: Path) -> list[str]:
    lines = (path / "episodes.jsonl").read_text().splitlines()[1:]
    return [json.loads(line)["controller"] for line in lines]


def test_every_directory_after_the_separator_is_a_run(tmp_path, capsys) -> None:
    first = _run(tmp_path / "a", ["x", "y", "x"])
    second = _run(tmp_path / "b", ["x", "z"])
    assert forget_main(["x", "--", str(first), str(second)]) == 0
    assert _controllers(first) == ["y"] and _controllers(second) == ["z"]
    out = capsys.readouterr().out
    assert f"{first}: 2 records dropped" in out and f"{second}: 1 records dropped" in out


def test_several_labels_before_the_separator(tmp_path) -> None:
    run = _run(tmp_path / "a", ["x", "y", "z"])
    assert forget_main(["x", "z", "--", str(run)]) == 0
    assert _controllers(run) == ["y"]


def test_a_command_without_the_separator_is_refused_and_changes_nothing(tmp_path, capsys) -> None:
    run = _run(tmp_path / "a", ["x", "y"])
    before = (run / "episodes.jsonl").read_bytes()
    assert forget_main(["x", str(run)]) == 2
    assert "no '--' in" in capsys.readouterr().err
    assert forget_main(["--", str(run)]) == 2
    assert "no controller label before '--'" in capsys.readouterr().err
    assert forget_main(["x", "--"]) == 2
    assert "no run directory after '--'" in capsys.readouterr().err
    assert (run / "episodes.jsonl").read_bytes() == before
