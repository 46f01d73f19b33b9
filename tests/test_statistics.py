"""evaluation.stats.statistics against published and independently computed reference values.

Sources of the hard-coded numbers:

- Wilson intervals: ``scipy.stats.binomtest(k, n).proportion_ci(method="wilson")`` (scipy 1.17,
  run offline; scipy is not needed to run these tests). 15/148, 0/20 and 1/29 are also
  Newcombe's published single-proportion examples (Statist. Med. 1998; 17: 857-872, method 3).
- Paired differences (Newcombe 1998, Statist. Med. 17: 2635-2650, "method 10"): the published
  examples quoted in the test suites of the R packages ratesci (tests/testthat/test3.R) and
  contingencytables (tests/testthat/test-ch8.R): Newcombe's own example (method 10 result),
  Fagerland, Lydersen & Laake (2014) / Bentur et al. (2009), Cavo et al. (2012) from Fagerland,
  Lydersen & Laake, "Statistical Analysis of Contingency Tables" (2017), Tang, Ling & Tian (2010),
  and Chang et al. (2024). Edge cases are cross-checked against a scalar re-implementation
  written here straight from the formulas.
- Exact McNemar p-values: by hand from binomial coefficients, the Cavo et al. value 0.052479
  published by Fagerland et al., and ``scipy.stats.binomtest(min(b, c), b + c).pvalue`` offline.
"""

from __future__ import annotations

import itertools
import json
import math
import warnings

import numpy as np
import pytest

import evaluation.stats.statistics as st
from evaluation.stats.statistics import (
    PairedComparison,
    bootstrap_mean_interval,
    paired_comparison,
    wilson_interval,
)


def _pairs(both: int, only_a: int, only_b: int, neither: int) -> tuple[list[bool], list[bool]]:
    """Outcome vectors with the given 2x2 table (a's and b's result per seed)."""
    a = [True] * both + [True] * only_a + [False] * only_b + [False] * neither
    b = [True] * both + [False] * only_a + [True] * only_b + [False] * neither
    return a, b


# ---------------------------------------------------------------------------------------- Wilson

WILSON_95 = [
    # successes, n, low, high   (scipy binomtest(...).proportion_ci(method="wilson"))
    (8, 10, 0.4901624715, 0.9433178485),
    (0, 10, 0.0, 0.2775327999),
    (10, 10, 0.7224672001, 1.0),
    (1, 1, 0.2065493144, 1.0),
    (0, 1, 0.0, 0.7934506856),
    (5, 10, 0.2365930905, 0.7634069095),
    (81, 263, 0.2552885199, 0.3662095770),
    # Newcombe (1998a) published to 4 decimals: 0.0624-0.1605, 0-0.1611, 0.0061-0.1718
    (15, 148, 0.0623863995, 0.1604872417),
    (0, 20, 0.0, 0.1611251581),
    (1, 29, 0.0061132143, 0.1717552188),
]


@pytest.mark.parametrize(("k", "n", "low", "high"), WILSON_95)
def test_wilson_matches_reference_values(k: int, n: int, low: float, high: float) -> None:
    got = wilson_interval(k, n)
    assert got == pytest.approx((low, high), abs=1e-9)
    assert isinstance(got[0], float) and isinstance(got[1], float)


@pytest.mark.parametrize(
    ("confidence", "low", "high"), [(0.90, 0.2633136172, 0.3565663496), (0.99, 0.2401369027, 0.3852825023)]
)
def test_wilson_other_confidence_levels(confidence: float, low: float, high: float) -> None:
    assert wilson_interval(81, 263, confidence) == pytest.approx((low, high), abs=1e-9)


def test_wilson_bounds_are_exact_at_zero_and_all_successes() -> None:
    assert wilson_interval(0, 7)[0] == 0.0
    assert wilson_interval(7, 7)[1] == 1.0
    for k in range(8):  # mirror symmetry: interval of k/n is 1 minus that of (n-k)/n
        low, high = wilson_interval(k, 7)
        mirror_low, mirror_high = wilson_interval(7 - k, 7)
        assert (low, high) == pytest.approx((1 - mirror_high, 1 - mirror_low), abs=1e-15)


