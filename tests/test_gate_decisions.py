"""evaluation/reports/baseline.py function by function, with every expectation written out (issue 41,
mutation testing): the pairing of episodes across two runs, the rows and their order, the gate's
thresholds at their boundaries, every reason the gate gives for not judging a run, the refusal of
a baseline of other settings or of a malformed file, and the Markdown section, to the character.

tests/test_baseline.py runs the same code end to end through ``evaluate.py``; these call it
directly, so that a changed threshold, message or order fails here within milliseconds.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from evaluation.episodes.distinct import ConflictingRecords
from evaluation.reports.baseline import (
    ALL_TASKS,
    GateOptions,
    compare_runs,
    comparison_markdown,
    coverage_failures,
    distinct_pairs,
    gate_failures,
    load_baseline,
    pair_keys,
    refuse_incomparable,
)
from evaluation.stats.statistics import bootstrap_mean_interval, paired_comparison

TR, FO = "KoopNav-TargetReaching-v0", "KoopNav-Formation-v0"


def _rec(seed, success=True, distances=(0.05, 0.05), controller="c", env=TR, map_name="map1", slip="nominal"):
    """An episode record as KoopNav writes it (passes the record schema)."""
    return {
        "key": f"{env}|{controller}|{map_name}|{slip}|{seed}",
        "status": "ok",
        "env_id": env,
        "controller": controller,
        "map": map_name,
        "slip": slip,
        "trial": seed,
        "seed": seed,
        "success": success,
        "collision": None,
        "steps": 100,
        "final_distance": list(distances),
        "final_poses": [[float(seed), 0.0, 0.0]] * len(distances),  # a distinct episode per seed
        "solver_failures": 0,
    }


def _error(seed, controller="c", env=TR, map_name="map1"):
    rec = _rec(seed, controller=controller, env=env, map_name=map_name)
    for field in ("success", "collision", "steps", "final_distance", "solver_failures"):
        del rec[field]
    return {**rec, "status": "error", "error": "RuntimeError: boom"}


def _expected_row(env, controller, run, base):
    """A comparison row computed from the paired records, in the order given."""
    pair = paired_comparison([r["success"] for r in run], [r["success"] for r in base])
    diffs = [
        100 * sum(a["final_distance"]) / len(a["final_distance"])
        - 100 * sum(b["final_distance"]) / len(b["final_distance"])
        for a, b in zip(run, base)
    ]
    low, high = bootstrap_mean_interval(diffs)
    return {
        "env_id": env,
        "controller": controller,
        **pair.to_dict(),
        "distance_cm_difference": pytest.approx(sum(diffs) / len(diffs), abs=1e-12),
        "distance_cm_low": pytest.approx(low, abs=1e-12),
        "distance_cm_high": pytest.approx(high, abs=1e-12),
    }


# ------------------------------------------------------------------------------------ pairing
def test_episodes_pair_by_cell_and_seed_in_sorted_order() -> None:
    # given out of order: the pairs are taken in (map, slip, seed) order, whatever the files' order
    base = [_rec(s, True, (0.01 * s, 0.03)) for s in (3, 0, 2, 1)] + [
        _rec(0, True, (0.2, 0.2), map_name="map0")
    ]
    run = [_rec(s, s != 2, (0.02 * s, 0.01)) for s in (1, 2, 3, 0)] + [
        _rec(0, False, (0.5, 0.1), map_name="map0")
    ]
    comparison = compare_runs(run, base)
    (row,) = comparison["rows"]
    order = lambda records: sorted(records, key=lambda r: (r["map"], r["slip"], r["seed"]))  # noqa: E731
    assert row == _expected_row(TR, "c", order(run), order(base))
    assert (row["n"], row["both_success"], row["only_a"], row["only_b"], row["both_fail"]) == (5, 3, 0, 2, 0)
    # the team's final distance is the mean over its robots, in cm: (0.5 + 0.1) / 2 - 0.2 = +10 cm on map0
    # map1: (s + 0.5) - (0.5 s + 1.5) cm for s = 0..3, i.e. -1, -0.5, 0, +0.5; sum with map0's +10: 9 over 5 pairs
    assert row["distance_cm_difference"] == pytest.approx(1.8, abs=1e-12)
    assert comparison["only_run"] == comparison["only_baseline"] == []


def test_errors_pair_with_nothing_and_one_sided_cells_are_listed() -> None:
    base = [
        _rec(0),
        _rec(1),
        _error(2),
        _rec(0, controller="gone"),
        _rec(0, map_name="map2"),
        _rec(5, slip="high"),
    ]
    run = [
        _rec(0),
        _error(1),
        _rec(2),
        _rec(0, controller="new"),
        _error(0, map_name="map3"),
        _rec(6, slip="high"),
    ]
    comparison = compare_runs(run, base)
    assert [(r["env_id"], r["controller"], r["n"]) for r in comparison["rows"]] == [(TR, "c", 1)]
    assert comparison["only_run"] == [
        [TR, "c", "map1", "high"],
        [TR, "c", "map1", "nominal"],
        [TR, "new", "map1", "nominal"],
    ]
    assert comparison["only_baseline"] == [
        [TR, "c", "map1", "high"],
        [TR, "c", "map1", "nominal"],
        [TR, "c", "map2", "nominal"],
        [TR, "gone", "map1", "nominal"],
    ]


def test_a_controller_without_shared_seeds_gets_no_row_and_the_others_still_do() -> None:
    # "a" sorts first and shares no seed: it is listed on both sides, and "b" after it is compared
    base = [_rec(s, controller="a") for s in range(3)] + [_rec(s, controller="b") for s in range(3)]
    run = [_rec(s, controller="a") for s in range(3, 6)] + [_rec(s, False, controller="b") for s in range(3)]
    comparison = compare_runs(run, base)
    assert [(r["controller"], r["n"], r["only_b"]) for r in comparison["rows"]] == [("b", 3, 3)]
    assert comparison["only_run"] == comparison["only_baseline"] == [[TR, "a", "map1", "nominal"]]


def test_a_controller_on_two_tasks_gets_a_pooled_row_after_the_task_rows() -> None:
    base, run = [], []
    for env in (TR, FO):
        for name in ("b", "a"):
            base += [_rec(s, True, (0.01 * s,), controller=name, env=env) for s in range(4)]
            run += [_rec(s, s % 2 == 0, (0.02,), controller=name, env=env) for s in range(4)]
    base += [_rec(s, controller="solo", env=FO) for s in range(3)]
    run += [_rec(s, False, controller="solo", env=FO) for s in range(3)]
    rows = compare_runs(run, base)["rows"]
    assert [(r["env_id"], r["controller"], r["n"]) for r in rows] == [
        (FO, "a", 4),
        (FO, "b", 4),
        (FO, "solo", 3),
        (TR, "a", 4),
        (TR, "b", 4),
        (ALL_TASKS, "a", 8),
        (ALL_TASKS, "b", 8),
    ]
    pooled_run = [r for env in (FO, TR) for r in run if r["env_id"] == env and r["controller"] == "a"]
    pooled_base = [r for env in (FO, TR) for r in base if r["env_id"] == env and r["controller"] == "a"]
    assert rows[5] == _expected_row(ALL_TASKS, "a", pooled_run, pooled_base)
    assert (rows[5]["only_a"], rows[5]["only_b"]) == (0, 4)


def test_pair_keys_are_the_cells_and_seeds_of_the_episodes_that_ran() -> None:
    records = [
        _rec(0),
        _rec(1, map_name="m2"),
        _error(2),
        _rec(0, controller="d", env=FO, slip="low"),
        _error(0, controller="e"),
    ]
    assert pair_keys(records) == {
        "c": {(TR, "map1", "nominal", 0), (TR, "m2", "nominal", 1)},
        "d": {(FO, "map1", "low", 0)},
    }
    assert pair_keys([]) == {}


# ----------------------------------------------------------------------------------- the gate
def _row(**changes) -> dict:
    row = {
        "env_id": TR,
        "controller": "c",
        "n": 20,
        "rate_a": 0.5,
        "rate_b": 0.8,
        "difference": -0.3,
        "low": -0.5,
        "high": -0.1,
        "only_a": 0,
        "only_b": 6,
        "p_value": 0.03125,
        "distance_cm_difference": 0.0,
        "distance_cm_low": -1.0,
        "distance_cm_high": 1.0,
    }
    return {**row, **changes}


def test_the_gate_message_names_the_rates_the_interval_and_the_p_value() -> None:
    assert gate_failures({"rows": [_row()]}, GateOptions()) == [
        f"c on {TR} (20 paired episodes): success 80% -> 50%, -30 points [-50, -10], McNemar p = 0.0312"
    ]
    farther = _row(difference=0.0, distance_cm_difference=2.5, distance_cm_low=0.25, distance_cm_high=4.75)
    assert gate_failures({"rows": [farther]}, GateOptions()) == [
        f"c on {TR} (20 paired episodes): final distance +2.50 cm [+0.25, +4.75]"
    ]
    # percentages rounded to whole points: 60, 10 and -90 [-97, -70] (a factor of 1.01 would show)
    rounded = [
        _row(rate_b=1.0, rate_a=0.6, difference=-0.4),
        _row(rate_b=1.0, rate_a=0.1, difference=-0.9, low=-0.97, high=-0.7),
    ]
    assert [f.split(": success ")[1] for f in gate_failures({"rows": rounded}, GateOptions())] == [
        "100% -> 60%, -40 points [-50, -10], McNemar p = 0.0312",
        "100% -> 10%, -90 points [-97, -70], McNemar p = 0.0312",
    ]
    both = _row(distance_cm_difference=2.5, distance_cm_low=0.25, distance_cm_high=4.75)
    assert [
        f.split(": ")[1][:7] for f in gate_failures({"rows": [both, _row(controller="d")]}, GateOptions())
    ] == [
        "success",
        "final d",
        "success",
    ]


@pytest.mark.parametrize(
    ("changes", "options", "fails"),
    [
        ({"difference": -0.1}, GateOptions(), False),  # a drop of exactly delta does not fail
        ({"difference": -0.1000001}, GateOptions(), True),
        ({"difference": -0.2}, GateOptions(delta=0.2), False),
        ({"difference": -0.2}, GateOptions(delta=0.19), True),
        ({"p_value": 0.05}, GateOptions(), False),  # p equal to alpha is not significant
        ({"p_value": 0.0499}, GateOptions(), True),
        ({"p_value": 0.01}, GateOptions(alpha=0.01), False),
        ({"p_value": 0.0099}, GateOptions(alpha=0.01), True),
        ({"difference": 0.3}, GateOptions(), False),  # a gain never fails
        ({"difference": -0.3, "p_value": 0.5}, GateOptions(), False),
    ],
)
def test_the_success_threshold_at_its_boundaries(changes, options, fails) -> None:
    assert len(gate_failures({"rows": [_row(**changes)]}, options)) == int(fails)


@pytest.mark.parametrize(
    ("increase", "low", "options", "fails"),
    [
        (1.0, 0.5, GateOptions(), False),  # an increase of exactly delta_cm does not fail
        (1.0001, 0.5, GateOptions(), True),
        (2.0, 0.0, GateOptions(), False),  # an interval touching 0 does not fail
        (2.0, 1e-9, GateOptions(), True),
        (2.0, -0.5, GateOptions(), False),
        (2.0, 0.5, GateOptions(delta_cm=2.0), False),
        (2.0, 0.5, GateOptions(delta_cm=1.99), True),
        (-3.0, 0.5, GateOptions(), False),
    ],
)
def test_the_distance_threshold_at_its_boundaries(increase, low, options, fails) -> None:
    row = _row(
        difference=0.0, distance_cm_difference=increase, distance_cm_low=low, distance_cm_high=increase + 1
    )
    assert len(gate_failures({"rows": [row]}, options)) == int(fails)


def test_the_gate_options_default_to_5_percent_10_points_1_cm_and_10_pairs() -> None:
    options = GateOptions()
    assert (options.alpha, options.delta, options.delta_cm, options.min_pairs) == (0.05, 0.10, 1.0, 10)
    GateOptions(alpha=0.999, delta=0, delta_cm=0, min_pairs=1)  # the smallest settings are allowed
    GateOptions(delta=5, delta_cm=1e6, min_pairs=10**6)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"alpha": 0.0}, "alpha=0.0 must lie in (0, 1)"),
        ({"alpha": 1.0}, "alpha=1.0 must lie in (0, 1)"),
        ({"alpha": -0.5}, "alpha=-0.5 must lie in (0, 1)"),
        ({"alpha": True}, "alpha=True must lie in (0, 1)"),
        ({"alpha": "0.05"}, "alpha='0.05' must lie in (0, 1)"),
        ({"alpha": math.nan}, "alpha=nan must lie in (0, 1)"),
        ({"delta": -0.01}, "delta=-0.01 must be a finite number >= 0"),
        ({"delta": math.inf}, "delta=inf must be a finite number >= 0"),
        ({"delta": math.nan}, "delta=nan must be a finite number >= 0"),
        ({"delta": True}, "delta=True must be a finite number >= 0"),
        ({"delta": "0.1"}, "delta='0.1' must be a finite number >= 0"),
        ({"delta_cm": -1}, "delta_cm=-1 must be a finite number >= 0"),
        ({"delta_cm": math.inf}, "delta_cm=inf must be a finite number >= 0"),
        ({"delta_cm": False}, "delta_cm=False must be a finite number >= 0"),
        ({"delta_cm": None}, "delta_cm=None must be a finite number >= 0"),
        ({"min_pairs": 0}, "min_pairs=0 must be an integer >= 1"),
        ({"min_pairs": 2.0}, "min_pairs=2.0 must be an integer >= 1"),
        ({"min_pairs": True}, "min_pairs=True must be an integer >= 1"),
        ({"min_pairs": "10"}, "min_pairs='10' must be an integer >= 1"),
    ],
)
def test_bad_gate_options_are_refused_with_their_value(kwargs, message) -> None:
    with pytest.raises(ValueError) as caught:
        GateOptions(**kwargs)
    assert str(caught.value) == message


# ------------------------------------------------------------------ why the gate cannot judge
def _keys(seeds, env=TR, map_name="map1", slip="nominal"):
    return {(env, map_name, slip, s) for s in seeds}


def test_a_baseline_without_an_episode_that_ran_is_named_with_its_counts() -> None:
    message = (
        "the baseline has no episode that ran ({} records, {} of them errors): there is nothing to "
        "compare with; rerun it (bash .ci/leaderboard.sh --update)"
    )
    for records, counts in (([], (0, 0)), ([_error(0), _error(1)], (2, 2))):
        assert coverage_failures(
            {"c": _keys(range(10))}, records, GateOptions(), run_names_its_controllers=True
        ) == [message.format(*counts)]


def test_exactly_min_pairs_pass_and_one_fewer_fails() -> None:
    base = [_rec(s) for s in range(12)]
    assert (
        coverage_failures({"c": _keys(range(10))}, base, GateOptions(), run_names_its_controllers=False) == []
    )
    assert coverage_failures(
        {"c": _keys(range(9))}, base, GateOptions(), run_names_its_controllers=False
    ) == [
        "c: 9 episode(s) pair with the baseline, fewer than the minimum 10: this run has only 9 episode(s) "
        "of it; run more per cell (--episodes)"
    ]
    assert (
        coverage_failures(
            {"c": _keys(range(3))}, base, GateOptions(min_pairs=3), run_names_its_controllers=True
        )
        == []
    )


def test_each_reason_for_too_few_pairs_is_named() -> None:
    base = [_rec(s, controller=name) for s in range(10) for name in ("c", "d", "e")]
    base += [_error(s, controller="raised") for s in range(4)]
    run = {
        "c": _keys(range(5, 15)),  # half of its seeds are new
        "d": set(),  # none of its episodes ran
        "raised": _keys(range(10)),  # every baseline episode of it raised
        "fresh": _keys(range(10)),  # not in the baseline at all
        "e": _keys(range(10), map_name="map2") | _keys(range(10, 16)),  # other cells and seeds
    }
    failures = coverage_failures(
        run, base, GateOptions(), run_names_its_controllers=True, run_errors={"d": 10, "c": 0, "fresh": 2}
    )
    assert failures == [
        "c: 5 episode(s) pair with the baseline, fewer than the minimum 10: the baseline ran it with seeds "
        "0-9 on map1/nominal, this run with seeds 5-14 on map1/nominal",
        "d: 0 episode(s) pair with the baseline, fewer than the minimum 10: none of its episodes in this run "
        "ran; 10 of its episodes in this run raised",
        "e: 0 episode(s) pair with the baseline, fewer than the minimum 10: the baseline ran it with seeds "
        "0-9 on map1/nominal, this run with seeds 0-15 on map1/nominal, map2/nominal",
        "fresh: 0 episode(s) pair with the baseline, fewer than the minimum 10: the baseline has no episodes "
        "of 'fresh' (it has ['c', 'd', 'e']); 2 of its episodes in this run raised",
        "raised: 0 episode(s) pair with the baseline, fewer than the minimum 10: all 4 of its baseline "
        "episodes raised",
    ]


def test_the_span_of_seeds_and_cells_is_summarised() -> None:
    base = [_rec(7, map_name=f"m{i}", slip=slip) for i in range(3) for slip in ("a", "b")]
    run = {"c": _keys([7], map_name="other")}
    (failure,) = coverage_failures(run, base, GateOptions(), run_names_its_controllers=True)
    assert failure.endswith(
        ": the baseline ran it with seed 7 on m0/a, m0/b, m1/a, m1/b and 2 more cells, this run with seed 7 "
        "on other/nominal"
    )
    five = [_rec(7 + i, map_name=f"m{i}", slip="a") for i in range(5)]  # 5 cells: 4 named, 1 more
    (failure,) = coverage_failures(run, five, GateOptions(), run_names_its_controllers=True)
    assert failure.endswith(
        ": the baseline ran it with seeds 7-11 on m0/a, m1/a, m2/a, m3/a and 1 more cells, this run with seed 7 "
        "on other/nominal"
    )
    two = [_rec(3, map_name="m0", slip="a"), _rec(9, map_name="m0", slip="a")]  # two seeds: a range
    (failure,) = coverage_failures(run, two, GateOptions(), run_names_its_controllers=True)
    assert failure.endswith(
        ": the baseline ran it with seeds 3-9 on m0/a, this run with seed 7 on other/nominal"
    )
    four = [_rec(7, map_name=f"m{i}", slip="a") for i in range(4)]
    (failure,) = coverage_failures(run, four, GateOptions(), run_names_its_controllers=True)
    assert failure.endswith(
        ": the baseline ran it with seed 7 on m0/a, m1/a, m2/a, m3/a, this run with seed 7 on other/nominal"
    )


def test_controllers_of_the_baseline_missing_from_the_run_fail_unless_the_run_names_its_own() -> None:
    base = [_rec(s, controller=name) for s in range(10) for name in ("c", "z", "y")]
    run = {"c": _keys(range(10))}
    assert coverage_failures(run, base, GateOptions(), run_names_its_controllers=False) == [
        f"the baseline's controller {name!r} is not in this run (not registered, or it could not be built "
        "here); name the controllers to gate with --controllers to leave it out"
        for name in ("y", "z")
    ]
    assert coverage_failures(run, base, GateOptions(), run_names_its_controllers=True) == []


# --------------------------------------------------------- repeated and conflicting episodes
def _copies(seeds, distance):
    """One episode under every seed: the same final poses and distances (exact starts, no slip)."""
    return [{**_rec(s, distances=(distance, distance)), "final_poses": [[0.0, 0.0, 0.0]] * 2} for s in seeds]


def test_ten_copies_of_one_episode_are_one_pair_for_the_minimum_and_for_every_test() -> None:
    """Ten seeds that repeat one episode on both sides are one pair: too few to judge, so the
    distance test does not fail the run on a zero-width interval ([+45, +45] cm) and the
    minimum of pairs names the repeats (issue 59)."""
    run, base = _copies(range(10), 0.5), _copies(range(10), 0.05)
    comparison = compare_runs(run, base)
    (row,) = comparison["rows"]
    assert row["n"] == 1
    assert (row["distance_cm_difference"], row["distance_cm_low"], row["distance_cm_high"]) == (
        45.0,
        45.0,
        45.0,
    )
    assert distinct_pairs(run, base) == {"c": 1}
    assert gate_failures(comparison, GateOptions()) == []  # not judged on one distinct pair
    keys = {"c": _keys(range(10))}
    assert coverage_failures(keys, base, GateOptions(), run_names_its_controllers=True) == []  # as planned
    assert coverage_failures(
        keys, base, GateOptions(), run_names_its_controllers=True, distinct=distinct_pairs(run, base)
    ) == [
        "c: 10 episode(s) pair with the baseline but only 1 of those pairs are distinct, fewer than the "
        "minimum 10: the others repeat an earlier seed's two episodes bit for bit (an identical rerun is "
        "not a sample); make the seeds' episodes differ (--start-noise, a random slip, --random-maps)"
    ]
    # with the minimum at one distinct pair the gate judges it, as it judges any single pair
    assert gate_failures(comparison, GateOptions(min_pairs=1)) == [
        f"c on {TR} (1 paired episodes): final distance +45.00 cm [+45.00, +45.00]"
    ]


def test_the_minimum_counts_distinct_pairs_over_every_task_of_a_controller() -> None:
    """Nine distinct pairs on one task and one pair repeated ten times on the other: ten distinct
    pairs, enough for the default minimum; the controller is judged on every row."""
    run = [_rec(s, distances=(0.5, 0.5)) for s in range(9)] + [
        {**r, "env_id": FO, "key": r["key"].replace(TR, FO)} for r in _copies(range(10), 0.5)
    ]
    base = [_rec(s) for s in range(9)] + [
        {**r, "env_id": FO, "key": r["key"].replace(TR, FO)} for r in _copies(range(10), 0.05)
    ]
    comparison = compare_runs(run, base)
    assert [(r["env_id"], r["n"]) for r in comparison["rows"]] == [(FO, 1), (TR, 9), (ALL_TASKS, 10)]
    assert distinct_pairs(run, base) == {"c": 10}
    assert len(gate_failures(comparison, GateOptions())) == 3  # farther on each task and over both
    assert gate_failures(comparison, GateOptions(min_pairs=11)) == []


def test_a_repeated_record_is_one_episode_on_either_side() -> None:
    base = [_rec(s) for s in range(10)]
    run = [_rec(s, distances=(0.5, 0.5)) for s in range(10)]
    for doubled_run, doubled_base in ((run + run, base), (run, base + base[::-1])):
        comparison = compare_runs(doubled_run, doubled_base)
        assert [r["n"] for r in comparison["rows"]] == [10]
        assert distinct_pairs(doubled_run, doubled_base) == {"c": 10}
    raised = base + [_error(10), _error(10)]  # one episode that raised, recorded twice
    (failure,) = coverage_failures(
        {"c": _keys(range(10)), "d": set()},
        raised + [_error(0, controller="d")] * 2,
        GateOptions(),
        run_names_its_controllers=True,
    )
    assert failure.endswith("all 1 of its baseline episodes raised")


@pytest.mark.parametrize("flipped_last", [True, False])
def test_conflicting_duplicates_are_refused_whatever_their_order(flipped_last) -> None:
    """Each baseline record twice, a success and a failure: refused both ways, naming the
    episode and the field (before, the later record won: one order passed, the other failed)."""
    run = [_rec(s, success=False, distances=(0.5, 0.5)) for s in range(10)]
    won = [_rec(s) for s in range(10)]
    lost = [_rec(s, success=False, distances=(0.5, 0.5)) for s in range(10)]
    base = won + lost if flipped_last else lost + won
    first, then = ("True", "False") if flipped_last else ("False", "True")
    message = (
        rf"^the baseline: episode '{TR}\|c\|map1\|nominal\|0' \(seed 0\) is recorded twice with different "
        rf"outcomes, at record 1 and record 11, which differ in success, final_distance \(success: {first}, "
        rf"then {then}; "
    )
    with pytest.raises(ConflictingRecords, match=message):
        compare_runs(run, base)
    with pytest.raises(ConflictingRecords, match=message):
        coverage_failures({"c": _keys(range(10))}, base, GateOptions(), run_names_its_controllers=True)
    with pytest.raises(ConflictingRecords, match=message.replace("the baseline", "the run")):
        compare_runs(base, run)


# ------------------------------------------------------------------------- reading a baseline
def _document(episodes=None, **changes) -> dict:
    doc = {
        "schema_version": 2,
        "package_version": "0.1.0",
        "config": {"env_settings": {"n_robots": 3}},
        "episodes": [_rec(0), _rec(1)] if episodes is None else episodes,
    }
    return {**doc, **changes}


def _write(path: Path, doc) -> Path:
    path.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return path


def test_a_baseline_is_read_from_its_file_or_its_run_directory(tmp_path) -> None:
    doc = _document()
    _write(tmp_path / "results.json", doc)
    assert load_baseline(tmp_path) == doc
    assert load_baseline(tmp_path / "results.json") == doc
    assert load_baseline(str(tmp_path / "results.json")) == doc


@pytest.mark.parametrize(
    ("content", "problem"),
    [
        ("{not json", "is not JSON (Expecting property name enclosed in double quotes, line 1)"),
        ("[1,\n", "is not JSON (Expecting value, line 2)"),
        ("[1, 2]", "is not a KoopNav results document (no schema_version, config, episodes)"),
        (
            {"schema_version": 2, "config": {}},
            "is not a KoopNav results document (no schema_version, config, episodes)",
        ),
        (_document(schema_version=1), "has schema_version=1; this version reads [2]"),
        (_document(schema_version="2"), "has schema_version='2'; this version reads [2]"),
    ],
)
def test_a_file_that_is_no_results_document_is_named(tmp_path, content, problem) -> None:
    path = _write(tmp_path / "b.json", content)
    with pytest.raises(ValueError) as caught:
        load_baseline(path, what="sweep level")
    assert str(caught.value) == f"sweep level {str(path)!r} {problem}"


def test_a_baseline_is_read_as_utf8_whatever_the_locale(tmp_path) -> None:
    """Under an ASCII locale (LC_ALL=C without UTF-8 mode) a label such as 'régulateur' still reads."""
    import os
    import subprocess
    import sys

    doc = _document([_rec(0, controller="régulateur")])
    path = tmp_path / "b.json"
    path.write_bytes(json.dumps(doc, ensure_ascii=False).encode("utf-8"))
    assert load_baseline(path) == doc  # here, and below in a process whose locale is ASCII
    env = {**os.environ, "LC_ALL": "C", "LANG": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}
    code = (
        "import sys, locale; from evaluation.reports.baseline import load_baseline; "
        "assert locale.getpreferredencoding(False).lower() not in ('utf-8', 'utf8'), locale.getpreferredencoding(False); "
        "doc = load_baseline(sys.argv[1]); "
        "assert doc['episodes'][0]['controller'] == 'r\\u00e9gulateur', ascii(doc['episodes'][0]['controller'])"
    )
    root = Path(__file__).resolve().parents[1]
    done = subprocess.run(
        [sys.executable, "-c", code, str(path)], cwd=root, env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr


def test_a_missing_baseline_is_named_with_the_reason(tmp_path) -> None:
    with pytest.raises(ValueError) as caught:
        load_baseline(tmp_path / "none.json")
    assert (
        str(caught.value)
        == f"baseline {str(tmp_path / 'none.json')!r} cannot be read (No such file or directory)"
    )
    with pytest.raises(ValueError) as caught:
        load_baseline(tmp_path)  # a directory without results.json
    assert (
        str(caught.value)
        == f"baseline {str(tmp_path / 'results.json')!r} cannot be read (No such file or directory)"
    )


@pytest.mark.parametrize(
    ("changes", "problem"),
    [
        ({"config": [1]}, "'config' is a JSON list, not an object"),
        ({"package_version": 1}, "'package_version' is 1, not a version string"),
        ({"package_version": None}, "'package_version' is None, not a version string"),
        ({"episodes": {"a": 1}}, "'episodes' is a JSON dict, not a list of episode records"),
        ({"episodes": [_rec(0), 5]}, "episodes[1]: a JSON int, not an episode record"),
        (
            {"episodes": [_rec(0), {**_rec(1), "steps": -1}]},
            f"episodes[1] ('{TR}|c|map1|nominal|1'): field 'steps' is -1; allowed: an integer >= 0",
        ),
        ({"episodes": [{**_rec(1), "key": 3}]}, "episodes[0]: field 'key' is 3; allowed: a non-empty string"),
    ],
)
def test_a_malformed_document_is_refused_naming_the_field(tmp_path, changes, problem) -> None:
    doc = _document(**changes)
    if "package_version" in changes and changes["package_version"] is None:
        del doc["package_version"]
    path = _write(tmp_path / "b.json", doc)
    with pytest.raises(ValueError) as caught:
        load_baseline(path)
    assert str(caught.value) == (
        f"baseline {str(path)!r} is not a results document as KoopNav writes it: {problem}; nothing was "
        "compared (rerun the baseline, or restore the file from version control)"
    )


def test_a_baseline_reads_each_episode_once_and_refuses_a_conflicting_repeat(tmp_path) -> None:
    path = _write(tmp_path / "b.json", _document([_rec(0), _rec(1), _rec(0), _rec(1)]))
    assert load_baseline(path)["episodes"] == [_rec(0), _rec(1)]
    path = _write(tmp_path / "b.json", _document([_rec(0), _rec(1), {**_rec(1), "success": False}]))
    with pytest.raises(ConflictingRecords) as caught:
        load_baseline(path, what="sweep level")
    assert str(caught.value) == (
        f"sweep level {str(path)!r}: episode '{TR}|c|map1|nominal|1' (seed 1) is recorded twice with "
        "different outcomes, at episodes[1] and episodes[2], which differ in success (success: True, then "
        "False); which one is true cannot be told, so neither is read (remove the wrong record, or run the "
        "episode again)"
    )


def test_a_baseline_of_other_outcome_settings_is_refused_naming_each() -> None:
    config = {
        "env_settings": {"n_robots": 3, "goal_tolerance": 0.1},
        "calibration": None,
        "map_files": ["a.json"],
        "random_maps": None,
        "episodes": 8,
    }
    same = {
        "config": {**config, "env_settings": {"goal_tolerance": 0.1, "n_robots": 3}, "episodes": 2},
        "package_version": "1.0",
    }
    refuse_incomparable(config, "1.0", same)  # key order and settings that change no outcome do not count
    other = {
        "config": {**config, "env_settings": {"n_robots": 4}, "map_files": ["b.json"]},
        "package_version": "0.9",
    }
    with pytest.raises(ValueError) as caught:
        refuse_incomparable(config, "1.0", other)
    assert str(caught.value) == (
        "the baseline was run with other settings (env_settings: baseline {'n_robots': 4}, now "
        "{'n_robots': 3, 'goal_tolerance': 0.1}; map_files: baseline ['b.json'], now ['a.json']; "
        "package_version: baseline '0.9', now '1.0'); its episodes cannot be paired with these"
    )
    missing = {
        "config": {k: v for k, v in config.items() if k != "calibration"} | {"random_maps": {"count": 2}},
        "package_version": "1.0",
    }
    with pytest.raises(ValueError) as caught:
        refuse_incomparable(config, "1.0", missing)
    assert str(caught.value) == (
        "the baseline was run with other settings (random_maps: baseline {'count': 2}, now None); its "
        "episodes cannot be paired with these"
    )
    # values JSON cannot hold are compared as text
    refuse_incomparable(
        {"calibration": Path("x")}, "1.0", {"config": {"calibration": "x"}, "package_version": "1.0"}
    )


# ------------------------------------------------------------------------------- the Markdown
def test_the_comparison_section_to_the_character() -> None:
    comparison = {
        "rows": [
            _row(
                controller="a|b",
                p_value=0.0009999,
                distance_cm_difference=1.234,
                distance_cm_low=-0.5,
                distance_cm_high=2.0,
            ),
            _row(
                env_id=FO,
                controller="d",
                rate_a=0.25,
                rate_b=0.25,
                difference=0.0,
                low=-0.125,
                high=0.125,
                only_a=1,
                only_b=1,
                p_value=1.0,
            ),
            _row(env_id=ALL_TASKS, p_value=0.001),
            _row(rate_b=1.0, rate_a=0.6, difference=-0.9, low=-0.97, high=-0.7, p_value=0.5),
        ],
        "only_run": [[TR, "new", "map1", "nominal"]],
        "only_baseline": [[FO, "old<x>", "map2", "high"], [TR, "gone", "map1", "low"]],
    }
    assert comparison_markdown(comparison, "main <branch>").split("\n") == [
        "## Compared with the baseline (main &lt;branch>)",
        "",
        "Run minus baseline on the episodes both ran (same env, controller, map, slip and seed): success with "
        "Newcombe's 95% interval and the exact McNemar p-value; team final distance with a 95% bootstrap interval.",
        "",
        "| Task | Controller | Pairs | Success baseline | Success run | Run - baseline [95% CI] | only run / only "
        "baseline | McNemar p | Final distance, run - baseline [cm] |",
        "|---|---|---|---|---|---|---|---|---|",
        "| target reaching | a\\|b | 20 | 80% | 50% | -30 [-50, -10] | 0 / 6 | <0.001 | +1.23 [-0.50, +2.00] |",
        "| formation | d | 20 | 25% | 25% | +0 [-12, +12] | 1 / 1 | 1.000 | +0.00 [-1.00, +1.00] |",
        "| all tasks | c | 20 | 80% | 50% | -30 [-50, -10] | 0 / 6 | 0.001 | +0.00 [-1.00, +1.00] |",
        "| target reaching | c | 20 | 100% | 60% | -90 [-97, -70] | 0 / 6 | 0.500 | +0.00 [-1.00, +1.00] |",
        "",
        "Cells in this run only (not compared): new map1 nominal (KoopNav-TargetReaching-v0)",
        "",
        "Cells in the baseline only (not compared): old&lt;x> map2 high (KoopNav-Formation-v0), gone map1 low "
        "(KoopNav-TargetReaching-v0)",
    ]


def test_a_comparison_without_one_sided_cells_ends_with_its_table() -> None:
    text = comparison_markdown({"rows": [], "only_run": [], "only_baseline": []}, "b")
    assert text.split("\n")[0] == "## Compared with the baseline (b)"
    assert text.endswith("|---|---|---|---|---|---|---|---|---|")


def test_last_digit_differences_are_ties_so_one_episode_ending_elsewhere_is_no_significant_increase() -> None:
    """Seen on an Intel machine against a baseline recorded on an AMD one: 19 of 20 formation
    episodes of dmpc-koopman-robust ended where they had, their final distances 1e-12 to 1e-5 cm
    larger (another BLAS kernel's rounding), and one ended 34 cm off. Counted as evidence, the
    crumbs put the bootstrap interval above 0 and the gate failed the run (+1.72 cm [+0.00,
    +5.17]); they are ties below DISTANCE_RESOLUTION_CM, so the interval touches 0."""
    baseline = [_rec(seed, distances=(0.05, 0.05)) for seed in range(20)]
    run = [_rec(seed, distances=(0.05 + 1e-9 * (seed + 1), 0.05)) for seed in range(20)]
    run[7] = _rec(7, success=False, distances=(0.73, 0.05))  # 34 cm further, one episode
    row = next(r for r in compare_runs(run, baseline)["rows"] if r["env_id"] == TR)
    assert row["distance_cm_difference"] == pytest.approx(34.0 / 20, rel=1e-6)
    assert row["distance_cm_low"] == 0.0  # every resample without that episode: exact ties
    assert gate_failures(compare_runs(run, baseline), GateOptions()) == []
    # a shift of 0.2 cm in every episode is no crumb: the same run is judged worse then
    shifted = [_rec(seed, distances=(0.052, 0.052)) for seed in range(20)]
    shifted[7] = run[7]
    assert gate_failures(compare_runs(shifted, baseline), GateOptions()) != []


# ------------------------------------------------- what the mutation run of this module showed
# (bash .ci/mutation.sh baseline: each test below kills mutants that survived the tests above)
def test_a_distance_difference_of_exactly_the_resolution_is_no_tie() -> None:
    from evaluation.reports.baseline import DISTANCE_RESOLUTION_CM, _tied

    assert _tied(DISTANCE_RESOLUTION_CM) == DISTANCE_RESOLUTION_CM
    assert _tied(-DISTANCE_RESOLUTION_CM) == -DISTANCE_RESOLUTION_CM
    assert _tied(0.999 * DISTANCE_RESOLUTION_CM) == 0.0
    assert _tied(-0.999 * DISTANCE_RESOLUTION_CM) == 0.0


def test_a_published_archive_as_the_baseline_is_named_with_how_to_use_it(tmp_path) -> None:
    archive = tmp_path / "scale_n3.tar.xz"
    archive.write_bytes(b"\xfd7zXZ\x00")  # named by its suffix, refused before it is read
    with pytest.raises(ValueError) as caught:
        load_baseline(archive)
    assert str(caught.value) == (
        f"baseline {str(archive)!r} is a published archive (episode logs), not a results.json or a run "
        f"directory: unpack it (tar -xJf {archive} -C DIR), write its run's results.json with the run's "
        "command and --resume --out DIR/NAME (data/publish.sh lists it; every episode is logged, so "
        "none runs again), then pass DIR/NAME"
    )


def test_a_baseline_nested_too_deep_is_named_by_its_file(tmp_path) -> None:
    path = _write(tmp_path / "deep.json", "[" * 100 + "]" * 100)
    with pytest.raises(ValueError) as caught:
        load_baseline(path)
    assert str(caught.value) == f"baseline {str(path)!r}: JSON nested 100 levels deep; allowed: at most 64"


def test_settings_that_are_not_json_compare_by_their_text() -> None:
    # a run's configuration may hold paths (map files given on the command line); the baseline's,
    # read back from JSON, holds their text: the same file is the same setting
    config = {"env_settings": {"n_robots": 3}, "map_files": [Path("maps/a.json")]}
    baseline = {
        "config": {"env_settings": {"n_robots": 3}, "map_files": ["maps/a.json"]},
        "package_version": "1",
    }
    refuse_incomparable(config, "1", baseline)
    # and either side may be built in memory (two runs compared in one Python session)
    refuse_incomparable(baseline["config"], "1", {"config": config, "package_version": "1"})
    with pytest.raises(ValueError, match=r"map_files: baseline \['maps/b.json'\], now \[PosixPath"):
        refuse_incomparable(
            config, "1", {**baseline, "config": {**baseline["config"], "map_files": ["maps/b.json"]}}
        )


@pytest.mark.parametrize("side", ["the run", "the baseline"])
def test_distinct_pairs_names_the_side_holding_a_conflicting_repeat(side) -> None:
    clean = [_rec(s) for s in range(3)]
    torn = clean + [_rec(0, success=False, distances=(0.5, 0.5))]
    records, baseline_records = (torn, clean) if side == "the run" else (clean, torn)
    with pytest.raises(ConflictingRecords, match=rf"^{side}: episode '{TR}\|c\|map1\|nominal\|0'"):
        distinct_pairs(records, baseline_records)


def test_a_controller_without_distinct_pairs_counted_has_none() -> None:
    # distinct pairs counted after the run for other controllers only: this one has 0, not 1
    base = [_rec(s) for s in range(10)]
    failures = coverage_failures(
        {"c": _keys(range(10))},
        base,
        GateOptions(min_pairs=1),
        run_names_its_controllers=True,
        distinct={"d": 10},
    )
    assert failures == [
        "c: 10 episode(s) pair with the baseline but only 0 of those pairs are distinct, fewer than the "
        "minimum 1: the others repeat an earlier seed's two episodes bit for bit (an identical rerun is "
        "not a sample); make the seeds' episodes differ (--start-noise, a random slip, --random-maps)"
    ]


def test_a_controller_too_thin_to_judge_does_not_stop_the_gate_judging_the_next() -> None:
    thin = _row(controller="a", n=3)
    worse = _row(controller="b")
    assert gate_failures({"rows": [thin, worse]}, GateOptions()) == [
        f"b on {TR} (20 paired episodes): success 80% -> 50%, -30 points [-50, -10], McNemar p = 0.0312"
    ]
