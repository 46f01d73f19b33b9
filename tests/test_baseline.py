"""--baseline and --fail-if-worse (evaluation/baseline.py): pairing across runs, refusal of other
settings, the gate's decisions, bad baseline files, the GitHub step summary."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import evaluate as ev
from evaluation.baseline import GateOptions, compare_runs, gate_failures, load_baseline

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
    }


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("base")
    assert ev.main([*RUN, "--controllers", NMPC, "--out", str(out)]) == 0
    return out


def test_an_identical_rerun_passes_the_gate(base, tmp_path, capsys) -> None:
    code = ev.main(
        [*RUN, "--controllers", NMPC, "--out", str(tmp_path), "--baseline", str(base), "--fail-if-worse"]
    )
    assert code == 0
    assert "baseline gate passed" in capsys.readouterr().out
    comparison = json.loads((tmp_path / "baseline_comparison.json").read_text())
    (row,) = comparison["rows"]
    assert row["n"] == 8 and row["only_a"] == row["only_b"] == 0 and row["distance_cm_difference"] == 0.0


def test_a_degraded_controller_fails_the_gate(base, tmp_path, capsys) -> None:
    degraded = "nominal-nmpc:solver=rti,horizon=3,label=nmpc"
    code = ev.main(
        [*RUN, "--controllers", degraded, "--out", str(tmp_path), "--baseline", str(base), "--fail-if-worse"]
    )
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


def test_the_github_step_summary_is_appended(base, tmp_path, monkeypatch) -> None:
    summary = tmp_path / "summary.md"
    summary.write_text("earlier step\n")
    monkeypatch.setenv("GITHUB_STEP_SUMMARY", str(summary))
    assert (
        ev.main([*RUN, "--controllers", NMPC, "--out", str(tmp_path / "run"), "--baseline", str(base)]) == 0
    )
    text = summary.read_text()
    assert (
        text.startswith("earlier step\n")
        and "## KoopNav leaderboard" in text
        and "Compared with the baseline" in text
    )


def test_the_badge_is_valid_svg_with_the_rate_and_its_interval(base, tmp_path) -> None:
    import xml.etree.ElementTree as ET

    assert ev.main([*RUN, "--controllers", NMPC, "--out", str(tmp_path), "--badge", "nmpc"]) == 0
    root = ET.fromstring((tmp_path / "badge.svg").read_text())
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
    from evaluation.baseline import ALL_TASKS

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
