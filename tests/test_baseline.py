"""--baseline and --fail-if-worse (evaluation/reports/baseline.py): pairing across runs, refusal of other
settings, the gate's decisions, bad baseline files, the GitHub step summary."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

import evaluate as ev
from evaluation.reports.baseline import (
    GateOptions,
    compare_runs,
    coverage_failures,
    gate_failures,
    load_baseline,
)

RUN = [
    "--env",
    "KoopNav-TargetReaching-v0",
    "--maps",
    "map1",
    "--slips",
    "nominal",
    "--episodes",
    "8",
    "--max-episode-steps",
    "300",
    "--quiet",
    "--workers",
    "1",
]
NMPC = "nominal-nmpc:solver=rti,label=nmpc"


def _record(
    seed: int, success: bool, distance: float = 0.05, controller: str = "c", map_name: str = "map1"
) -> dict:
    return {
        "status": "ok",
        "env_id": "KoopNav-TargetReaching-v0",
        "controller": controller,
        "map": map_name,
        "slip": "nominal",
        "seed": seed,
        "success": success,
        "final_distance": [distance] * 3,
        # a distinct episode per seed (evaluation.episodes.distinct: identical episodes count once)
        "final_poses": [[float(seed), 0.0, 0.0]] * 3,
    }


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("base")
    assert ev.main([*RUN, "--controllers", NMPC, "--out", str(out)]) == 0
    return out


#: the gate's options for RUN's 8 episodes (the default minimum is 10 pairs per controller)
GATE = ["--fail-if-worse", "--min-pairs", "8"]


@pytest.fixture(scope="module")
def rerun(base, tmp_path_factory) -> tuple[Path, int, str, Path]:
    """An identical rerun gated against ``base``, with a badge and a GitHub step summary that
    already holds an earlier step's text: (its output directory, exit code, stdout, the summary).
    One run of 8 NMPC episodes serves the three tests that read it."""
    out = tmp_path_factory.mktemp("rerun")
    summary = out / "summary.md"
    summary.write_text("earlier step\n")
    args = [*RUN, "--controllers", NMPC, "--out", str(out), "--baseline", str(base), *GATE, "--badge", "nmpc"]
    with pytest.MonkeyPatch.context() as patch, contextlib.redirect_stdout(io.StringIO()) as stdout:
        patch.setenv("GITHUB_STEP_SUMMARY", str(summary))
        code = ev.main(args)
    return out, code, stdout.getvalue(), summary


# slow: the rerun fixture, a second run of RUN's 8 NMPC episodes (issue 61); the gate still runs
# by default in test_a_degraded_controller_fails_the_gate and the fails-closed tests
@pytest.mark.slow
def test_an_identical_rerun_passes_the_gate(rerun) -> None:
    out, code, stdout, _ = rerun
    assert code == 0
    assert "baseline gate passed" in stdout
    comparison = json.loads((out / "baseline_comparison.json").read_text())
    (row,) = comparison["rows"]
    assert row["n"] == 8 and row["only_a"] == row["only_b"] == 0 and row["distance_cm_difference"] == 0.0


#: a controller that stands still under the NMPC's label: every episode of RUN fails, in 8 x 300
#: env steps with no solver (a degraded NMPC, horizon=3, took 9 CPU-s to fail the same way)
STANDING = "plugin_controllers:PlainTimed:label=nmpc"


def test_a_degraded_controller_fails_the_gate(base, tmp_path, capsys) -> None:
    code = ev.main([*RUN, "--controllers", STANDING, "--out", str(tmp_path), "--baseline", str(base), *GATE])
    assert code == ev.FAILED_GATE_EXIT
    assert (
        "nmpc on KoopNav-TargetReaching-v0 (8 paired episodes): success 100% -> 0%" in capsys.readouterr().err
    )


def test_a_baseline_of_other_settings_is_refused_before_any_episode(base, tmp_path, capsys) -> None:
    code = ev.main(
        [*RUN, "--controllers", NMPC, "--out", str(tmp_path), "--baseline", str(base), "--tolerance", "0.05"]
    )
    assert code == 2
    err = capsys.readouterr().err
    assert (
        "the baseline was run with other settings (env_settings:" in err and "'goal_tolerance': 0.05" in err
    )
    assert not (tmp_path / "episodes.jsonl").exists()


@pytest.mark.parametrize(
    "content, message",
    [
        (None, "cannot be read"),
        ("{not json", "is not JSON"),
        ('{"a": 1}', "is not a KoopNav results document"),
        (
            '{"schema_version": 99, "config": {}, "episodes": []}',
            r"has schema_version=99; this version reads \[2\]",
        ),
    ],
)
def test_bad_baseline_files_are_named(tmp_path, capsys, content, message) -> None:
    path = tmp_path / "base.json"
    if content is not None:
        path.write_text(content)
    with pytest.raises(ValueError, match=message):
        load_baseline(path)
    code = ev.main(
        [*RUN, "--controllers", "consensus", "--out", str(tmp_path / "run"), "--baseline", str(path)]
    )
    assert code == 2 and str(path) in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(
    "args, message",
    [
        (["--alpha", "0"], "alpha=0.0 must lie in"),
        (["--alpha", "1.5"], "alpha=1.5 must lie in"),
        (["--delta", "-0.1"], "delta=-0.1 must be"),
        (["--delta-cm", "-1"], "delta_cm=-1.0 must be"),
        (["--fail-if-worse"], "--fail-if-worse needs --baseline"),
    ],
)
def test_bad_gate_options_exit_2(tmp_path, capsys, args, message) -> None:
    assert ev.main([*RUN, "--controllers", "consensus", "--out", str(tmp_path / "run"), *args]) == 2
    assert message in capsys.readouterr().err


def test_the_gates_decisions_on_known_tables() -> None:
    # 6 discordant pairs, all lost: McNemar p = 2 * 0.5**6 = 0.03125 < 0.05, drop 60 points > 10
    base = [_record(s, True) for s in range(10)]
    run = [_record(s, s >= 6) for s in range(10)]
    comparison = compare_runs(run, base)
    (row,) = comparison["rows"]
    assert row["only_b"] == 6 and row["p_value"] == pytest.approx(0.03125)
    assert len(gate_failures(comparison, GateOptions())) == 1
    assert gate_failures(comparison, GateOptions(alpha=0.01)) == []  # not significant at 1%
    assert gate_failures(comparison, GateOptions(delta=0.7)) == []  # drop smaller than 70 points
    # 5 lost pairs: p = 0.0625, not significant at 5%
    assert gate_failures(compare_runs([_record(s, s >= 5) for s in range(10)], base), GateOptions()) == []
    # distances: +2 cm on every pair fails a 1 cm tolerance, passes a 3 cm one
    farther = [_record(s, True, distance=0.07) for s in range(10)]
    assert any(
        "final distance +2.00 cm" in f for f in gate_failures(compare_runs(farther, base), GateOptions())
    )
    assert gate_failures(compare_runs(farther, base), GateOptions(delta_cm=3.0)) == []


def test_cells_on_one_side_only_are_listed_not_dropped() -> None:
    base = [_record(0, True), _record(0, True, controller="gone"), _record(0, True, map_name="map2")]
    run = [_record(0, True), _record(0, True, controller="new")]
    comparison = compare_runs(run, base)
    assert [r["controller"] for r in comparison["rows"]] == ["c"]
    assert comparison["only_run"] == [["KoopNav-TargetReaching-v0", "new", "map1", "nominal"]]
    assert comparison["only_baseline"] == [
        ["KoopNav-TargetReaching-v0", "c", "map2", "nominal"],
        ["KoopNav-TargetReaching-v0", "gone", "map1", "nominal"],
    ]


# slow: the rerun fixture, a second run of RUN's 8 NMPC episodes (issue 61); the gate still runs
# by default in test_a_degraded_controller_fails_the_gate and the fails-closed tests
@pytest.mark.slow
def test_the_github_step_summary_is_appended(rerun) -> None:
    _, code, _, summary = rerun
    assert code == 0
    text = summary.read_text()
    assert (
        text.startswith("earlier step\n")
        and "## KoopNav leaderboard" in text
        and "Compared with the baseline" in text
    )


# slow: the rerun fixture, a second run of RUN's 8 NMPC episodes (issue 61); the gate still runs
# by default in test_a_degraded_controller_fails_the_gate and the fails-closed tests
@pytest.mark.slow
def test_the_badge_is_valid_svg_with_the_rate_and_its_interval(rerun) -> None:
    import xml.etree.ElementTree as ET

    out, code, _, _ = rerun
    assert code == 0
    root = ET.fromstring((out / "badge.svg").read_text())
    assert root.tag == "{http://www.w3.org/2000/svg}svg"
    texts = [t.text for t in root.iter("{http://www.w3.org/2000/svg}text")]
    assert texts == ["nmpc success", "100% [68-100], n=8"]


def test_a_badge_of_a_controller_not_in_the_run_is_refused_first(tmp_path, capsys) -> None:
    assert ev.main([*RUN, "--controllers", NMPC, "--out", str(tmp_path), "--badge", "nmcp"]) == 2
    assert "--badge 'nmcp' is not a controller of this run; it runs ['nmpc'] (did you mean 'nmpc'?)" in (
        capsys.readouterr().err
    )
    assert not (tmp_path / "episodes.jsonl").exists()


def test_the_solver_comparison_page_pairs_across_files_and_counts_cells() -> None:
    """docs/solver_comparison.py: a later file's episodes replace an earlier one's (a rerun arm)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "solver_comparison", Path(ev.__file__).parent / "docs" / "solver_comparison.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for_doc = [_record(s, True, controller="c@ipopt") for s in range(6)] + [
        _record(s, True, controller="c@rti") for s in range(6)
    ]
    rerun = [_record(s, False, controller="c@rti") for s in range(6)]
    for r in for_doc + rerun:
        r["solve_ms_median"] = 1.0
    documents = [{"episodes": for_doc}, {"episodes": rerun}]
    (row,) = module.comparison_rows(documents, "rti", "ipopt")
    assert (
        row["n"] == 6
        and row["only_b"] == 6
        and row["p_value"] == pytest.approx(0.03125)
        and module.loses(row)
    )
    table = module.per_cell_markdown(documents, "rti", "ipopt")
    assert "| target reaching | map1 | nominal | 6/6 | 0/6 |" in table


