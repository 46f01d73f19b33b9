"""Every record is read once (issue 59, item 5; evaluation/episodes/distinct.py's ``read_once``): two
records of one episode (task, controller label, map, slip, seed) that agree in every outcome are
one episode wherever they are read (a resume log, a baseline, a published log, a page, a run's
data), and two that disagree are refused naming the file, the episode and the fields that differ,
never "the last one wins". The gate counts repeated identical episodes once for its minimum of
pairs as for its tests (tests/test_gate_decisions.py calls the gate's functions directly).
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import evaluate as ev
from evaluation.episodes.distinct import ConflictingRecords, outcome_fields, read_once
from evaluation.reports.baseline import load_baseline
from evaluation.reports.published import results_from_log
from evaluation.reports.results import Results

ROOT = Path(__file__).resolve().parents[1]
TR = "KoopNav-TargetReaching-v0"


def _rec(seed: int = 3, **changes) -> dict:
    """An episode record as KoopNav writes it (passes the record schema)."""
    record = {
        "key": f"{TR}|c|map1|nominal|{seed}",
        "status": "ok",
        "env_id": TR,
        "controller": "c",
        "map": "map1",
        "slip": "nominal",
        "trial": seed,
        "seed": seed,
        "success": True,
        "collision": None,
        "steps": 100,
        "final_distance": [0.01, 0.02],
        "final_poses": [[float(seed), 0.0, 0.0]] * 2,
        "solver_failures": 0,
    }
    return {**record, **changes}


# ------------------------------------------------------------------------------- the one rule
def test_a_repeat_that_differs_only_in_what_is_no_outcome_is_read_once() -> None:
    """Wall and decision times, a calibration's time and source, a controller's own timings, the
    traceback's text and the trial index are no outcome; NaN (in a run) and null (read back) are
    one value."""
    first = _rec(
        wall_seconds=1.5,
        solve_ms_median=2.0,
        calibration={"transitions": 5, "key": "ab", "seconds": 0.5, "source": "fitted"},
        controller_extra={"filter_ms_median": 1.0, "solver": "rti"},
        time_to_goal=None,
    )
    again = _rec(
        wall_seconds=9.0,
        solve_ms_median=7.0,
        solve_ms=[1.0, 2.0],
        calibration={"transitions": 5, "key": "ab", "seconds": 0.1, "source": "cache"},
        controller_extra={"filter_ms_median": math.nan, "solver": "rti"},
        time_to_goal=math.nan,
        traceback="elsewhere",
        trial=13,
        key="another run's numbering",
    )
    other = _rec(seed=4)
    assert read_once([first, other, again, first], "f") == [first, other]
    assert outcome_fields(first) == outcome_fields(again)
    # a setting or an outcome inside a summary is compared
    for changes in (
        {"calibration": {"transitions": 6, "key": "ab", "seconds": 0.5, "source": "fitted"}},
        {"controller_extra": {"filter_ms_median": 1.0, "solver": "ipopt"}},
        {"env_kwargs": '{"n_robots": 4}'},
        {"wall_seconds": 1.5, "steps": 101},
    ):
        with pytest.raises(ConflictingRecords):
            read_once([first, {**first, **changes}], "f")


def test_a_conflicting_repeat_is_refused_naming_source_places_episode_and_fields() -> None:
    flipped = _rec(success=False, collision="obstacle", final_distance=[0.5, 0.02], steps=7)
    with pytest.raises(ConflictingRecords) as caught:
        read_once(
            [_rec(seed=1), _rec(), flipped],
            "baseline 'b.json'",
            ["episodes[0]", "episodes[1]", "episodes[2]"],
        )
    assert str(caught.value) == (
        f"baseline 'b.json': episode '{TR}|c|map1|nominal|3' (seed 3) is recorded twice with different "
        "outcomes, at episodes[1] and episodes[2], which differ in success, collision, final_distance, steps "
        "(success: True, then False; collision: None, then 'obstacle'; final_distance: [0.01, 0.02], then "
        "[0.5, 0.02]; ...); which one is true cannot be told, so neither is read (remove the wrong record, "
        "or run the episode again)"
    )
    assert isinstance(caught.value, ValueError)  # the command line's bad input (exit 2)
    with pytest.raises(ConflictingRecords, match=r"at record 1 and record 2, which differ in success \("):
        read_once([_rec(), _rec(success=False)], "f")
    without = {k: v for k, v in _rec().items() if k != "final_poses"}
    with pytest.raises(
        ConflictingRecords, match=r"differ in final_poses \(final_poses: absent, then \[\[3\.0, "
    ):
        read_once([without, _rec()], "f")


def test_a_run_s_data_counts_a_record_given_twice_once() -> None:
    """Aggregation (cells, leaderboard, paired comparisons) reads every episode once."""
    measured = {
        "time_to_goal": 9.0,
        "path_length": [2.0, 2.0],
        "control_effort": [1.0, 1.0],
        "formation_rms": None,
        "solve_ms_median": 1.0,
        "solve_ms_p95": 2.0,
    }
    records = [_rec(seed=s, **measured) for s in range(4)]
    results = Results([*records, dict(records[2], wall_seconds=3.0)], {})
    assert len(results.records) == 4
    (cell,) = results.cells
    assert (cell.episodes, cell.valid, cell.duplicates) == (4, 4, 0)
    assert results.leaderboard()[0]["episodes_run"] == 4
    with pytest.raises(ConflictingRecords, match=r"^the run's records: episode .* differ in success "):
        Results([*records, dict(records[2], success=False)], {})


# ------------------------------------------------------------------------ end to end, a real run
RUN = [
    "--env",
    TR,
    "--controllers",
    "consensus",
    "--maps",
    "map1",
    "--slips",
    "nominal",
    "--episodes",
    "10",
    "--max-episode-steps",
    "20",
    "--quiet",
    "--workers",
    "1",
]


@pytest.fixture(scope="module")
def noisy(tmp_path_factory) -> Path:
    """Ten distinct episodes (perturbed starts): a run directory with its log and results.json."""
    out = tmp_path_factory.mktemp("noisy")
    assert ev.main([*RUN, "--start-noise", "0.05", "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def exact(tmp_path_factory) -> Path:
    """Exact starts at nominal slip: every seed runs the same episode, ten copies of one."""
    out = tmp_path_factory.mktemp("exact")
    assert ev.main([*RUN, "--start-noise", "0", "--out", str(out)]) == 0
    return out


def _baseline(run: Path, tmp_path: Path, edit) -> Path:
    """A copy of ``run``'s results.json with its episode list replaced by ``edit(episodes)``."""
    doc = json.loads((run / "results.json").read_text())
    doc["episodes"] = edit(doc["episodes"])
    path = tmp_path / "baseline.json"
    path.write_text(json.dumps(doc))
    return path


