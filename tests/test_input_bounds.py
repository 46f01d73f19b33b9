"""Issue 59: every bad value refused by the parser that owns it, with its own name, before any
work; and the exit codes as one table a CI script can act on (evaluation/exit_codes.py)."""

from __future__ import annotations

import json
import time
import tracemalloc
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import controllers
import evaluate as ev
import koopman_envs  # noqa: F401 - registers the ids
from controllers.option_spec import options
from evaluation.cli import (
    command,  # the command evaluate.py runs: what a test stubs
    parse_env_kwargs,
)
from evaluation.execution.backends import RunInterrupted
from evaluation.exit_codes import EXIT_CODES, EXIT_PRECEDENCE, worst
from evaluation.experiments.sweep import MAX_SWEEP_LEVELS, load_sweep, parse_sweep, refuse_sweep_clash
from evaluation.reports.thresholds import load_thresholds
from evaluation.run.configs import ControllerConfig, parse_controller
from evaluation.run.spec import RunSpec
from koopman_envs.checks import MAX_JSON_DEPTH, MAX_NUMBER, parse_json
from koopman_envs.engine.keywords import ENV_KEYWORDS

TINY = ["--env", "KoopNav-TargetReaching-v0", "--maps", "map1", "--episodes", "1"]
TINY += ["--max-episode-steps", "5", "--workers", "1", "--quiet"]


def _run(tmp_path: Path, *words: str) -> list[str]:
    return [*TINY, "--out", str(tmp_path / "run"), *words]


# --------------------------------------------------------------------------- 1. controller options
def test_an_unbounded_horizon_is_refused_at_parse_time_naming_controller_option_value_and_range() -> None:
    config = parse_controller("koopman-nmpc:horizon=100000000")
    with pytest.raises(ValueError) as caught:
        config.validate()
    assert "koopman-nmpc: horizon=100000000 must be an integer >= 1 and <= 200" in str(caught.value)


def test_every_numeric_option_of_every_registered_controller_declares_a_range() -> None:
    for name in [*controllers.available(), "safe:consensus"]:
        spec = options(name)
        unbounded = [o.name for o in spec.options if o.kind in ("number", "numbers") and o.bounds is None]
        assert unbounded == [], f"{name}: no declared range for {unbounded}"
        for option in spec.options:  # the defaults lie in their ranges
            if option.bounds is not None and option.default is not None:
                option.check(option.default, name)


#: text values a user might write after ``option=``: huge, negative, NaN, infinite, flags, empty,
#: nested junk, and any text without the list separator
_VALUES = st.one_of(
    st.integers(-(10**30), 10**30).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(lambda x: json.dumps(x)),
    st.sampled_from(
        [
            "NaN",
            "Infinity",
            "-Infinity",
            "1e308",
            "1e999",
            "-0",
            "true",
            "false",
            "null",
            "None",
            "",
            "[1, 2]",
            '{"a": 1}',
            "[" * 500 + "]" * 500,
            "abc",
            "0x10",
            " 5 ",
        ]
    ),  # fmt: skip
    st.text(max_size=12).filter(lambda t: "," not in t),
)
_OPTIONS = sorted(
    (name, option.name)
    for name in [*controllers.available(), "safe:consensus"]
    for option in options(name).options
    if option.name != "policy_root"  # a path: the directory is looked up (tested below by name)
)
#: a build's bounds: far above what one takes (about 1 ms and well under 1 MiB); a hang guard
BUILD_SECONDS = 10.0
BUILD_BYTES = 64 * 2**20


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(_OPTIONS), _VALUES)
def test_any_option_value_builds_a_controller_or_is_refused_naming_the_option(
    target: tuple[str, str], value: str
) -> None:
    """For every declared option of every registered controller: a built controller, or a
    ValueError/TypeError naming the option, within BUILD_SECONDS and BUILD_BYTES (building only)."""
    name, option = target
    tracemalloc.start()
    start = time.perf_counter()
    try:
        parse_controller(f"{name}:{option}={value}").validate()
    except (ValueError, TypeError) as exc:
        assert option in str(exc), f"{name}:{option}={value!r}: {exc}"
    finally:
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
    assert time.perf_counter() - start < BUILD_SECONDS
    assert peak < BUILD_BYTES, f"{name}:{option}={value!r} allocated {peak / 2**20:.0f} MiB to build"


