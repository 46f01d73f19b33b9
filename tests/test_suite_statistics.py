"""A suite run's statistics in its reports (evaluation/stats/suite_statistics.py): the leaderboard's
intervals are the two-stage bootstrap over layouts; every paired table is a family declared from
the run's design, Holm within it, its p-values the layout sign-flip test's; each table states its
power; records written before the metrics existed still make a report."""

from __future__ import annotations

import math

import numpy as np
import pytest

from evaluation.episodes.records import record_problem
from evaluation.reports.results import Results
from evaluation.reports.sections import markdown, sections
from evaluation.stats.aggregate import leaderboard, paired_comparisons
from evaluation.stats.clustered import layout_mean_interval, layout_rate_interval
from evaluation.stats.designs import ALL, declared_pairs, pooled_reference_pairs, reference_pairs
from evaluation.stats.families import HypothesisFamily, power_statement
from evaluation.stats.layout_tests import (
    layout_sign_flip_test,
    paired_means_by_layout,
    paired_rates_by_layout,
)
from evaluation.stats.run_data import RunData
from evaluation.stats.statistics import holm_adjusted, wilson_interval
from evaluation.stats.suite_statistics import MEASURES, METRICS, OUTCOMES, measure_table, suite_tables

TASKS = ("KoopNav-TargetReaching-v0", "KoopNav-Formation-v0")
#: the metric fields a record written before the suite's metric tables lacks
NEW_FIELDS = (
    "near_obstacle_share",
    "jerk_rms",
    "path_ratio",
    "strict_success",
    "success_excusing_unavoidable",
)


def _record(
    env_id: str, controller: str, layout: int, seed: int, rng: np.random.Generator, skill: float
) -> dict:
    """A plausible suite record: success more likely for a higher ``skill`` and on low layouts."""
    success = bool(rng.random() < skill * (1.0 - layout / 60))
    clearance = float(rng.normal(0.02 + 0.05 * skill, 0.02))
    record = {
        "key": f"{env_id}|{controller}|{layout}|{seed}",
        "status": "ok",
        "env_id": env_id,
        "controller": controller,
        "map": "suite:koopnav-bench-v1/validation",
        "slip": "high",
        "trial": seed,
        "seed": seed,
        "layout": layout,
        "layout_family": ("clutter", "passages", "rooms")[layout % 3],
        "layout_tier": ("easy", "medium", "hard")[layout % 3],
        "suite": f"koopnav-bench-v1/{env_id}/validation@000000000000",
        "success": success,
        "strict_success": success and clearance > 0.05,
        "success_excusing_unavoidable": success,
        "collision": None,
        "collision_at_fault": False,
        "steps": 100,
        "time_to_goal": float(rng.uniform(5, 10)) if success else None,
        "final_distance": [0.05 if success else 1.0 + rng.random()],
        "final_poses": [[float(rng.random()), float(seed), float(layout)]],
        "path_length": [float(rng.uniform(2.0, 3.0))],
        "straight_distance": [2.0],
        "path_ratio": None,
        "min_clearance": {"obstacle": clearance, "robot": None, "mover": None},
        "clearance_min_m": clearance,
        "near_obstacle_share": [float(rng.uniform(0, 0.3 * (1 - skill)))],
        "jerk_rms": [float(rng.uniform(1, 20))],
        "control_effort": [1.0],
        "formation_rms": None,
        "solver_failures": 0,
        "solve_ms_median": 1.0,
    }
    record["path_ratio"] = record["path_length"][0] / 2.0
    assert record_problem(record) is None, record_problem(record)
    return record


def _run(layouts: int = 12, seeds: int = 2, controllers=(("a", 0.9), ("b", 0.5), ("c", 0.6))) -> list[dict]:
    rng = np.random.default_rng(3)
    return [
        _record(env_id, name, layout, 100 * layout + j, rng, skill)
        for env_id in TASKS
        for name, skill in controllers
        for layout in range(layouts)
        for j in range(seeds)
    ]


