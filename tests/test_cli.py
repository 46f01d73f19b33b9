"""The evaluator's command line reads as a tool: its name as invoked, option groups, help with
defaults for every option, exit codes in --help."""

from __future__ import annotations

import sys

import pytest

import evaluate as ev


def _help(monkeypatch, argv0: str, capsys) -> str:
    monkeypatch.setattr(sys, "argv", [argv0])
    with pytest.raises(SystemExit) as exit_info:
        ev.main(["--help"])
    assert exit_info.value.code == 0
    return capsys.readouterr().out


@pytest.mark.parametrize(
    "argv0, name", [("/venv/bin/koopnav-evaluate", "koopnav-evaluate"), ("evaluate.py", "python evaluate.py")]
)
def test_usage_names_the_program_as_it_was_called(monkeypatch, capsys, argv0: str, name: str) -> None:
    assert _help(monkeypatch, argv0, capsys).startswith(f"usage: {name} ")
    assert ev.program_name() == name


def test_help_groups_the_options_and_lists_the_exit_codes(monkeypatch, capsys) -> None:
    text = _help(monkeypatch, "evaluate.py", capsys)
    for group in (
        "what to run:",
        "env settings:",
        "controllers:",
        "output:",
        "execution:",
        "CI:",
        "exit codes:",
    ):
        assert group in text
    for code, _ in ev.EXIT_CODES:  # every code of the one table, none of the old count of episodes
        assert f"\n  {code:<6} " in text
    assert "1-100" not in text
    assert "when several apply, the highest-priority one: 130 > 103 > 102 > 101 > 3" in text


def test_every_option_has_help_and_a_default_or_a_reason() -> None:
    parser = ev.build_parser()
    for action in parser._actions:
        if action.dest == "help":
            continue
        assert action.help, action.option_strings
        flag_like = action.nargs == 0  # store_true: off unless given
        assert flag_like or "default" in action.help or action.dest in ("resume",), (
            action.option_strings,
            action.help,
        )


def test_envs_is_the_plural_of_env() -> None:
    assert ev.build_parser().parse_args(["--envs", "KoopNav-Formation-v0"]).env == ["KoopNav-Formation-v0"]


def test_the_resume_hint_uses_the_program_name(monkeypatch, tmp_path, capsys) -> None:
    from evaluation.backends import RunInterrupted

    def interrupted(*_, **__):
        raise RunInterrupted(1, 4)

    monkeypatch.setattr(ev, "evaluate", interrupted)
    monkeypatch.setattr(sys, "argv", ["/venv/bin/koopnav-evaluate"])
    code = ev.main(["--controllers", "consensus", "--out", str(tmp_path)])
    assert code == ev.INTERRUPTED_EXIT
    assert "continue with: koopnav-evaluate --controllers consensus" in capsys.readouterr().err