def test_a_controller_on_several_tasks_is_also_gated_over_all_of_them() -> None:
    """4 of 12 pairs lost per task is not significant (p = 0.125); 8 of 24 over both tasks is (p = 0.008)."""
    from evaluation.reports.baseline import ALL_TASKS

    def run(won: int) -> list[dict]:
        records = []
        for env in ("KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"):
            records += [{**_record(seed, seed < won), "env_id": env} for seed in range(12)]
        return records

    comparison = compare_runs(run(won=8), run(won=12))
    rows = {row["env_id"]: row for row in comparison["rows"]}
    assert set(rows) == {"KoopNav-TargetReaching-v0", "KoopNav-Formation-v0", ALL_TASKS}
    assert rows[ALL_TASKS]["n"] == 24 and rows[ALL_TASKS]["only_b"] == 8
    assert rows["KoopNav-Formation-v0"]["p_value"] == pytest.approx(0.125)
    assert rows[ALL_TASKS]["p_value"] == pytest.approx(2 * 0.5**8)
    (failure,) = gate_failures(comparison, GateOptions())
    assert failure.startswith(f"c on {ALL_TASKS} (24 paired episodes): success 100% -> 67%")
    # one task only: no pooled row
    single = compare_runs(run(won=8)[:12], run(won=12)[:12])
    assert [row["env_id"] for row in single["rows"]] == ["KoopNav-TargetReaching-v0"]