def test_the_leaderboard_interval_is_the_two_stage_bootstrap_over_layouts() -> None:
    records = _run()
    data = RunData(records, {})
    for row in leaderboard(data.cells, data.records):
        own = [r for r in records if r["env_id"] == row["env_id"] and r["controller"] == row["controller"]]
        clusters = [[r["success"] for r in own if r["layout"] == lay] for lay in range(12)]
        wins = sum(r["success"] for r in own)
        wilson = wilson_interval(wins, len(own))
        _, low, high = layout_rate_interval(clusters)
        assert row["success_ci"] == [min(wilson[0], low), max(wilson[1], high)]
        # the final distance over settled runs: the two-stage bootstrap of the team means
        settled = [
            [100 * r["final_distance"][0] for r in own if r["layout"] == lay and r["success"]]
            for lay in range(12)
        ]
        _, d_low, d_high = layout_mean_interval([c for c in settled if c])
        assert row["final_distance_ci"] == [d_low, d_high]


def test_each_table_is_a_family_of_the_runs_design_with_holm_within_it() -> None:
    records = _run()
    tables = suite_tables(records)
    assert [t["measure"] for t in tables] == [m.key for m in MEASURES]
    assert declared_pairs(records) == [
        (env, a, b) for env in TASKS for a, b in (("a", "b"), ("a", "c"), ("b", "c"))
    ]
    for table in tables:
        family = table["family"]
        assert family["size"] == 6 and len(family["tests"]) == 6  # 3 pairs x 2 tasks, declared
        assert table["label"] in family["family"] and "koopnav-bench-v1/validation" in family["family"]
        raw = [t["p_value"] for t in family["tests"]]
        assert [t["p_holm"] for t in family["tests"]] == pytest.approx(holm_adjusted(raw))
        for t in family["tests"]:
            assert t["rejected"] == (t["p_holm"] <= 0.05)
        # every row carries its family's correction
        by_label = {t["comparison"]: t for t in family["tests"]}
        for row in table["rows"]:
            test = by_label[f"{row['env_id']}: {row['a']} vs {row['b']}"]
            assert (row["p_value"], row["p_holm"], row["rejected"]) == (
                test["p_value"],
                test["p_holm"],
                test["rejected"],
            )
    # the success table is the report's paired comparisons
    assert paired_comparisons(records) == tables[0]["rows"]


def test_a_narrower_family_is_declared_from_the_design_and_corrected_within_itself() -> None:
    """Every controller against a reference plus a named pair (a page that tests fewer pairs than
    every pair): the family holds exactly those, Holm runs over its own m, and its rows are the
    every-pair table's, oriented a - reference, with a Holm p no larger."""
    records = _run(controllers=(("a", 0.9), ("b", 0.5), ("c", 0.6), ("c-v0", 0.4)))
    declared = {env: ["a", "b", "c", "c-v0"] for env in TASKS}
    pairs = reference_pairs(declared, "b", also=[("c", "c-v0"), ("c", "c-v0")])
    assert pairs == [
        (env, a, b) for env in TASKS for a, b in (("a", "b"), ("c", "b"), ("c-v0", "b"), ("c", "c-v0"))
    ]
    narrow = measure_table(records, OUTCOMES[0], pairs, "each controller against b")
    every = measure_table(records, OUTCOMES[0])
    assert narrow["family"]["size"] == 8 and every["family"]["size"] == 12
    assert narrow["family"]["family"].endswith("success, each controller against b")
    raw = [t["p_value"] for t in narrow["family"]["tests"]]
    assert [t["p_holm"] for t in narrow["family"]["tests"]] == pytest.approx(holm_adjusted(raw))
    full = {(r["env_id"], r["a"], r["b"]): r for r in every["rows"]}
    for row in narrow["rows"]:
        twin = full.get((row["env_id"], row["a"], row["b"])) or full[row["env_id"], row["b"], row["a"]]
        sign = 1 if twin["a"] == row["a"] else -1
        assert row["difference"] == pytest.approx(sign * twin["difference"])
        assert row["p_value"] == pytest.approx(twin["p_value"])
        assert row["p_holm"] <= twin["p_holm"] + 1e-12
    with pytest.raises(ValueError, match=r"reference='z' is not one of the controllers \['a', 'b'\]"):
        reference_pairs({TASKS[0]: ["a", "b"]}, "z")