def test_a_policy_root_without_policies_is_refused_by_its_option_name(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="policy_root="):
        parse_controller(f"rl-ppo:policy_root={tmp_path}").validate()


# --------------------------------------------------------------------------- 7. thresholds
@pytest.mark.parametrize(
    "rule, message",
    [
        ('max_final_distance_cm = "x"', "max_final_distance_cm='x' must be a finite number >= 0"),
        ("min_success_rate = nan", "min_success_rate=nan must be a finite number >= 0"),
        ("min_success_rate = 1.5", "min_success_rate=1.5 must be a finite number >= 0 <= 1"),
        ("min_success_rate = true", "min_success_rate=True must be a finite number"),
        ("min_sucess_rate = 0.5", "unknown key 'min_sucess_rate' (did you mean 'min_success_rate'?)"),
        ("controller = 3", "controller=3 must be non-empty text"),
    ],
)
def test_a_bad_thresholds_file_is_refused_on_load_naming_the_key(
    tmp_path: Path, rule: str, message: str
) -> None:
    path = tmp_path / "floors.toml"
    path.write_text(f"[[cell]]\nenv = 'KoopNav-TargetReaching-v0'\n{rule}\n")
    with pytest.raises(ValueError) as caught:
        load_thresholds(path)
    assert message in str(caught.value) and "[[cell]] 1" in str(caught.value)


def test_bad_thresholds_exit_2_before_any_episode(tmp_path: Path, capsys) -> None:
    path = tmp_path / "floors.toml"
    path.write_text('[[cell]]\nmax_final_distance_cm = "x"\n')
    code = ev.main(_run(tmp_path, "--controllers", "consensus", "--check", str(path)))
    err = capsys.readouterr().err
    assert code == ev.BAD_INPUT_EXIT and "max_final_distance_cm='x'" in err and "Traceback" not in err
    assert not (tmp_path / "run").exists()  # nothing ran


# --------------------------------------------------------------------------- 8. nested JSON
def test_deeply_nested_env_kwargs_are_refused_by_name() -> None:
    deep = "[" * 100_000 + "]" * 100_000
    with pytest.raises(
        ValueError,
        match=f"--env-kwargs movers: JSON nested 100000 levels deep; allowed: at most {MAX_JSON_DEPTH}",
    ):
        parse_env_kwargs([f"movers={deep}"])


def test_a_deeply_nested_sweep_manifest_is_refused_by_name(tmp_path: Path) -> None:
    (tmp_path / "sweep.json").write_text('{"axes": ' + "[" * 100_000 + "]" * 100_000 + "}")
    with pytest.raises(ValueError, match="sweep manifest .*sweep.json.*: JSON nested 100001 levels deep"):
        load_sweep(tmp_path)


def test_parse_json_counts_brackets_outside_strings_only() -> None:
    assert parse_json('{"a": "[[[[[[", "b": "\\"[["}', "x") == {"a": "[[[[[[", "b": '"[['}


# --------------------------------------------------------------------------- 10. float overflow
def test_a_huge_detection_noise_is_a_value_error_at_make() -> None:
    with pytest.raises(
        ValueError, match=r"movers.detection_noise=1e\+200 must be a finite number >= 0 <= 20"
    ):
        gym.make("KoopNav-TargetReaching-v0", movers=dict(count=1, detection_noise=1e200))


