"""The evaluator's command line reads as a tool: its name as invoked, option groups, help with
defaults for every option, exit codes in --help."""

from __future__ import annotations

import re
import shlex
import sys
from pathlib import Path

import pytest

import controllers
import evaluate as ev
from evaluation.cli import (
    EXAMPLES,
    build_parser,
    command,  # the command evaluate.py runs: what a test stubs
    spec_from_args,
)

ROOT = Path(__file__).resolve().parents[1]


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
    from evaluation.execution.backends import RunInterrupted

    def interrupted(*_, **__):
        raise RunInterrupted(1, 4)

    monkeypatch.setattr(command, "evaluate", interrupted)
    monkeypatch.setattr(sys, "argv", ["/venv/bin/koopnav-evaluate"])
    code = ev.main(["--controllers", "consensus", "--out", str(tmp_path)])
    assert code == ev.INTERRUPTED_EXIT
    assert "continue with: koopnav-evaluate --controllers consensus" in capsys.readouterr().err


# --------------------------------------------------------------------------- --help's examples
def test_help_shows_the_examples_first_in_its_epilog(monkeypatch, capsys) -> None:
    text = _help(monkeypatch, "evaluate.py", capsys)
    assert text.index("examples:") < text.index("exit codes:")
    for options, what in EXAMPLES:
        assert re.search(
            rf"^  python evaluate\.py {re.escape(options)} *# {re.escape(what)}$", text, re.MULTILINE
        )
    assert 6 <= len(EXAMPLES) <= 10


@pytest.mark.parametrize(("options", "what"), EXAMPLES, ids=[o or "(none)" for o, _ in EXAMPLES])
def test_every_example_of_the_help_parses_and_makes_a_run(options: str, what: str) -> None:
    """Each example's options parse and, but for --options (which prints and exits), make the run
    they describe; a file an example names exists in the checkout."""
    args = build_parser().parse_args(shlex.split(options))
    if args.options:
        assert args.options in controllers.available()
        return
    spec = spec_from_args(args)
    assert spec.episodes >= 1 and spec.envs
    if args.baseline:
        assert (ROOT / args.baseline).is_file()
    if args.ablation_out:
        assert (ROOT / args.ablation_out).is_file()


def test_what_the_quick_start_and_the_examples_write_is_ignored_by_git() -> None:
    """The default directory, the next ones a repeated quick start chooses and every example's
    --out: a run leaves nothing for ``git status`` to list."""
    import shutil
    import subprocess

    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    outs = ["results", "results-2", "results-17"]
    for options, _ in EXAMPLES:
        args = build_parser().parse_args(shlex.split(options))
        if args.out:
            outs.append(args.out)
    paths = [f"{out}/results.json" for out in outs]
    ignored = subprocess.run(
        ["git", "check-ignore", "--no-index", *paths], cwd=ROOT, capture_output=True, text=True
    ).stdout.split()
    assert sorted(set(paths) - set(ignored)) == []


# --------------------------------------------------------------------------- the quick start twice
def _readme_quick_command() -> list[str]:
    """The options of README's first command, ``pip install -e . && python evaluate.py ...``."""
    line = next(row for row in (ROOT / "README.md").read_text().splitlines() if "python evaluate.py" in row)
    command = line.split("&&", 1)[1].split("#", 1)[0]
    words = shlex.split(command)
    assert words[:2] == ["python", "evaluate.py"], line
    return words[2:]


#: the quick command on one tiny cell: the same code path at a budget a test can pay
_SMALL = ["--env", "KoopNav-TargetReaching-v0", "--maps", "map1", "--controllers", "consensus"]
_SMALL += ["--episodes", "1", "--max-episode-steps", "5", "--workers", "1", "--quiet"]


def test_the_quick_start_can_be_run_twice(monkeypatch, tmp_path, capsys) -> None:
    """README's quick command names no --out: a second run goes to results-2/ (a note says so) and
    leaves the first run's files alone; --resume continues results/; an --out that holds a run is
    still refused."""
    quick = _readme_quick_command()
    assert "--out" not in quick
    monkeypatch.chdir(tmp_path)
    assert ev.main([*quick, *_SMALL]) == 0
    first = (tmp_path / "results" / "episodes.jsonl").read_bytes()
    capsys.readouterr()
    assert ev.main([*quick, *_SMALL]) == 0
    err = capsys.readouterr().err
    assert "note: results/ holds an earlier run, so this one writes to results-2/" in err
    assert (tmp_path / "results" / "episodes.jsonl").read_bytes() == first
    assert (tmp_path / "results-2" / "episodes.jsonl").read_bytes().count(b"\n") == 2  # header + 1
    assert ev.main([*quick, *_SMALL, "--resume"]) == 0  # continues results/: nothing left to run
    assert (tmp_path / "results" / "episodes.jsonl").read_bytes() == first
    assert not (tmp_path / "results-3").exists()
    capsys.readouterr()
    assert ev.main([*quick, *_SMALL, "--out", "results"]) == ev.BAD_INPUT_EXIT
    assert "exists: pass --resume" in capsys.readouterr().err


def test_an_empty_results_directory_is_used_and_a_file_is_passed_over(monkeypatch, tmp_path) -> None:
    from evaluation.episodes.runlog import output_directory

    monkeypatch.chdir(tmp_path)
    assert output_directory(None, resume=False) == "results"
    (tmp_path / "results").mkdir()
    assert output_directory(None, resume=False) == "results"
    (tmp_path / "results" / "x").write_text("")
    (tmp_path / "results-2").write_text("a file")
    assert output_directory(None, resume=False) == "results-3"
    assert output_directory(None, resume=True) == "results"
    assert output_directory("mine", resume=False) == "mine"


