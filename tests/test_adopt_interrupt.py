"""Ctrl-C during ``python -m evaluation.tune adopt NAME``: exit 130 (INTERRUPTED_EXIT) with a
message that fits what was running. Without ``--confirm`` no episode runs, so the message says
nothing was adopted (it spoke of confirmation episodes before); with ``--confirm`` it names the
confirmation logs, as tests/test_tune.py checks on a real run."""

from __future__ import annotations

from evaluation.exit_codes import INTERRUPTED_EXIT
from evaluation.tune import cli


def _interrupt(*args: object, **kwargs: object) -> None:
    raise KeyboardInterrupt


def test_ctrl_c_in_a_plain_adopt_says_nothing_was_adopted(monkeypatch, capsys, tmp_path) -> None:
    monkeypatch.setattr(cli, "adopt", _interrupt)
    code = cli.main(["adopt", "orca", "--studies", str(tmp_path / "s"), "--tuned", str(tmp_path / "t")])
    err = capsys.readouterr().err
    assert code == INTERRUPTED_EXIT
    assert err == "interrupted: orca: nothing adopted; the same command adopts it\n"


def test_ctrl_c_in_a_confirmation_names_its_logs(monkeypatch, capsys, tmp_path) -> None:
    monkeypatch.setattr(cli, "adopt_confirmed", _interrupt)
    argv = [
        "adopt",
        "orca",
        "--confirm",
        "5",
        "--studies",
        str(tmp_path / "s"),
        "--tuned",
        str(tmp_path / "t"),
    ]
    assert cli.main(argv) == INTERRUPTED_EXIT
    err = capsys.readouterr().err
    assert err.startswith("interrupted: orca's finished confirmation episodes are in ")
    assert "the same command continues" in err