@pytest.mark.parametrize("row", [k for k in ENV_KEYWORDS if k.annotation == "float"], ids=lambda k: k.name)
def test_no_float_keyword_accepts_a_value_beyond_max_number(row: Any) -> None:
    with pytest.raises(ValueError, match=f"{row.name}=1e\\+200 must be a finite number"):
        row.resolve(1e200)
    assert MAX_NUMBER**2 < np.finfo(np.float64).max  # its square stays finite


# --------------------------------------------------------------------------- 11. messages
def test_a_bad_team_size_is_named_not_the_slips() -> None:
    spec = RunSpec(
        envs="KoopNav-TargetReaching-v0", controllers=["consensus"], env_kwargs={"n_robots": "abc"}
    )
    with pytest.raises(ValueError, match="env_kwargs: n_robots='abc' must be an integer >= 1") as caught:
        spec.validate()
    assert "slips" not in str(caught.value)


@pytest.mark.parametrize("value", ["nan", "NaN", "abc"])
def test_a_non_numeric_gain_is_named_not_numpys_ufunc(value: str) -> None:
    with pytest.raises(ValueError) as caught:
        parse_controller(f"consensus:goal_gain={value}").validate()
    assert "consensus: goal_gain=" in str(caught.value) and "ufunc" not in str(caught.value)


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda n: n.update(mean=np.where(np.arange(n["mean"].size) == 3, np.nan, n["mean"])), r"mean\[3\]=nan"),
        (lambda n: n.update(var=np.where(np.arange(n["var"].size) == 0, -1.0, n["var"])), r"var\[0\]=-1.0; allowed: finite and >= 0"),
    ],
)  # fmt: skip
def test_a_corrupt_observation_normalization_is_refused_at_load(
    tmp_path: Path, change: Any, message: str
) -> None:
    pytest.importorskip("stable_baselines3")
    from baselines.sb3.policy import SHIPPED, PolicyLoadError, load_policy

    source = SHIPPED / "formation"
    target = tmp_path / "formation"
    target.mkdir()
    for name in ("policy.zip", "metadata.json"):
        (target / name).write_bytes((source / name).read_bytes())
    with np.load(source / "obs_norm.npz") as data:
        norm = {key: data[key] for key in data.files}
    change(norm)
    np.savez(target / "obs_norm.npz", **norm)
    with pytest.raises(PolicyLoadError, match=message):
        load_policy(target, "formation")