def test_only_a_missing_path_or_an_empty_directory_holds_nothing(tmp_path) -> None:
    from evaluation.episodes.runlog import _holds_nothing

    (tmp_path / "empty").mkdir()
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("")
    (tmp_path / "file").write_text("")
    (tmp_path / "link").symlink_to(tmp_path / "empty")
    (tmp_path / "dangling").symlink_to(tmp_path / "missing")
    held = {p.name: _holds_nothing(p) for p in sorted(tmp_path.iterdir())}
    held["missing"] = _holds_nothing(tmp_path / "missing")
    assert held == {
        "dangling": False,
        "empty": True,
        "file": False,
        "full": False,
        "link": False,
        "missing": True,
    }


def test_the_default_directory_counts_up_from_results_2_past_symlinks(monkeypatch, tmp_path) -> None:
    """results/ taken: results-2/ next (then -3, ...); a symlink holds something even when it
    points to an empty directory, so it is passed over and left alone."""
    from evaluation.episodes.runlog import output_directory

    monkeypatch.chdir(tmp_path)
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "x").write_text("")
    assert output_directory(None, resume=False) == "results-2"
    (tmp_path / "empty").mkdir()
    (tmp_path / "results-2").symlink_to(tmp_path / "empty")
    (tmp_path / "results-3").mkdir()
    assert output_directory(None, resume=False) == "results-3"
    (tmp_path / "results-3" / "y").mkdir()
    assert output_directory(None, resume=False) == "results-4"


def test_the_resume_hint_names_the_directory_a_repeated_run_chose(monkeypatch, tmp_path, capsys) -> None:
    from evaluation.execution.backends import RunInterrupted

    def interrupted(*_, **__):
        raise RunInterrupted(1, 4)

    monkeypatch.chdir(tmp_path)
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "episodes.jsonl").write_text("an earlier run\n")
    monkeypatch.setattr(command, "evaluate", interrupted)
    monkeypatch.setattr(sys, "argv", ["evaluate.py"])
    assert ev.main(["--controllers", "consensus"]) == ev.INTERRUPTED_EXIT
    assert "continue with: python evaluate.py --controllers consensus --out results-2 --resume" in (
        capsys.readouterr().err
    )


@pytest.mark.parametrize("words", [["--controllers", "consensus"], ["--crowd", "crowd", "--episodes", "1"]])
def test_the_command_reads_the_parsed_options_without_changing_them(monkeypatch, tmp_path, words) -> None:
    """The output directory chosen, a protocol's own sweep axes and reference: derived values,
    never written into the options (issue 61: spec_from_args edited args while reading it)."""
    from evaluation.execution import runner
    from evaluation.execution.backends import RunInterrupted

    def interrupted(*_, **__):
        raise RunInterrupted(0, 1)

    monkeypatch.chdir(tmp_path)
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "episodes.jsonl").write_text("an earlier run\n")  # a new directory is chosen
    monkeypatch.setattr(command, "evaluate", interrupted)
    monkeypatch.setattr(runner, "evaluate", interrupted)  # a sweep's levels
    args = build_parser().parse_args(words)
    before = dict(vars(args))
    assert command.run_command(args, words) == ev.INTERRUPTED_EXIT
    assert vars(args) == before


def test_no_option_defaults_to_a_path_in_the_checkout(monkeypatch, tmp_path) -> None:
    """Run from anywhere, no default of the evaluator names a file or directory of the checkout
    (the ablation report went to docs/ablation.md unless told otherwise)."""
    monkeypatch.chdir(ROOT)
    args = build_parser().parse_args(["--ablation"])
    for name, value in vars(args).items():
        if isinstance(value, str):
            assert not Path(value).is_absolute() and not Path(value).exists(), (name, value)
    assert args.ablation_out is None and args.out is None


# slow: two ablation runs with their calibrations, about 4 CPU-s (issue 61)
@pytest.mark.slow
def test_the_ablation_report_goes_under_out_unless_a_page_is_named(tmp_path) -> None:
    """--ablation writes OUT/ablation.md (it wrote the tracked docs/ablation.md before); with
    --ablation-out the report goes there and its regeneration command names the page."""
    from evaluation.reports.published import results_from_log

    page = (ROOT / "docs" / "ablation.md").read_bytes()
    tiny = ["--ablation", "margins", "--env", "KoopNav-TargetReaching-v0", "--maps", "map1"]
    tiny += ["--episodes", "1", "--max-episode-steps", "3", "--calibration-budget", "2000"]
    tiny += ["--workers", "1", "--quiet"]
    assert ev.main([*tiny, "--out", str(tmp_path / "run")]) == 0
    report = (tmp_path / "run" / "ablation.md").read_text()
    assert (
        report.startswith("# Ablation") and "Regenerate with `python evaluate.py --ablation margins" in report
    )
    assert (ROOT / "docs" / "ablation.md").read_bytes() == page
    elsewhere = tmp_path / "page.md"
    args = build_parser().parse_args([*tiny, "--ablation-out", str(elsewhere)])
    results = results_from_log(tmp_path / "run" / "episodes.jsonl")
    results.config["workers"] = 1  # what the run adds to the log's settings
    command.write_ablation(args, results, 1.0)
    assert f"--episodes 1 --ablation-out {elsewhere}`." in elsewhere.read_text()
