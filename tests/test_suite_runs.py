"""Runs on the benchmark suite (``--suite koopnav-bench-v1``): each layout's episodes run on that
layout and every controller meets the same (layout, seed) units; records carry the layout, its
family and tier and the split's label; the reports print the label and break success down by
tier and family, with intervals over layouts; bad suite options are refused by name; an
interrupted suite run resumes, and a log of another suite version is refused."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

import evaluate as ev
from evaluation.episodes.records import record_problem
from evaluation.stats.aggregate import leaderboard, paired_comparisons
from evaluation.stats.run_data import RunData
from koopman_envs.suites import load_suite

ROOT = Path(ev.__file__).parent
SUITE = "koopnav-bench-v1"
TASKS = {"KoopNav-TargetReaching-v0": "target_reaching", "KoopNav-Formation-v0": "formation"}
#: two layouts x one episode per task, a fast controller and a real CasADi one, short episodes
ARGS = [
    "--suite",
    SUITE,
    "--split",
    "test",
    "--layouts",
    "2",
    "--controllers",
    "consensus",
    "nominal-nmpc",
    "--solver",
    "rti",
    "--env-kwargs",
    "max_episode_steps=10",
    "--workers",
    "1",
    "--quiet",
]
#: record fields that hold wall times (they differ between any two runs of one episode)
_TIMING = {"wall_seconds", "solve_ms", "solve_ms_median", "solve_ms_p95", "controller_extra", "calibration"}


def _outcomes(records: list[dict]) -> dict[str, dict]:
    return {r["key"]: {k: v for k, v in r.items() if k not in _TIMING} for r in records}


def _log_records(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()[1:]]


@pytest.fixture(scope="module")
def suite_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("suite")
    assert ev.main([*ARGS, "--out", str(out)]) == ev.SUCCESS_EXIT
    return out


def test_every_episode_runs_on_its_layout_and_records_it(suite_run) -> None:
    results = json.loads((suite_run / "results.json").read_text())
    episodes = results["episodes"]
    assert len(episodes) == 2 * 2 * 2  # tasks x controllers x layouts
    for record in episodes:
        assert record["status"] == "ok", record.get("error")
        assert record_problem(record) is None
        suite = load_suite(SUITE, TASKS[record["env_id"]], "test")
        layout = suite.layout(record["layout"])
        assert record["map"] == "suite:koopnav-bench-v1/test"
        assert (record["layout_family"], record["layout_tier"], record["suite"]) == (
            layout.family,
            layout.tier,
            suite.label,
        )
    # the episode's obstacles (kept for the first trial of a cell) are its layout's
    for record in _log_records(suite_run):
        if record["trial"] == 0:
            suite = load_suite(SUITE, TASKS[record["env_id"]], "test")
            assert np.allclose(record["obstacles"], suite.layout(0).spec.obstacles)
    config = results["config"]["suite"]
    assert (config["name"], config["version"], config["split"], config["layouts"]) == (
        SUITE,
        1,
        "test",
        [0, 2],
    )
    for env_id, task in TASKS.items():
        assert config["tasks"][env_id]["sha256"] == load_suite(SUITE, task, "test").sha256


def test_controllers_are_paired_on_the_same_layout_and_seed_units(suite_run) -> None:
    results = json.loads((suite_run / "results.json").read_text())
    for env_id in TASKS:
        units = {
            name: sorted(
                (r["layout"], r["seed"])
                for r in results["episodes"]
                if r["env_id"] == env_id and r["controller"] == name
            )
            for name in ("consensus", "nominal-nmpc")
        }
        assert units["consensus"] == units["nominal-nmpc"] == [(0, 0), (1, 1)]
    pairs = results["paired_comparisons"]
    assert [(p["a"], p["b"], p["n"]) for p in pairs] == [("consensus", "nominal-nmpc", 2)] * 2


def test_the_reports_print_the_label_and_break_success_down_by_tier_and_family(suite_run) -> None:
    markdown = (suite_run / "results.md").read_text()
    for task in TASKS.values():
        assert load_suite(SUITE, task, "test").label in markdown
    assert "Suite koopnav-bench-v1 (version 1), split test, layouts 0-1 (2 of 200)" in markdown
    assert "| Task | Controller | easy | medium | hard |" in markdown
    assert "| Task | Controller | clutter | passages | rooms |" in markdown
    assert "two-stage bootstrap over layouts" in markdown and "over trials" not in markdown
    results = json.loads((suite_run / "results.json").read_text())
    tiers = [r for r in results["suite_breakdown"] if r["by"] == "layout_tier"]
    assert len(tiers) == 2 * 2 * 3 and sum(r["episodes"] for r in tiers) == 8
    assert "layout_tier" in (suite_run / "results.csv").read_text().splitlines()[0]
    jsonschema = pytest.importorskip("jsonschema")
    jsonschema.validate(results, json.loads((ROOT / "docs" / "results.schema.json").read_text()))


#: the captions of a suite report's paired tables, one per outcome and metric
PAIRED_CAPTIONS = (
    "Paired: Success",
    "Paired: Strict success (clearance above 5 cm all episode)",
    "Paired: Success excusing unavoidable collisions",
    "Paired: Minimum clearance [cm]",
    "Paired: Share of periods within 5 cm of an obstacle",
    "Paired: Time to goal [s]",
    "Paired: Path-length ratio",
    "Paired: Jerk RMS [m/s³]",
)


def test_the_report_holds_a_tested_table_per_outcome_and_metric(suite_run) -> None:
    markdown = (suite_run / "results.md").read_text()
    assert "## Outcomes and metrics over layouts" in markdown
    assert "## Paired comparisons over layouts" in markdown and "McNemar" not in markdown
    for caption in PAIRED_CAPTIONS:
        assert caption in markdown
    results = json.loads((suite_run / "results.json").read_text())
    tables = results["suite_tests"]
    assert len(tables) == len(PAIRED_CAPTIONS)
    for table in tables:
        # one pair per task, declared for both tasks; Holm within the table
        family = table["family"]
        assert family["size"] == 2 and [t["comparison"] for t in family["tests"]] == [
            f"{env_id}: consensus vs nominal-nmpc" for env_id in TASKS
        ]
        assert f"Family '{family['family']}': m = 2 tests" in markdown
        for row in table["rows"]:
            assert row["test"] == "layout sign-flip" and row["layouts"] == 2
    # the episodes ran 10 periods: clearance, near-obstacle share and jerk are compared on every unit
    for key in ("clearance_cm", "near_obstacle_share", "jerk_rms"):
        (table,) = [t for t in tables if t["measure"] == key]
        assert [r["n"] for r in table["rows"]] == [2, 2]
    assert [row["controller"] for row in results["suite_summary"]] == ["consensus", "nominal-nmpc"] * 2
    for record in results["episodes"]:
        assert len(record["near_obstacle_share"]) == len(record["final_distance"])
        assert record["jerk_rms"] is not None and record["path_ratio"] is not None


def test_a_log_written_before_the_metrics_still_resumes_and_reports(suite_run, tmp_path) -> None:
    """A log whose records lack the metric fields (written before them) is read as it is: nothing
    runs again, and the report's tables count those episodes as having no value."""
    lines = (suite_run / "episodes.jsonl").read_text().splitlines()
    old = [json.loads(line) for line in lines[1:]]
    for record in old:
        for field in (
            "near_obstacle_share",
            "jerk_rms",
            "path_ratio",
            "strict_success",
            "success_excusing_unavoidable",
        ):
            record.pop(field)
    (tmp_path / "episodes.jsonl").write_text("\n".join([lines[0], *map(json.dumps, old)]) + "\n")
    assert ev.main([*ARGS, "--out", str(tmp_path), "--resume"]) == ev.SUCCESS_EXIT
    assert [json.loads(line) for line in (tmp_path / "episodes.jsonl").read_text().splitlines()[1:]] == old
    markdown = (tmp_path / "results.md").read_text()
    assert "Paired: Jerk RMS [m/s³]: no pair of controllers shares a unit with a value." in markdown
    assert "**Paired: Minimum clearance [cm]**" in markdown