def _flip(record: dict) -> dict:
    """The record as a success (a success has no collision, and is a success with the unavoidable
    collisions excused too)."""
    assert record["collision"] is None and not record["success"]
    return {**record, "success": True, "success_excusing_unavoidable": True}


@pytest.mark.parametrize("flipped_last", [True, False], ids=["failure-then-success", "success-then-failure"])
def test_a_baseline_holding_each_record_twice_is_refused_in_either_order(
    noisy, tmp_path, capsys, flipped_last
) -> None:
    """Before: the last record won, so one order passed the gate and the other failed it."""

    def doubled(episodes: list[dict]) -> list[dict]:
        flipped = [_flip(r) for r in episodes]
        return episodes + flipped if flipped_last else flipped + episodes

    path = _baseline(noisy, tmp_path, doubled)
    code = ev.main(
        [*RUN, "--start-noise", "0.05", "--out", str(tmp_path / "run"), "--baseline", str(path)]
        + ["--fail-if-worse"]
    )
    err = capsys.readouterr().err
    assert code == 2, err
    first, second = ("False", "True") if flipped_last else ("True", "False")
    assert (
        f"error: baseline {str(path)!r}: episode '{TR}|consensus|map1|nominal|0' (seed 0) is recorded twice "
        f"with different outcomes, at episodes[0] and episodes[10], which differ in success, "
        f"success_excusing_unavoidable (success: {first}, then {second}; success_excusing_unavoidable: "
        f"{first}, then {second}); which one is true cannot be told" in err
    )
    assert not (tmp_path / "run").exists()  # refused before any episode