# --------------------------------------------------------------------------- 12. doubtful input
@pytest.mark.parametrize(
    "text, message",
    [
        ("consensus:label=a\nb", "holds a line break"),
        ("consensus:label=", "label= is empty"),
        ("consensus:goal_gain=true", "consensus: goal_gain=True must be a finite number"),
        ("nominal-nmpc:solver_options=notadict", "nominal-nmpc: solver_options='notadict' is not a dict"),
        ("consensus:goal_gain=1,goal_gain=2", "option 'goal_gain' is given twice"),
        ("consensus:label=a,label=b", "option 'label' is given twice"),
    ],
)
def test_doubtful_controller_configurations_are_refused(text: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        parse_controller(text).validate()


def test_a_label_with_a_line_break_is_refused_from_python_too() -> None:
    with pytest.raises(ValueError, match="holds a line break"):
        ControllerConfig("two\nlines", "consensus")


def test_a_duplicate_env_kwargs_key_is_refused() -> None:
    with pytest.raises(ValueError, match="--env-kwargs 'start_noise' is given twice"):
        parse_env_kwargs(["start_noise=0.1", "start_noise=0.2"])


@pytest.mark.parametrize(
    "words, message",
    [
        (["--env-kwargs", "start_noise=0.1", "--sweep", "start_noise=0,0.2"], "--sweep start_noise and the setting start_noise=0.1"),
        (["--start-noise", "0.1", "--sweep", "start_noise=0,0.2"], "--sweep start_noise and the setting start_noise=0.1"),
        (["--env-kwargs", "movers.count=2", "--sweep", "movers.count=0,4"], "--sweep movers.count and the setting movers.count=2"),
    ],
)  # fmt: skip
def test_a_setting_the_sweep_also_sets_is_refused(
    tmp_path: Path, capsys, words: list[str], message: str
) -> None:
    assert ev.main(_run(tmp_path, "--controllers", "consensus", *words)) == ev.BAD_INPUT_EXIT
    assert message in capsys.readouterr().err


def test_a_sweep_over_other_fields_of_a_given_dict_runs_its_checks(tmp_path: Path) -> None:
    """movers.radius given, movers.count swept: no clash (parse only)."""
    refuse_sweep_clash(["movers.count=0,4"], {"movers": {"radius": 0.1}})


def test_an_empty_out_is_refused(capsys) -> None:
    with pytest.raises(SystemExit) as exited:
        ev.main([*TINY, "--out", ""])
    assert exited.value.code == ev.BAD_INPUT_EXIT and "--out: '' is empty" in capsys.readouterr().err


def test_sweep_levels_have_a_stated_cap() -> None:
    parse_sweep("comm.drop=" + ",".join(str(i / 1000) for i in range(MAX_SWEEP_LEVELS)))
    with pytest.raises(ValueError, match=f"15,000 levels; allowed: at most {MAX_SWEEP_LEVELS}"):
        parse_sweep("comm.drop=" + ",".join(str(i) for i in range(15_000)))


# --------------------------------------------------------------------------- exit codes
def test_the_table_lists_each_code_once_with_the_stated_precedence() -> None:
    codes = [code for code, _ in EXIT_CODES]
    assert codes == [0, 1, 2, 3, 101, 102, 103, 130]
    assert EXIT_PRECEDENCE == (130, 103, 102, 101, 3)
    assert worst(3, 101) == 101 and worst(101, 102) == 102 and worst(3, 130, 103) == 130 and worst() == 0
    with pytest.raises(ValueError, match="exit code 2 does not combine"):
        worst(2, 3)


def _verdict(failed: int, problems: list[str], worse: list[str], uncovered: list[str]) -> int:
    args = SimpleNamespace(
        baseline="base.json", fail_if_worse=bool(worse or uncovered), alpha=0.05, check="t"
    )
    results = SimpleNamespace(failed_episodes=[{}] * failed)
    check = SimpleNamespace(problems=problems, skipped=[], reading="interval") if problems else None
    return command.verdict(args, results, check, worse, uncovered)


@pytest.mark.parametrize(
    "failed, problems, worse, uncovered, code",
    [
        (0, [], [], [], 0),
        (1, [], [], [], 3),
        (250, [], [], [], 3),  # the count is printed, not encoded
        (2, ["floor"], [], [], 101),
        (2, ["floor"], ["worse"], [], 102),
        (0, [], ["worse"], [], 102),
        (2, [], [], ["too few pairs"], 2),  # the gate fails closed, above 3
        (2, ["floor"], [], ["too few pairs"], 101),
    ],
)
def test_outcomes_of_a_finished_run_combine_by_precedence(
    failed: int, problems: list[str], worse: list[str], uncovered: list[str], code: int
) -> None:
    assert _verdict(failed, problems, worse, uncovered) == code


def test_exit_0_success(tmp_path: Path) -> None:
    assert ev.main(_run(tmp_path, "--controllers", "consensus")) == ev.SUCCESS_EXIT == 0


def test_exit_1_internal_error_prints_the_traceback_and_says_it_is_a_bug(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    def broken(*args: Any, **kwargs: Any) -> None:
        raise KeyError("a bug")

    monkeypatch.setattr(command, "evaluate", broken)
    assert ev.main(_run(tmp_path, "--controllers", "consensus")) == ev.INTERNAL_ERROR_EXIT == 1
    err = capsys.readouterr().err
    assert "Traceback" in err and "KeyError: 'a bug'" in err and "internal error in python evaluate.py" in err


def test_exit_2_bad_input(tmp_path: Path, capsys) -> None:
    assert (
        ev.main(_run(tmp_path, "--controllers", "koopman-nmpc:horizon=100000000")) == ev.BAD_INPUT_EXIT == 2
    )
    assert "horizon=100000000" in capsys.readouterr().err


def test_exit_3_episodes_raised_with_the_count_printed(tmp_path: Path, capsys) -> None:
    code = ev.main(
        _run(tmp_path, "--controllers", "plugin_controllers:AlwaysRaising:label=raising", "--episodes", "2")
    )
    assert code == ev.EPISODES_RAISED_EXIT == 3
    assert "2 episode(s) raised" in capsys.readouterr().err
    assert (tmp_path / "run" / "results.json").exists()  # the results are written


def test_exit_101_a_floor_missed(tmp_path: Path) -> None:
    floors = tmp_path / "floors.toml"
    floors.write_text('reading = "point"\n[[cell]]\ncontroller = "consensus"\nmin_success_rate = 1.0\n')
    assert (
        ev.main(_run(tmp_path, "--controllers", "consensus", "--check", str(floors))) == ev.FAILED_CHECK_EXIT
    )


def test_exit_103_unwritable_output(tmp_path: Path) -> None:
    (tmp_path / "run").write_text("a file, not a directory")
    assert ev.main(_run(tmp_path, "--controllers", "consensus")) == ev.UNWRITABLE_OUT_EXIT == 103


def test_exit_130_interrupted(tmp_path: Path, monkeypatch) -> None:
    def interrupted(*args: Any, **kwargs: Any) -> None:
        raise RunInterrupted(0, 1)

    monkeypatch.setattr(command, "evaluate", interrupted)
    assert ev.main(_run(tmp_path, "--controllers", "consensus")) == ev.INTERRUPTED_EXIT == 130


def test_help_is_generated_from_the_table(capsys) -> None:
    with pytest.raises(SystemExit):
        ev.main(["--help"])
    text = capsys.readouterr().out
    for code, meaning in EXIT_CODES:
        assert f"  {code:<6} {meaning}\n" in text
    assert "130 > 103 > 102 > 101 > 3" in text


@pytest.mark.parametrize("page", ["docs/ci.md", "docs/evaluator.md"])
def test_the_docs_exit_code_tables_are_the_one_table(page: str) -> None:
    """Both pages held a copy written by hand; they now hold exit_codes_markdown() verbatim."""
    from evaluation.exit_codes import exit_codes_markdown

    text = (Path(__file__).resolve().parents[1] / page).read_text(encoding="utf-8")
    assert f"## Exit codes\n\n{exit_codes_markdown()}" in text


@pytest.mark.parametrize(
    "error", [ValueError("a bug after the run"), PermissionError(13, "a read after the run")]
)
def test_an_exception_after_the_run_is_koopnav_s_fault_not_bad_input_or_an_unwritable_out(
    tmp_path, monkeypatch, capsys, error: Exception
) -> None:
    """A ValueError raised after the episodes ran exited 2 ("bad input, before any episode ran")
    and any OSError 103 ("--out cannot be made or written"); both are now an internal error (1),
    while a report that cannot be written stays 103 (tests/test_bounded_reads.py)."""
    import evaluate as ev
    from evaluation.cli import command

    def raises(*args, **kwargs):
        raise error

    monkeypatch.setattr(command, "check_thresholds", raises)
    floors = tmp_path / "floors.toml"
    floors.write_text('[[cell]]\ncontroller = "consensus"\nmin_success_rate = 0.0\n', encoding="utf-8")
    argv = ["--env", "KoopNav-TargetReaching-v0", "--controllers", "consensus", "--maps", "map1"]
    argv += [
        "--episodes",
        "1",
        "--max-episode-steps",
        "5",
        "--workers",
        "1",
        "--quiet",
        "--check",
        str(floors),
    ]
    code = ev.main([*argv, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == ev.INTERNAL_ERROR_EXIT, err
    assert "internal error" in err and type(error).__name__ in err
    assert (tmp_path / "out" / "results.json").is_file()  # the reports were written before