def test_a_pooled_comparison_keeps_each_tasks_layouts_apart() -> None:
    """A comparison pooled over both tasks tests every (task, layout) as its own cluster: a wins
    on layouts 0-5 of the first task and on 0-2 of the second, b on 3-5 of the second. Twelve
    clusters (9 for a, 3 for b) give the sign-flip p 598/4096; merging each layout number of the
    two tasks into one cluster would give six (3 for a, 3 ties) and p = 2/8, another interval."""
    rng = np.random.default_rng(0)
    records = []
    for env_id in TASKS:
        for layout in range(6):
            for name in ("a", "b"):
                record = _record(env_id, name, layout, 100 * layout, rng, 0.5)
                won = name == "a" if env_id == TASKS[0] or layout < 3 else name == "b"
                record.update(success=won, strict_success=won, success_excusing_unavoidable=won)
                records.append(record)
    pairs = pooled_reference_pairs({env: ["b", "a"] for env in TASKS}, "b")
    assert pairs == [(ALL, "a", "b")]
    table = measure_table(records, OUTCOMES[0], pairs, "a against b over both tasks")
    (row,) = table["rows"]
    assert (row["env_id"], row["layouts"], row["n"], row["only_a"], row["only_b"]) == (ALL, 12, 12, 9, 3)
    assert table["family"]["size"] == 1
    assert table["family"]["tests"][0]["comparison"] == "both tasks: a vs b"
    assert row["p_value"] == pytest.approx(598 / 4096)
    kept_apart = paired_rates_by_layout([[True]] * 9 + [[False]] * 3, [[False]] * 9 + [[True]] * 3)
    merged = paired_rates_by_layout(
        [[True, True]] * 3 + [[True, False]] * 3, [[False, False]] * 3 + [[False, True]] * 3
    )
    assert (row["p_value"], row["low"], row["high"]) == (kept_apart.p_value, kept_apart.low, kept_apart.high)
    assert merged.p_value == pytest.approx(0.25) and (merged.low, merged.high) != (row["low"], row["high"])
    # a controller missing from one task is no pooled comparison: counted in m, untested
    partial = [r for r in records if not (r["env_id"] == TASKS[1] and r["controller"] == "a")]
    cut = measure_table(partial, OUTCOMES[0], pairs, "a against b over both tasks")
    assert cut["rows"] == [] and cut["family"]["size"] == 1
    # pooled pairs need the reference in every task, and two tasks
    with pytest.raises(ValueError, match=r"reference='z' is not one of the controllers"):
        pooled_reference_pairs({env: ["a", "b"] for env in TASKS}, "z")
    with pytest.raises(ValueError, match="a pooled comparison needs at least two"):
        pooled_reference_pairs({TASKS[0]: ["a", "b"]}, "b")
    # a controller of one task only is left out; named pairs join where both are everywhere
    declared = {TASKS[0]: ["r", "a", "x", "a-v0"], TASKS[1]: ["r", "a", "a-v0"]}
    assert pooled_reference_pairs(declared, "r", also=[("a", "a-v0"), ("x", "r")]) == [
        (ALL, "a", "r"),
        (ALL, "a-v0", "r"),
        (ALL, "a", "a-v0"),
    ]


def test_a_pairs_test_is_the_layout_sign_flip_on_its_shared_units() -> None:
    records = _run()
    by = {(r["env_id"], r["controller"], r["layout"], r["seed"]): r for r in records}
    env = TASKS[1]
    for measure in (OUTCOMES[0], METRICS[0], METRICS[2]):
        table = measure_table(records, measure)
        (row,) = [r for r in table["rows"] if (r["env_id"], r["a"], r["b"]) == (env, "a", "c")]
        a, b = [], []
        for layout in range(12):
            pairs = [
                (measure.read(by[(env, "a", layout, s)]), measure.read(by[(env, "c", layout, s)]))
                for s in (100 * layout, 100 * layout + 1)
            ]
            pairs = [(x, y) for x, y in pairs if x is not None and y is not None]
            a.append([x for x, _ in pairs])
            b.append([y for _, y in pairs])
        compare = paired_rates_by_layout if measure.binary else paired_means_by_layout
        expected = compare(a, b)
        assert (
            row["p_value"] == expected.p_value and row["low"] == expected.low and row["high"] == expected.high
        )
        differences = [
            [float(x) - float(y) for x, y in zip(p, q, strict=True)] for p, q in zip(a, b, strict=True)
        ]
        assert row["p_value"] == layout_sign_flip_test(differences)[0]
        assert row["n"] == sum(len(p) for p in a)
        assert row["test"] == "layout sign-flip"
    # time to goal pairs only the units both won
    time_row = [
        r for r in measure_table(records, METRICS[2])["rows"] if r["env_id"] == env and r["a"] == "a"
    ][0]
    both_won = sum(
        by[(env, "a", lay, s)]["success"] and by[(env, time_row["b"], lay, s)]["success"]
        for lay in range(12)
        for s in (100 * lay, 100 * lay + 1)
    )
    assert time_row["n"] == both_won