def test_a_baseline_holding_each_record_twice_alike_counts_each_once(noisy, tmp_path) -> None:
    path = _baseline(
        noisy, tmp_path, lambda episodes: episodes + [{**r, "wall_seconds": 0.0} for r in episodes]
    )
    doc = load_baseline(path)
    assert [r["key"] for r in doc["episodes"]] == [
        r["key"] for r in json.loads((noisy / "results.json").read_text())["episodes"]
    ]


def test_ten_copies_of_one_episode_are_one_pair_and_the_gate_cannot_judge_them(
    exact, tmp_path, capsys
) -> None:
    """Before: ten seeds of one episode passed --min-pairs 10 as ten pairs, and the distance
    test failed the run on one distinct pair with a zero-width interval."""
    episodes = json.loads((exact / "results.json").read_text())["episodes"]
    assert len({json.dumps(r["final_poses"]) for r in episodes}) == 1  # one episode, ten times
    # the baseline ended every copy of it 0 cm from the targets: the run looks farther
    path = _baseline(
        exact, tmp_path, lambda eps: [{**r, "final_distance": [0.0] * len(r["final_distance"])} for r in eps]
    )
    code = ev.main(
        [
            *RUN,
            "--start-noise",
            "0",
            "--out",
            str(tmp_path / "run"),
            "--baseline",
            str(path),
            "--fail-if-worse",
        ]
    )
    err = capsys.readouterr().err
    assert code == 2, err
    assert (
        "consensus: 10 episode(s) pair with the baseline but only 1 of those pairs are distinct, fewer than "
        "the minimum 10: the others repeat an earlier seed's two episodes bit for bit" in err
    )
    assert "worse than the baseline" not in err
    (row,) = json.loads((tmp_path / "run" / "baseline_comparison.json").read_text())["rows"]
    assert row["n"] == 1 and row["distance_cm_low"] == row["distance_cm_high"] > 0


def _resume(run: Path, tmp_path: Path, append: bytes) -> tuple[Path, Path]:
    out = tmp_path / "resumed"
    shutil.copytree(run, out)
    log = out / "episodes.jsonl"
    log.write_bytes(log.read_bytes() + append)
    return out, log