# --------------------------------------------------------------------------- the gate fails closed
def _gate(base: Path, out: Path, *extra: str, controllers: str = NMPC) -> int:
    return ev.main(
        [*RUN, "--controllers", controllers, "--out", str(out), "--baseline", str(base), *GATE, *extra]
    )


def _edited(base: Path, tmp_path: Path, edit) -> Path:
    """A copy of the baseline's results.json with ``edit(doc)`` applied."""
    doc = json.loads((base / "results.json").read_text())
    edit(doc)
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize(
    "edit, extra, message",
    [
        (
            lambda d: d.update(episodes=[]),
            [],
            "the baseline has no episode that ran (0 records, 0 of them errors)",
        ),
        (
            lambda d: [r.update(status="error", error="RuntimeError: x") for r in d["episodes"]],
            [],
            "the baseline has no episode that ran (8 records, 8 of them errors)",
        ),
        (
            lambda d: [r.update(controller="renamed") for r in d["episodes"]],
            [],
            "the baseline has no episodes of 'nmpc' (it has ['renamed'])",
        ),
        (
            lambda d: None,
            ["--seed", "100"],
            "the baseline ran it with seeds 0-7 on map1/nominal, this run with seeds 100-107 on map1/nominal",
        ),
        (
            lambda d: None,
            ["--episodes", "4"],
            "nmpc: 4 episode(s) pair with the baseline, fewer than the minimum 8",
        ),
    ],
    ids=["empty", "all-errors", "renamed", "other-seeds", "too-few"],
)
def test_a_stale_baseline_fails_the_gate_before_any_episode(
    base, tmp_path, capsys, edit, extra, message
) -> None:
    code = _gate(_edited(base, tmp_path, edit), tmp_path / "run", *extra)
    err = capsys.readouterr().err
    assert code == 2, err
    assert "--fail-if-worse cannot judge this run against the baseline" in err and message in err
    assert "baseline gate passed" not in err
    assert not (tmp_path / "run" / "episodes.jsonl").exists()  # refused before any episode