def test_wilson_accepts_numpy_integers_and_returns_nan_for_no_trials() -> None:
    assert wilson_interval(np.int64(8), np.int32(10)) == pytest.approx((0.4901624715, 0.9433178485), abs=1e-9)
    low, high = wilson_interval(0, 0)
    assert math.isnan(low) and math.isnan(high)


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((11, 10), r"successes=11 .* 0 <= successes <= n=10"),
        ((-1, 10), r"successes=-1 .* integer >= 0"),
        ((1, -3), r"n=-3 .* integer >= 0"),
        ((8.0, 10), r"successes=8\.0 .* integer"),
        ((8, 10.5), r"n=10\.5 .* integer"),
        ((True, 1), r"successes=True .* integer"),
        ((1, 0), r"successes=1 .* n=0"),
        ((8, 10, 1.0), r"confidence=1\.0 .* 0 < confidence < 1"),
        ((8, 10, 0), r"confidence=0 .* 0 < confidence < 1"),
        ((8, 10, 95), r"confidence=95 .* 0 < confidence < 1"),
        ((8, 10, "0.95"), r"confidence='0\.95' .* 0 < confidence < 1"),
    ],
)
def test_wilson_rejects_bad_input(args: tuple, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        wilson_interval(*args)


# ----------------------------------------------------------------------------- exact McNemar

MCNEMAR = [
    # only_a, only_b, p
    (1, 8, 2 * (1 + 9) / 2**9),  # = 0.0390625 by hand
    (8, 1, 0.0390625),
    (8, 0, 2 / 2**8),  # = 0.0078125
    (1, 7, 2 * (1 + 8) / 2**8),  # = 0.0703125, Bentur et al. (2009) data
    (6, 16, 0.052478790283203125),  # Cavo et al. (2012); Fagerland et al. publish P = 0.052479
    (12, 2, 0.012939453125),  # scipy binomtest(2, 14)
    (10, 25, 0.016673847800120715),  # scipy binomtest(10, 35)
    (0, 30, 2 / 2**30),  # 1.862645149230957e-09
    (40, 60, 0.05688793364098089),  # scipy binomtest(40, 100)
    (5, 5, 1.0),
    (3, 4, 1.0),  # 2 P(X <= 3) > 1, capped
    (0, 1, 1.0),
    (0, 0, 1.0),  # no discordant pairs
]


@pytest.mark.parametrize(("only_a", "only_b", "p"), MCNEMAR)
def test_exact_mcnemar_p_value(only_a: int, only_b: int, p: float) -> None:
    result = paired_comparison(*_pairs(3, only_a, only_b, 2))
    assert (result.only_a, result.only_b) == (only_a, only_b)
    assert result.p_value == pytest.approx(p, rel=1e-12)


def test_mcnemar_hand_value_of_the_brief() -> None:
    assert paired_comparison(*_pairs(0, 1, 8, 0)).p_value == 0.0390625


# ------------------------------------------------------------------ Newcombe method 10 (paired)

NEWCOMBE_PUBLISHED = [
    # (both, only_a, only_b, neither), (low, high), decimals published
    ((20, 12, 2, 16), (0.0562, 0.3292), 4),  # Newcombe (1998), his method 10 result
    ((1, 1, 7, 12), (-0.507, -0.026), 3),  # Fagerland et al. (2014), Bentur et al. data
    ((59, 6, 16, 80), (-0.1186, -0.0046), 4),  # Fagerland et al. (2017), Cavo et al. data
    ((8, 3, 1, 2), (-0.1574, 0.4136), 4),  # Tang, Ling & Tian (2010)
    ((7, 25, 2, 68), (0.133, 0.318), 3),  # Chang et al. (2024)
    ((1, 0, 0, 1), (-0.5734, 0.5734), 4),  # contingencytables: ad - bc = n/2, phi = 0
]


@pytest.mark.parametrize(("table", "interval", "decimals"), NEWCOMBE_PUBLISHED)
def test_newcombe_matches_published_examples(table: tuple, interval: tuple, decimals: int) -> None:
    result = paired_comparison(*_pairs(*table))
    n = sum(table)
    assert (result.n, result.both_success, result.only_a, result.only_b, result.both_fail) == (n, *table)
    assert result.rate_a == pytest.approx((table[0] + table[1]) / n)
    assert result.rate_b == pytest.approx((table[0] + table[2]) / n)
    assert result.difference == pytest.approx(result.rate_a - result.rate_b, abs=1e-15)
    assert (round(result.low, decimals), round(result.high, decimals)) == interval


def test_newcombe_full_precision_for_the_cavo_example() -> None:
    # independent scalar computation (below), agreeing with the published -0.1186 to -0.0046
    result = paired_comparison(*_pairs(59, 6, 16, 80))
    assert (result.low, result.high) == pytest.approx((-0.11862119563871, -0.00462511393305), abs=1e-12)
    assert result.difference == pytest.approx(-10 / 161, abs=1e-15)
    assert result.p_value == pytest.approx(0.052478790283203125, rel=1e-12)


def _wilson_reference(k: int, n: int, z: float) -> tuple[float, float]:
    """Wilson's interval in the textbook (centre +- half-width) form."""
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def _method10_reference(e: int, f: int, g: int, h: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Newcombe (1998) method 10 for the table [[e, f], [g, h]], straight from the paper."""
    n = e + f + g + h
    p1, p2 = (e + f) / n, (e + g) / n
    l1, u1 = _wilson_reference(e + f, n, z)
    l2, u2 = _wilson_reference(e + g, n, z)
    if (e + f) * (g + h) * (e + g) * (f + h) == 0:
        phi = 0.0
    else:
        big_b = e * h - f * g
        if big_b > n / 2:
            big_c = big_b - n / 2
        elif big_b >= 0:
            big_c = 0.0
        else:
            big_c = big_b
        phi = big_c / math.sqrt((e + f) * (g + h) * (e + g) * (f + h))
    delta = p1 - p2
    lower = delta - math.sqrt(max(0.0, (p1 - l1) ** 2 - 2 * phi * (p1 - l1) * (u2 - p2) + (u2 - p2) ** 2))
    upper = delta + math.sqrt(max(0.0, (p2 - l2) ** 2 - 2 * phi * (p2 - l2) * (u1 - p1) + (u1 - p1) ** 2))
    return lower, upper


def _tables(max_n: int):
    for n in range(1, max_n + 1):
        for e, f, g in itertools.product(range(n + 1), repeat=3):
            if e + f + g <= n:
                yield e, f, g, n - e - f - g


def test_newcombe_agrees_with_scalar_reference_on_every_small_table_without_warnings() -> None:
    # all 209 tables with 1 <= n <= 6 (zero margins, all-concordant, all-discordant, n = 1, ...)
    # plus a few larger ones; numpy/Python warnings are errors here
    tables = list(_tables(6)) + [
        (36, 12, 2, 0),
        (0, 12, 2, 36),
        (0, 50, 0, 0),
        (50, 0, 0, 0),
        (0, 0, 0, 50),
        (0, 0, 50, 0),
        (25, 0, 0, 25),
        (0, 25, 25, 0),
        (400, 13, 2, 585),
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for table in tables:
            result = paired_comparison(*_pairs(*table))
            expected = _method10_reference(*table)
            assert (result.low, result.high) == pytest.approx(expected, abs=1e-12), table
            assert -1.0 <= result.low <= result.difference <= result.high <= 1.0, table
            assert not (math.isnan(result.low) or math.isnan(result.high)), table


@pytest.mark.parametrize(
    ("table", "interval"),
    [
        # scalar reference values for degenerate margins, hand-checkable from the Wilson limits
        ((1, 0, 0, 0), (-0.7934506856, 0.7934506856)),  # n = 1, both succeed: +- (1 - 0.2065...)
        ((0, 0, 0, 1), (-0.7934506856, 0.7934506856)),  # n = 1, both fail
        ((0, 1, 0, 0), (1 - math.sqrt(2) * 0.7934506856, 1.0)),  # n = 1, only a
        ((0, 0, 1, 0), (-1.0, math.sqrt(2) * 0.7934506856 - 1)),  # n = 1, only b
        # all concordant: ad - bc = 25 > n/2, phi = (25 - 5) / sqrt(5**4) = 0.8, so the half-width is
        # (0.5 - 0.2365930905) * sqrt(2 - 2 * 0.8), with 0.2365930905 the Wilson lower limit of 5/10
        ((5, 0, 0, 5), (-(0.5 - 0.2365930905) * math.sqrt(0.4), (0.5 - 0.2365930905) * math.sqrt(0.4))),
    ],
)
def test_newcombe_degenerate_tables(table: tuple, interval: tuple) -> None:
    result = paired_comparison(*_pairs(*table))
    assert (result.low, result.high) == pytest.approx(_method10_reference(*table), abs=1e-12)
    assert (result.low, result.high) == pytest.approx(interval, abs=1e-4)


def test_paired_comparison_is_antisymmetric_and_order_free() -> None:
    a, b = _pairs(20, 12, 2, 16)
    ab, ba = paired_comparison(a, b), paired_comparison(b, a)
    assert (ba.difference, ba.low, ba.high) == pytest.approx((-ab.difference, -ab.high, -ab.low), abs=1e-15)
    assert (ba.only_a, ba.only_b, ba.p_value) == (ab.only_b, ab.only_a, ab.p_value)
    order = np.random.default_rng(3).permutation(len(a))
    shuffled = paired_comparison([a[i] for i in order], [b[i] for i in order])
    assert shuffled == ab


def test_paired_comparison_confidence_level() -> None:
    a, b = _pairs(20, 12, 2, 16)
    narrow, wide = paired_comparison(a, b, 0.80), paired_comparison(a, b, 0.99)
    middle = paired_comparison(a, b)
    assert wide.low < middle.low < narrow.low < 0.2 < narrow.high < middle.high < wide.high
    assert (narrow.low, narrow.high) == pytest.approx(
        _method10_reference(20, 12, 2, 16, z=1.2815515655446004), abs=1e-12
    )


def test_paired_comparison_accepts_numpy_and_integer_outcomes() -> None:
    a, b = _pairs(20, 12, 2, 16)
    expected = paired_comparison(a, b)
    assert paired_comparison(np.array(a), np.array(b)) == expected
    assert paired_comparison(np.array(a, dtype=int), [float(x) for x in b]) == expected
    assert paired_comparison([np.bool_(x) for x in a], (int(x) for x in b)) == expected


def test_to_dict_is_plain_json() -> None:
    result = paired_comparison(np.array([True, True, False, True]), np.array([True, False, False, False]))
    d = result.to_dict()
    assert list(d) == [
        "n",
        "rate_a",
        "rate_b",
        "difference",
        "low",
        "high",
        "both_success",
        "only_a",
        "only_b",
        "both_fail",
        "p_value",
    ]
    assert {k: type(v) for k, v in d.items()} == {
        "n": int,
        "rate_a": float,
        "rate_b": float,
        "difference": float,
        "low": float,
        "high": float,
        "both_success": int,
        "only_a": int,
        "only_b": int,
        "both_fail": int,
        "p_value": float,
    }
    assert json.loads(json.dumps(d)) == d
    assert (d["n"], d["both_success"], d["only_a"], d["only_b"], d["both_fail"]) == (4, 1, 2, 0, 1)
    assert d["p_value"] == 0.5  # 2 * P(X <= 0), X ~ Bin(2, 1/2)
    assert PairedComparison(**d) == result
    nan = PairedComparison(0, math.nan, math.nan, math.nan, math.nan, math.nan, 0, 0, 0, 0, 1.0).to_dict()
    assert isinstance(nan["low"], float) and math.isnan(nan["low"])


def test_paired_comparison_is_frozen() -> None:
    result = paired_comparison([True], [False])
    with pytest.raises(AttributeError):
        result.low = 0.0  # type: ignore[misc]


@pytest.mark.parametrize(
    ("a", "b", "kwargs", "match"),
    [
        ([True, False, True], [True, False], {}, r"len\(a\)=3 and len\(b\)=2"),
        ([], [], {}, r"n=0"),
        ([True, 2], [True, False], {}, r"a\[1\]=2 .* True/False"),
        ([True, False], [0.5, 1], {}, r"b\[0\]=0\.5 .* True/False"),
        ([True, "yes"], [True, False], {}, r"a\[1\]='yes' .* True/False"),
        ([True, None], [True, False], {}, r"a\[1\]=None .* True/False"),
        ([True, False], [True, math.nan], {}, r"b\[1\]=nan .* True/False"),
        (np.ones((2, 2), bool), [True, False], {}, r"a must be one-dimensional; got shape \(2, 2\)"),
        ([True], [False], {"confidence": 1.5}, r"confidence=1\.5 .* 0 < confidence < 1"),
    ],
)
def test_paired_comparison_rejects_bad_input(a, b, kwargs, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        paired_comparison(a, b, **kwargs)


# ------------------------------------------------------------------------------------ bootstrap


def test_bootstrap_is_deterministic_for_a_seed() -> None:
    values = np.random.default_rng(7).exponential(size=60)
    first = bootstrap_mean_interval(values, resamples=2000, seed=11)
    assert bootstrap_mean_interval(list(values), resamples=2000, seed=11) == first
    assert bootstrap_mean_interval(values, resamples=2000, seed=12) != first
    low, high = first
    assert isinstance(low, float) and isinstance(high, float)
    assert values.min() < low < values.mean() < high < values.max()


def test_bootstrap_constant_single_and_empty() -> None:
    assert bootstrap_mean_interval([0.1] * 7) == (0.1, 0.1)
    assert bootstrap_mean_interval(np.full(500, -3.25)) == (-3.25, -3.25)
    assert bootstrap_mean_interval([42.0]) == (42.0, 42.0)
    assert bootstrap_mean_interval(iter([5])) == (5.0, 5.0)
    low, high = bootstrap_mean_interval([])
    assert math.isnan(low) and math.isnan(high)


def test_bootstrap_two_point_sample_has_known_quantiles() -> None:
    # resampled means of [0, 1] are 0, 1/2, 1 with probabilities 1/4, 1/2, 1/4: the 2.5% and
    # 97.5% quantiles are 0 and 1
    assert bootstrap_mean_interval([0.0, 1.0]) == (0.0, 1.0)
    # 40%: the 30% and 70% quantiles are both 1/2
    assert bootstrap_mean_interval([0.0, 1.0], confidence=0.40) == (0.5, 0.5)


def test_bootstrap_large_sample_matches_the_normal_interval() -> None:
    values = np.random.default_rng(2024).normal(10.0, 2.0, size=2000)
    half = 1.959963984540054 * values.std(ddof=1) / math.sqrt(values.size)
    low, high = bootstrap_mean_interval(values)
    # Monte Carlo error of a 2.5% quantile from 10 000 resamples is ~3% of `half`
    assert low == pytest.approx(values.mean() - half, abs=0.1 * half)
    assert high == pytest.approx(values.mean() + half, abs=0.1 * half)


def test_bootstrap_chunking_covers_every_resample(monkeypatch: pytest.MonkeyPatch) -> None:
    values = np.random.default_rng(5).normal(size=50)
    reference = bootstrap_mean_interval(values, resamples=3001)
    monkeypatch.setattr(st, "_BOOTSTRAP_CHUNK", 7 * 50 + 3)  # 7 rows a chunk, 3001 % 7 != 0
    chunked = bootstrap_mean_interval(values, resamples=3001)
    se = values.std(ddof=1) / math.sqrt(values.size)
    assert chunked == pytest.approx(reference, abs=0.15 * se)
    monkeypatch.setattr(st, "_BOOTSTRAP_CHUNK", 1)  # one resample a chunk
    low, high = bootstrap_mean_interval(values, resamples=5)
    assert values.min() < low <= high < values.max()


@pytest.mark.parametrize(
    ("values", "kwargs", "match"),
    [
        ([1.0, 2.0, math.nan], {}, r"values\[2\]=nan .* finite"),
        ([1.0, math.inf], {}, r"values\[1\]=inf .* finite"),
        (np.array([-np.inf, 1.0]), {}, r"values\[0\]=-inf .* finite"),
        ([1.0, None], {}, r"values\[1\]=None .* finite"),
        (["a", 1.0], {}, r"finite numbers"),
        ([[1.0, 2.0], [3.0, 4.0]], {}, r"one-dimensional; got shape \(2, 2\)"),
        ([1.0, 2.0], {"resamples": 0}, r"resamples=0 .* integer >= 1"),
        ([1.0, 2.0], {"resamples": 100.0}, r"resamples=100\.0 .* integer"),
        ([1.0, 2.0], {"seed": -1}, r"seed=-1 .* integer >= 0"),
        ([1.0, 2.0], {"confidence": 0.0}, r"confidence=0\.0 .* 0 < confidence < 1"),
    ],
)
def test_bootstrap_rejects_bad_input(values, kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        bootstrap_mean_interval(values, **kwargs)
