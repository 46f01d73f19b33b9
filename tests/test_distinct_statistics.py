"""Verdicts a reviewer accepts: identical episodes count once, clustered outcomes widen the
interval, a table of many tests is corrected (evaluation/episodes/distinct.py, evaluation/stats/statistics.py,
evaluation/stats/aggregate.py)."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from evaluation.episodes.distinct import distinct_records, distinct_units, duplicates
from evaluation.stats.aggregate import aggregate, leaderboard, paired_comparisons
from evaluation.stats.statistics import (
    cluster_bootstrap_rate,
    holm_adjusted,
    paired_comparison,
    wilson_interval,
)

from helpers.records import episode_record


def test_identical_episodes_are_counted_once() -> None:
    """Ten trials of exact starts at nominal slip: one episode, ten times. The cell, the
    leaderboard and the paired test each count it once; a real difference counts again."""
    records = [episode_record("a", s, True, 1.0) for s in range(10)]  # one episode, ten times
    records += [episode_record("b", s, s < 5, 2.0 + (s < 5)) for s in range(10)]  # two distinct episodes
    assert duplicates(records) == 9 + 8
    assert len(distinct_records(records)) == 1 + 2
    cells = {c.controller: c for c in aggregate(records)}
    assert (cells["a"].episodes, cells["a"].valid, cells["a"].duplicates) == (10, 1, 9)
    assert (cells["b"].valid, cells["b"].successes) == (2, 1)
    rows = {r["controller"]: r for r in leaderboard(list(cells.values()), records)}
    assert rows["a"]["episodes"] == 1 and rows["a"]["episodes_run"] == 10
    # Wilson over 1 episode, not over 10
    assert rows["a"]["success_ci"][0] <= wilson_interval(1, 1)[0] < wilson_interval(10, 10)[0]
    (pair,) = paired_comparisons(records)
    assert pair["n"] == 2  # (a's episode, b's success) and (a's episode, b's failure)
    assert (pair["only_a"], pair["only_b"]) == (1, 0)


def test_distinct_units_keep_a_seed_whose_episodes_differ_on_either_side() -> None:
    a = {(m, s): episode_record("a", s, True, 1.0, m) for m in ("map1", "map2") for s in range(3)}
    b = {(m, s): episode_record("b", s, True, 1.0 + s, m) for m in ("map1", "map2") for s in range(3)}
    keys = sorted(a)
    assert distinct_units(keys, a, b) == keys  # b differs on every seed: every unit is distinct
    assert distinct_units(keys, a, a) == [("map1", 0), ("map2", 0)]  # one per cell


def test_holm_against_hand_computed_values() -> None:
    # m = 4: sorted 0.01, 0.02, 0.03, 0.5 -> 0.04, 0.06, 0.06 (monotone), 0.5
    assert holm_adjusted([0.03, 0.5, 0.01, 0.02]) == pytest.approx([0.06, 0.5, 0.04, 0.06])
    assert holm_adjusted([0.2, 0.9]) == pytest.approx([0.4, 0.9])
    assert holm_adjusted([0.6, 0.7]) == pytest.approx([1.0, 1.0])  # capped at 1
    adjusted = holm_adjusted([math.nan, 0.01])
    assert math.isnan(adjusted[0]) and adjusted[1] == pytest.approx(0.01)  # NaN is not a test
    assert holm_adjusted([]) == []


def test_holm_counts_a_test_on_the_same_data_once() -> None:
    # the second and third tests are one (same identity): m = 2, not 3
    assert holm_adjusted([0.01, 0.02, 0.02], same=["x", "y", "y"]) == pytest.approx([0.02, 0.02, 0.02])
    assert holm_adjusted([0.01, 0.02, 0.02]) == pytest.approx([0.03, 0.04, 0.04])
    with pytest.raises(ValueError, match="same names 1 tests, p_values 2"):
        holm_adjusted([0.1, 0.2], same=["x"])


def test_a_bit_identical_twin_adds_no_test_to_the_paired_family() -> None:
    records = []
    for name, rate in (("a", 0.9), ("b", 0.5), ("c", 0.2)):
        records += [episode_record(name, s, s < rate * 20, s + ord(name)) for s in range(20)]
    # c's twin: every episode bit for bit c's (a -robust variant at nominal slip)
    records += [{**r, "controller": "c-twin"} for r in records if r["controller"] == "c"]
    rows = {(r["a"], r["b"]): r for r in paired_comparisons(records)}
    assert len(rows) == 6
    without = {
        (r["a"], r["b"]): r for r in paired_comparisons([r for r in records if r["controller"] != "c-twin"])
    }
    # a-c and a-c-twin, b-c and b-c-twin are two tests; c-c-twin (no discordant pair) is the fourth
    assert rows[("a", "c-twin")]["p_holm"] == rows[("a", "c")]["p_holm"]
    assert rows[("c", "c-twin")]["p_value"] == 1.0
    distinct_p = [without[k]["p_value"] for k in without] + [1.0]
    expected = dict(zip([*without, ("c", "c-twin")], holm_adjusted(distinct_p), strict=True))
    for key in without:
        assert rows[key]["p_holm"] == pytest.approx(expected[key])


def test_the_paired_table_carries_holm_and_the_probability_of_improvement() -> None:
    records = []
    for name, rate in (("a", 0.9), ("b", 0.5), ("c", 0.2)):
        records += [episode_record(name, s, s < rate * 20, s + ord(name)) for s in range(20)]
    rows = paired_comparisons(records)
    assert len(rows) == 3
    raw = [r["p_value"] for r in rows]
    for row, expected in zip(rows, holm_adjusted(raw), strict=True):
        assert row["p_holm"] == expected >= row["p_value"]
    ab = next(r for r in rows if (r["a"], r["b"]) == ("a", "b"))
    # a succeeds on seeds 0-17, b on 0-9: a better on 8 of 20, ties on 12
    assert ab["prob_improvement"] == pytest.approx((8 + 0.5 * 12) / 20)
    assert ab == {
        **ab,
        **paired_comparison([s < 18 for s in range(20)], [s < 10 for s in range(20)]).to_dict(),
    }


def test_the_cluster_bootstrap_covers_a_clustered_rate() -> None:
    """Clusters of 8 episodes sharing a cluster-level success probability (Beta(1.2, 0.8),
    mean 0.6, an intraclass correlation of 0.5): over 300 samples of 30 clusters the cluster
    bootstrap's 95% interval covers 0.6 in close to 95% of them; Wilson over the pooled episodes,
    which takes them as independent, in far fewer."""
    rng = np.random.default_rng(7)
    covered = wilson_covered = 0
    draws = 300
    for i in range(draws):
        probabilities = rng.beta(1.2, 0.8, size=30)
        clusters = [rng.random(8) < p for p in probabilities]
        _, low, high = cluster_bootstrap_rate(clusters, n_boot=1000, seed=i)
        covered += low <= 0.6 <= high
        pooled = np.concatenate(clusters)
        w_low, w_high = wilson_interval(int(pooled.sum()), pooled.size)
        wilson_covered += w_low <= 0.6 <= w_high
    assert 0.90 <= covered / draws <= 0.99, covered / draws
    assert wilson_covered / draws < 0.85, wilson_covered / draws


def test_the_cluster_bootstrap_names_bad_input() -> None:
    rate, low, high = cluster_bootstrap_rate([])
    assert math.isnan(rate) and math.isnan(low) and math.isnan(high)
    with pytest.raises(ValueError, match=r"clusters\[0\]\[1\]=2 is not allowed"):
        cluster_bootstrap_rate([[True, 2]])
    with pytest.raises(ValueError, match=r"confidence=1.5"):
        cluster_bootstrap_rate([[True]], confidence=1.5)


def test_a_record_without_final_poses_is_judged_by_its_distances() -> None:
    one = episode_record("a", 0, True, 1.0)
    other = copy.deepcopy(one)
    del one["final_poses"], other["final_poses"]
    other["seed"] = 1
    assert duplicates([one, other]) == 1
    other["final_distance"] = [0.02]
    assert duplicates([one, other]) == 0


def test_a_controller_that_never_moves_does_not_outrank_one_that_tries() -> None:
    """Both fail every episode; the one that ends closer ranks first (the settled distance, NaN
    for both, cannot tell them apart), whatever order they come in."""
    still = [{**episode_record("still", s, False, 10.0 + s), "final_distance": [5.0]} for s in range(4)]
    tries = [{**episode_record("tries", s, False, 20.0 + s), "final_distance": [1.0]} for s in range(4)]
    for records in (still + tries, tries + still):
        rows = leaderboard(aggregate(records), records)
        assert [r["controller"] for r in rows] == ["tries", "still"]
        assert rows[0]["final_distance_all_cm"] == pytest.approx(100.0)


# ------------------------------------------------- what the mutation run of statistics.py showed
# (bash .ci/mutation.sh statistics: each test below kills mutants that survived the tests above)
CLUSTERS = [[True, True, False], [False], [True, True], [False, False, True, True], [True]]
#: 40 layouts of 1-4 episodes: enough distinct replicate rates that a changed seed or count moves a bound
MANY = [[(7 * i + 3 * j) % 5 < 2 + i % 3 for j in range(1 + i % 4)] for i in range(40)]


def test_no_successes_give_a_lower_wilson_bound_of_exactly_zero() -> None:
    # (centre - spread) / denominator is a rounding crumb (4.9e-17 at n = 3), not 0
    for n in (3, 6, 7, 12, 14, 50):
        assert wilson_interval(0, n)[0] == 0.0


def test_the_cluster_bootstrap_rate_is_the_one_stage_layout_interval_with_its_defaults() -> None:
    from evaluation.stats.clustered import layout_rate_interval

    assert cluster_bootstrap_rate(CLUSTERS)[0] == 7 / 11  # successes over episodes, each weighs the same
    rate, low, high = cluster_bootstrap_rate(MANY)
    assert rate == 59 / 100
    assert (rate, low, high) == cluster_bootstrap_rate(MANY, confidence=0.95, n_boot=4000, seed=0)
    assert (rate, low, high) == layout_rate_interval(MANY, 0.95, 4000, 0, resample="layouts")
    assert (rate, low, high) == cluster_bootstrap_rate(MANY)  # a function of its arguments
    assert cluster_bootstrap_rate(MANY, seed=1) != (rate, low, high)
    assert cluster_bootstrap_rate(MANY, n_boot=4001) != (rate, low, high)
    narrow = cluster_bootstrap_rate(MANY, confidence=0.5)
    assert narrow == layout_rate_interval(MANY, 0.5, 4000, 0, resample="layouts")
    assert low < narrow[1] <= narrow[2] < high


def test_the_cluster_bootstrap_rate_names_a_bad_count_or_seed() -> None:
    assert not math.isnan(cluster_bootstrap_rate(CLUSTERS, n_boot=1)[1])
    with pytest.raises(ValueError, match="^n_boot=0 must be an integer >= 1$"):
        cluster_bootstrap_rate(CLUSTERS, n_boot=0)
    with pytest.raises(ValueError, match="^seed=-1 must be an integer >= 0$"):
        cluster_bootstrap_rate(CLUSTERS, seed=-1)


def test_every_bootstrap_replicate_is_the_rate_of_its_drawn_layouts() -> None:
    import evaluation.stats.statistics as statistics

    table = statistics._layout_table("clusters", MANY, binary=True)
    replicates = statistics._replicates(table, statistics._ratio, "layouts", 50, np.random.default_rng(3))
    picks = np.random.default_rng(3).integers(0, len(MANY), size=(50, len(MANY)))
    successes, sizes = table[0].sum(axis=1), table[1]
    expected = successes[picks].sum(axis=1) / sizes[picks].sum(axis=1)
    np.testing.assert_allclose(replicates, expected, rtol=1e-12, atol=0)


def test_bootstrap_replicates_do_not_depend_on_the_chunk_size(monkeypatch) -> None:
    # the replicates are drawn in chunks of at most _BOOTSTRAP_CHUNK entries to bound memory; the
    # chunks must neither overlap, skip a replicate nor change the draws
    import evaluation.stats.statistics as statistics
    from evaluation.stats.clustered import layout_rate_interval

    whole = [layout_rate_interval(CLUSTERS, n_boot=50, resample=scheme) for scheme in ("layouts", "within")]
    whole.append(cluster_bootstrap_rate(CLUSTERS, n_boot=50))
    monkeypatch.setattr(statistics, "_BOOTSTRAP_CHUNK", 5 * 4 * 3)  # 3 replicates of 5 x 4 per chunk
    chunked = [layout_rate_interval(CLUSTERS, n_boot=50, resample=scheme) for scheme in ("layouts", "within")]
    chunked.append(cluster_bootstrap_rate(CLUSTERS, n_boot=50))
    assert chunked == whole