def test_an_interrupted_suite_run_resumes_to_the_uninterrupted_results(suite_run, tmp_path) -> None:
    log = (suite_run / "episodes.jsonl").read_text().splitlines(keepends=True)
    (tmp_path / "episodes.jsonl").write_text("".join(log[:4]))  # the header and 3 of 8 episodes
    assert ev.main([*ARGS, "--out", str(tmp_path), "--resume"]) == ev.SUCCESS_EXIT
    assert _outcomes(_log_records(tmp_path)) == _outcomes(_log_records(suite_run))


def test_a_log_of_another_suite_version_is_refused_by_name(suite_run, tmp_path, capsys) -> None:
    lines = (suite_run / "episodes.jsonl").read_text().splitlines(keepends=True)
    header = json.loads(lines[0])
    header["config"]["suite"]["tasks"]["KoopNav-Formation-v0"]["sha256"] = "0" * 64
    (tmp_path / "episodes.jsonl").write_text(json.dumps(header) + "\n" + "".join(lines[1:3]))
    assert ev.main([*ARGS, "--out", str(tmp_path), "--resume"]) == ev.BAD_INPUT_EXIT
    err = capsys.readouterr().err
    assert "belongs to a run with other settings (suite: logged" in err and "0000000000" in err


@pytest.mark.parametrize(
    ("words", "named"),
    [
        (["--suite", "koopnav-bench-v9"], "suite='koopnav-bench-v9' is not one of ['koopnav-bench-v1']"),
        (["--suite", SUITE, "--maps", "map1"], "cannot be combined with --maps"),
        (["--suite", SUITE, "--random-maps", "3"], "cannot be combined with --random-maps"),
        (["--suite", SUITE, "--paper"], "cannot be combined with --paper"),
        (["--suite", SUITE, "--layouts", "0"], "layouts=0:0 is not a selection of koopnav-bench-v1/"),
        (["--suite", SUITE, "--layouts", "201"], "allowed: N in [1, 200] (the first N) or a slice a:b"),
        (["--suite", SUITE, "--layouts", "5:3"], "layouts=5:3 is not a selection"),
        (["--suite", SUITE, "--layouts", "a:b"], "layouts='a:b' is not a selection"),
        (["--suite", SUITE, "--episodes", "60"], "make 12000 episodes per cell; allowed: at most 10000"),
        (["--layouts", "2"], "--layouts need --suite NAME"),
        (["--split", "validation"], "--split need --suite NAME"),
    ],
)
def test_bad_suite_options_are_refused_by_name_before_any_episode(words, named, tmp_path, capsys) -> None:
    code = ev.main([*words, "--controllers", "consensus", "--out", str(tmp_path / "out"), "--quiet"])
    assert code == ev.BAD_INPUT_EXIT
    assert named in capsys.readouterr().err
    assert not (tmp_path / "out" / "episodes.jsonl").exists()


