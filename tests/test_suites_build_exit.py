"""``python -m koopman_envs.suites.build`` exits with the evaluator's codes: 101 when ``--check``
finds a difference (as ``docs/make_pages.py --check`` and ``evaluate.py --check``), 2 when
``--write`` is refused, 0 when the stored data is what the generator builds."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from evaluation.exit_codes import BAD_INPUT_EXIT, FAILED_CHECK_EXIT, SUCCESS_EXIT
from koopman_envs.suites import build


def test_the_build_uses_the_evaluators_exit_codes() -> None:
    assert (build.BAD_INPUT_EXIT, build.CHECK_DIFFERS_EXIT) == (BAD_INPUT_EXIT, FAILED_CHECK_EXIT)


@pytest.fixture
def one_suite(monkeypatch, tmp_path):
    """A stand-in suite whose build is instant (the real build rolls episodes for minutes)."""
    definition = SimpleNamespace(name="tiny", tasks=("target_reaching",))
    monkeypatch.setattr(build, "SUITES", {"tiny": definition})
    monkeypatch.setattr(build, "_DATA", tmp_path)
    monkeypatch.setattr(build, "build_suite", lambda d: ({"test": {}}, {"splits": {}}))
    return tmp_path


def test_a_check_that_finds_a_difference_exits_101_naming_it(one_suite, monkeypatch, capsys) -> None:
    monkeypatch.setattr(build, "_differences", lambda d, docs, m: ["tiny/test: hash differs"])
    assert build.main(["--check"]) == FAILED_CHECK_EXIT
    assert "tiny/test: hash differs" in capsys.readouterr().out


def test_a_check_that_finds_nothing_exits_0(one_suite, monkeypatch, capsys) -> None:
    monkeypatch.setattr(build, "_differences", lambda d, docs, m: [])
    assert build.main([]) == SUCCESS_EXIT
    assert "tiny: the stored data is what the generator builds" in capsys.readouterr().out


def test_a_write_over_published_data_is_refused_with_2(one_suite, capsys) -> None:
    (one_suite / "tiny").mkdir()
    (one_suite / "tiny" / "manifest.json").write_text("{}")
    assert build.main(["--write"]) == BAD_INPUT_EXIT
    assert "--write refused: ['tiny']" in capsys.readouterr().err