def test_each_table_states_its_power_from_its_comparisons() -> None:
    records = _run(layouts=40)
    for measure in (OUTCOMES[0], METRICS[1]):
        table = measure_table(records, measure)
        family = HypothesisFamily(
            table["family"]["family"], tuple(t["comparison"] for t in table["family"]["tests"])
        )
        compare = paired_rates_by_layout if measure.binary else paired_means_by_layout
        by = {(r["env_id"], r["controller"], r["layout"], r["seed"]): measure.read(r) for r in records}
        comparisons = [
            compare(
                *(
                    [[by[(env, name, lay, s)] for s in (100 * lay, 100 * lay + 1)] for lay in range(40)]
                    for name in (a, b)
                )
            )
            for env, a, b in declared_pairs(records)
        ]
        expected = power_statement(comparisons, family)
        assert math.isfinite(expected.difference)
        assert table["power"]["difference"] == pytest.approx(expected.difference)
        assert table["power"]["family_size"] == 6
        assert "m = 6 tests" in table["power"]["sentence"]


def test_a_controller_without_a_shared_unit_still_counts_in_its_family() -> None:
    records = _run(controllers=(("a", 0.9), ("b", 0.5)))
    # controller c raised on every episode: its pairs were declared and count as p = 1
    for env_id in TASKS:
        records.append(
            {
                **{
                    k: records[0][k]
                    for k in (
                        "map",
                        "slip",
                        "trial",
                        "seed",
                        "layout",
                        "layout_family",
                        "layout_tier",
                        "suite",
                    )
                },
                "key": f"{env_id}|c",
                "status": "error",
                "error": "RuntimeError: boom",
                "env_id": env_id,
                "controller": "c",
            }
        )
    table = measure_table(records, OUTCOMES[0])
    assert table["family"]["size"] == 6
    assert len(table["rows"]) == 2  # only a vs b was run
    raw = [t["p_value"] for t in table["family"]["tests"]]
    assert sum(math.isnan(p) for p in raw) == 4
    counted = holm_adjusted([1.0 if math.isnan(p) else p for p in raw])
    ran = [t for t in table["family"]["tests"] if not math.isnan(t["p_value"])]
    assert [t["p_holm"] for t in ran] == pytest.approx(
        [q for q, p in zip(counted, raw, strict=True) if not math.isnan(p)]
    )


def test_records_without_the_new_fields_still_make_the_report() -> None:
    old = [{k: v for k, v in r.items() if k not in NEW_FIELDS} for r in _run(layouts=4, seeds=1)]
    assert all(record_problem(r) is None for r in old)
    data = Results(
        old,
        {
            "suite": {
                "name": "koopnav-bench-v1",
                "version": 1,
                "split": "validation",
                "layouts": [0, 4],
                "episodes_per_layout": 1,
                "tasks": {},
            }
        },
    )
    tables = {t["measure"]: t for t in data.suite_tables}
    for key in ("near_obstacle_share", "jerk_rms", "strict_success", "success_excusing_unavoidable"):
        assert tables[key]["rows"] == [] and tables[key]["power"] is None
        assert tables[key]["family"]["size"] == 6
    # clearance and path ratio are read from the fields that were there before
    assert tables["clearance_cm"]["rows"] and tables["path_ratio"]["rows"]
    text = markdown(sections(data))
    assert "**Paired: Minimum clearance [cm]**" in text
    assert "Paired: Jerk RMS [m/s³]: no pair of controllers shares a unit with a value." in text
    assert '"suite_tests"' in data.to_json()