def test_a_resume_log_with_a_flipped_duplicate_is_refused_by_name(noisy, tmp_path, capsys) -> None:
    """Before: the resumed run exited 0, counting a "success" that settled metres away."""
    lines = (noisy / "episodes.jsonl").read_bytes().splitlines()
    first = json.loads(lines[1])
    out, log = _resume(noisy, tmp_path, (json.dumps(_flip(first)) + "\n").encode())
    code = ev.main([*RUN, "--start-noise", "0.05", "--out", str(out), "--resume"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert (
        f"error: {log} cannot be resumed: episode {first['key']!r} (seed {first['seed']}) is recorded twice "
        f"with different outcomes, at line 2 and line {len(lines) + 1}, which differ in success, "
        "success_excusing_unavoidable (success: False, then True; success_excusing_unavoidable: False, then "
        "True)" in err
    )
    assert log.read_bytes().splitlines()[-1] == json.dumps(_flip(first)).encode()  # nothing changed


def test_a_resume_log_with_a_repeated_line_reads_it_once(noisy, tmp_path, capsys) -> None:
    lines = (noisy / "episodes.jsonl").read_bytes().splitlines()
    out, log = _resume(noisy, tmp_path, lines[3] + b"\n")
    assert ev.main([*RUN, "--start-noise", "0.05", "--out", str(out), "--resume"]) == 0
    assert (
        f"note: {log}: 1 record(s) repeat an episode logged before, outcome for outcome; each episode is "
        "read once" in capsys.readouterr().err
    )
    assert len(json.loads((out / "results.json").read_text())["episodes"]) == 10


# ------------------------------------------------------------------------------ page generators
def test_a_published_log_with_a_conflicting_duplicate_is_refused(noisy, tmp_path) -> None:
    lines = (noisy / "episodes.jsonl").read_bytes().splitlines()
    third = json.loads(lines[3])
    log = tmp_path / "episodes.jsonl"
    log.write_bytes(b"\n".join([*lines, json.dumps(_flip(third)).encode()]) + b"\n")
    with pytest.raises(
        ValueError,
        match=rf"^{log}: episode '{TR}\|consensus\|map1\|nominal\|2' \(seed 2\) is recorded twice with "
        rf"different outcomes, at line 4 and line {len(lines) + 1}, which differ in success, "
        r"success_excusing_unavoidable ",
    ):
        results_from_log(log)
    log.write_bytes(b"\n".join([*lines, lines[3]]) + b"\n")  # the same line twice: read once
    assert len(results_from_log(log).records) == 10


def _page(*results: Path, tmp_path: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "docs/make_results_md.py", *map(str, results)]
        + ["--out", str(tmp_path / "results.md"), "--figures", str(tmp_path / "figures")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,  # a hang guard only
    )


def test_the_results_page_refuses_conflicting_duplicates_naming_the_files(noisy, tmp_path) -> None:
    doubled = _baseline(noisy, tmp_path, lambda eps: eps + [_flip(eps[0])])
    done = _page(doubled, tmp_path=tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith(
        f"error: results {str(doubled)!r}: episode '{TR}|consensus|map1|nominal|0' (seed 0) is recorded "
        "twice with different outcomes, at episodes[0] and episodes[10], which differ in success"
    )
    # two files that disagree about one episode: pooled, the refusal names both
    other = tmp_path / "other.json"
    doc = json.loads((noisy / "results.json").read_text())
    other.write_text(json.dumps({**doc, "episodes": [_flip(doc["episodes"][0])]}))
    done = _page(noisy / "results.json", other, tmp_path=tmp_path)
    assert done.returncode == 2, done.stderr
    assert (
        f"at {noisy / 'results.json'} episodes[0] and {other} episodes[0], which differ in success"
        in done.stderr
    )
    assert not (tmp_path / "results.md").exists()


def test_the_compute_page_refuses_a_conflicting_duplicate_by_name(noisy, tmp_path) -> None:
    """docs/make_compute_md.py read its archives' logs line by line and kept the last record of an
    episode logged twice; it now reads them as every page does (results_from_log)."""
    import importlib.util

    from evaluation.reports.published import pack_run

    spec = importlib.util.spec_from_file_location("make_compute_md", ROOT / "docs" / "make_compute_md.py")
    assert spec is not None and spec.loader is not None
    page = importlib.util.module_from_spec(spec)
    sys.modules["make_compute_md"] = page
    spec.loader.exec_module(page)
    run = tmp_path / "run"
    shutil.copytree(noisy, run)
    lines = (run / "episodes.jsonl").read_bytes().splitlines()
    assert len(page.read_records(pack_run(run, tmp_path / "same.tar.xz"), "")) == 10
    (run / "episodes.jsonl").write_bytes(
        b"\n".join([*lines, json.dumps(_flip(json.loads(lines[3]))).encode()]) + b"\n"
    )
    with pytest.raises(ConflictingRecords, match=r"is recorded twice with different outcomes"):
        page.read_records(pack_run(run, tmp_path / "flipped.tar.xz"), "")