def test_an_unknown_split_is_refused_by_name(capsys) -> None:
    with pytest.raises(SystemExit) as stop:
        ev.main(["--suite", SUITE, "--split", "tset"])
    assert stop.value.code == ev.BAD_INPUT_EXIT
    assert "invalid choice: 'tset'" in capsys.readouterr().err
    with pytest.raises(ValueError, match="split='tset' is not one of"):
        ev.RunSpec(suite=SUITE, split="tset", controllers=["consensus"]).validate()


def test_the_spec_refuses_suite_with_maps_and_layouts_without_suite() -> None:
    with pytest.raises(ValueError, match=r"suite='koopnav-bench-v1' and maps=\['map1'\]"):
        ev.RunSpec(suite=SUITE, maps=["map1"], controllers=["consensus"]).validate()
    with pytest.raises(ValueError, match="layouts=.* needs suite="):
        ev.RunSpec(layouts=3, controllers=["consensus"]).validate()


def test_a_unit_is_fixed_by_its_layout_and_episode_so_a_smaller_run_is_a_subset() -> None:
    def units(**changes) -> set[tuple]:
        spec = ev.RunSpec(suite=SUITE, controllers=["consensus"], slips=["high"], **changes)
        spec.validate()
        return {(e.env_id, e.key, e.seed, e.layout) for e in spec.resolved().episodes_plan()}

    small, large = units(layouts=(3, 5), episodes=2), units(layouts=8, episodes=3)
    assert len(small) == 2 * 2 * 2 and small < large
    # layout 4, episode 1 of the 200-layout test split: trial and seed 1 * 200 + 4
    assert (
        "KoopNav-Formation-v0",
        "KoopNav-Formation-v0|consensus|suite:koopnav-bench-v1/test|high|204",
        204,
        4,
    ) in small