def test_without_the_gate_a_stale_baseline_is_only_compared(base, tmp_path) -> None:
    """--baseline alone reports; only --fail-if-worse needs pairs."""
    path = _edited(base, tmp_path, lambda d: d.update(episodes=[]))
    code = ev.main([*RUN, "--controllers", STANDING, "--out", str(tmp_path / "run"), "--baseline", str(path)])
    assert code == 0
    assert json.loads((tmp_path / "run" / "baseline_comparison.json").read_text())["rows"] == []


def test_episodes_that_raise_in_the_run_fail_the_gate_after_it(base, tmp_path, capsys) -> None:
    """The planned episodes pair, but those that raised cannot: exit 2 naming why, not a pass."""
    code = _gate(base, tmp_path / "run", controllers="plugin_controllers:AlwaysRaising:label=nmpc")
    err = capsys.readouterr().err
    assert code == 2, err
    assert "the baseline gate cannot judge this run" in err
    assert (
        "nmpc: 0 episode(s) pair with the baseline" in err and "8 of its episodes in this run raised" in err
    )
    assert (tmp_path / "run" / "results.json").exists()  # the run's results are written all the same


def test_coverage_failures_name_a_baseline_controller_missing_from_the_run() -> None:
    base = [{**_record(s, True), "controller": name} for s in range(10) for name in ("c", "gone")]
    run = {"c": {("KoopNav-TargetReaching-v0", "map1", "nominal", s) for s in range(10)}}
    (failure,) = coverage_failures(run, base, GateOptions(), run_names_its_controllers=False)
    assert failure.startswith("the baseline's controller 'gone' is not in this run")
    assert coverage_failures(run, base, GateOptions(), run_names_its_controllers=True) == []
    raised = [*base, *({**_record(s, True), "controller": "d", "status": "error"} for s in range(3))]
    run["d"] = run["c"]
    (failure,) = coverage_failures(run, raised, GateOptions(), run_names_its_controllers=True)
    assert failure.endswith(
        "d: 0 episode(s) pair with the baseline, fewer than the minimum 10: all 3 of its baseline episodes raised"
    )
    del run["d"]
    assert coverage_failures(run, base, GateOptions(min_pairs=11), run_names_its_controllers=True) == [
        "c: 10 episode(s) pair with the baseline, fewer than the minimum 11: this run has only 10 "
        "episode(s) of it; run more per cell (--episodes)"
    ]


@pytest.mark.parametrize("value", [0, -3, 2.5, True])
def test_min_pairs_must_be_a_whole_number_of_at_least_one(value) -> None:
    with pytest.raises(ValueError, match=f"min_pairs={value!r} must be an integer >= 1"):
        GateOptions(min_pairs=value)


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda r: r.pop("success"), "a 'ok' record without ['success']"),
        (lambda r: r.update(success="false"), "field 'success' is 'false'; allowed: true or false"),
        (lambda r: r.update(success=None), "field 'success' is None; allowed: true or false"),
        (lambda r: r.update(steps=-5), "field 'steps' is -5; allowed: an integer >= 0"),
        (lambda r: r.update(collision=3), "field 'collision' is 3"),
        (lambda r: r.update(final_distance=[]), "field 'final_distance' is []"),
        (lambda r: r.update(final_distance=["0.1"]), "field 'final_distance' is ['0.1']"),
        (lambda r: r.update(seed="0"), "field 'seed' is '0'; allowed: an integer >= 0"),
        (lambda r: r.update(status="maybe"), "field 'status' is 'maybe'"),
        (lambda r: r.update(collision="obstacle"), "field 'success' is true with collision 'obstacle'"),
    ],
)
def test_a_baseline_record_is_validated_field_by_field(base, tmp_path, capsys, edit, message) -> None:
    def corrupt(doc: dict) -> None:
        edit(doc["episodes"][3])

    path = _edited(base, tmp_path, corrupt)
    with pytest.raises(ValueError) as error:
        load_baseline(path)
    text = str(error.value)
    assert str(path) in text and "episodes[3] ('KoopNav-TargetReaching-v0|nmpc|map1|nominal|3')" in text
    assert message in text
    assert _gate(path, tmp_path / "run") == 2 and message in capsys.readouterr().err


def test_the_ci_leaderboard_script_fails_closed_on_other_seeds(tmp_path) -> None:
    """.ci/leaderboard.sh with a subset run on seeds the committed baseline never ran: exit 2 at once."""
    import os
    import subprocess

    root = Path(ev.__file__).parent
    env = {**os.environ, "KOOPNAV_GATE_ARGS": "--controllers consensus --seed 1000 --workers 1"}
    done = subprocess.run(
        ["bash", ".ci/leaderboard.sh", str(tmp_path)], cwd=root, env=env, capture_output=True, text=True
    )
    assert done.returncode == 2, done.stderr
    assert "consensus: 0 episode(s) pair with the baseline" in done.stderr
    assert "baseline gate passed" not in done.stdout + done.stderr