def test_batched_episodes_run_on_their_own_layouts(tmp_path) -> None:
    """A controller that acts in batch (tests/plugin_controllers.py, standing still) runs a cell's
    episodes together in the vector env: each sub-env must get its own layout."""
    spec = ev.RunSpec(
        envs="KoopNav-TargetReaching-v0",
        suite=SUITE,
        layouts=3,
        controllers=["plugin_controllers:BatchedFailingOnce"],
        slips=["nominal"],
        env_kwargs={"max_episode_steps": 2, "start_noise": 0.0},
    )
    together = ev.evaluate(spec, workers=1, batch=64).records
    suite = load_suite(SUITE, "target_reaching", "test")
    for record in together:
        assert record["status"] == "ok", record.get("error")
        assert np.allclose(record["final_poses"], suite.layout(record["layout"]).spec.starts, atol=1e-9)


def _record(layout: int | None, seed: int, success: bool, controller: str = "a") -> dict:
    record = {
        "key": f"e|{controller}|m|s|{seed}|{layout}",
        "status": "ok",
        "env_id": "e",
        "controller": controller,
        "map": "suite:koopnav-bench-v1/test",
        "slip": "high",
        "trial": seed,
        "seed": seed,
        "success": success,
        "collision": None,
        "steps": 10,
        "final_distance": [0.05 if success else 1.0 + 0.01 * seed + 0.1 * (layout or 0)],
        "final_poses": [[0.0, float(seed), float(layout or 0)]],
        "solver_failures": 0,
        "time_to_goal": None,
        "path_length": [1.0],
        "control_effort": [1.0],
        "formation_rms": None,
        "solve_ms_median": 1.0,
    }
    if layout is not None:
        record.update(layout=layout, layout_family="clutter", layout_tier="easy", suite="s@0")
    return record


def test_the_leaderboard_interval_resamples_layouts() -> None:
    """Two layouts, five episodes each: one always succeeds, one never. The layouts are the
    sample: resampling them gives 0%, 50% or 100%, so the interval is [0, 1]; resampling the ten
    seeds as independent trials would make it far narrower."""
    records = [_record(layout, 10 * layout + j, layout == 0) for layout in (0, 1) for j in range(5)]
    data = RunData(records, {})
    (row,) = leaderboard(data.cells, data.records)
    assert row["success_rate"] == 0.5 and row["success_ci"] == [0.0, 1.0]


def test_records_of_one_seed_on_two_layouts_are_two_units() -> None:
    """Pairing and reading once go by (layout, seed): the same seed on two layouts is two episodes."""
    records = [_record(layout, 7, layout == 0, name) for name in ("a", "b") for layout in (0, 1)]
    data = RunData(copy.deepcopy(records), {})
    assert len(data.records) == 4
    (pair,) = paired_comparisons(data.records)
    assert pair["n"] == 2


@pytest.mark.parametrize(
    ("field", "value"),
    [("layout", -1), ("layout", "3"), ("layout_family", "maze"), ("layout_tier", "extreme"), ("suite", "")],
)
def test_bad_layout_fields_are_refused_by_both_schemas(field, value) -> None:
    record = _record(0, 1, True)
    record[field] = value
    assert field in (record_problem(record) or "")
    jsonschema = pytest.importorskip("jsonschema")
    schema = json.loads((ROOT / "docs" / "results.schema.json").read_text())["properties"]["episodes"][
        "items"
    ]
    jsonschema.validate(_record(0, 1, True), schema)
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(record, schema)


def test_a_suite_run_of_one_controller_writes_its_reports_without_pairs(tmp_path) -> None:
    """One controller has nothing to pair: the reports are written with no paired rows (the run
    ended in "family ... declares no comparison" after every episode had run)."""
    out = tmp_path / "one"
    words = [w for w in ARGS if w != "nominal-nmpc"]
    assert ev.main([*words, "--out", str(out)]) == ev.SUCCESS_EXIT
    report = json.loads((out / "results.json").read_text())
    assert report["paired_comparisons"] == [] and len(report["leaderboard"]) == 2  # one row per task
    assert RunData(_log_records(out), report["config"]).suite_tables == []
