"""evaluation.stats.statistics to the bit where tests/test_statistics.py checks to a tolerance (issue 41,
mutation testing): the bootstraps replayed from the very indices they drew (so the resampled
statistic, the quantiles, the chunking and the memory bound are all checked exactly), the
documented defaults, the tail mean by hand, and the outcome and message checks.

Each bootstrap runs with its generator wrapped (``numpy.random.default_rng`` as the module sees
it): the wrapper passes every ``integers`` call through unchanged and keeps the index arrays, from
which the test recomputes the interval independently.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import evaluation.stats.statistics as st
from evaluation.stats.statistics import (
    bootstrap_mean_interval,
    bootstrap_tail_interval,
    paired_comparison,
    tail_mean,
    wilson_interval,
)


class _Recording:
    """A numpy Generator that keeps the index arrays ``integers`` returns."""

    def __init__(self, seed: int, log: list[dict]) -> None:
        self._rng = np.random.Generator(np.random.PCG64(seed))
        self._log = log
        log.append({"seed": seed, "calls": []})

    def integers(self, *args, **kwargs):
        out = self._rng.integers(*args, **kwargs)
        self._log[-1]["calls"].append(out.copy())
        return out


@pytest.fixture
def generators(monkeypatch: pytest.MonkeyPatch) -> list[dict]:
    """Every generator the statistics module makes, with the indices it drew."""
    log: list[dict] = []

    class _Random:
        @staticmethod
        def default_rng(seed: int) -> _Recording:
            return _Recording(seed, log)

    class _Numpy:  # the module's numpy, with only default_rng replaced
        random = _Random

        def __getattr__(self, name: str):
            return getattr(np, name)

    monkeypatch.setattr(st, "np", _Numpy())
    return log


def _quantiles(stat: np.ndarray, confidence: float) -> tuple[float, float]:
    tail = (1.0 - confidence) / 2.0
    return float(np.quantile(stat, tail)), float(np.quantile(stat, 1.0 - tail))


# ------------------------------------------------------------------------- bootstrap of the mean
VALUES = [0.5, 2.0, 3.25, 7.0, 11.0]  # odd n: a split of the draws changes the generator's stream


@pytest.mark.parametrize("confidence", [0.95, 0.5, 0.9])
def test_the_mean_bootstrap_is_the_quantiles_of_the_resampled_means(generators, confidence) -> None:
    got = bootstrap_mean_interval(VALUES, confidence=confidence, resamples=301, seed=4)
    (gen,) = generators
    assert gen["seed"] == 4
    idx = np.concatenate(gen["calls"])
    assert idx.shape == (301, 5) and idx.min() == 0 and idx.max() == 4  # every value is drawn
    means = np.asarray(VALUES)[idx].mean(axis=1)
    assert got == _quantiles(means, confidence)
    assert all(isinstance(v, float) for v in got)


def test_the_mean_bootstrap_defaults_are_10000_resamples_seed_0_and_95_percent(generators) -> None:
    got = bootstrap_mean_interval(VALUES)
    (gen,) = generators
    idx = np.concatenate(gen["calls"])
    assert gen["seed"] == 0 and idx.shape == (10_000, 5)
    assert got == _quantiles(np.asarray(VALUES)[idx].mean(axis=1), 0.95)


@pytest.mark.parametrize(("chunk", "rows"), [(1, 1), (4, 1), (12, 2), (15, 3), (1 << 20, 7)])
def test_the_mean_bootstrap_draws_at_most_a_chunk_of_indices_at_once(
    generators, monkeypatch: pytest.MonkeyPatch, chunk: int, rows: int
) -> None:
    # rows per draw = max(1, chunk // n): with n = 5 values, a chunk of 12 indices is 2 resamples
    monkeypatch.setattr(st, "_BOOTSTRAP_CHUNK", chunk)
    got = bootstrap_mean_interval(VALUES, resamples=7, seed=3)
    calls = generators[0]["calls"]
    assert [c.shape for c in calls] == [(min(rows, 7 - start), 5) for start in range(0, 7, rows)]
    assert got == _quantiles(np.asarray(VALUES)[np.concatenate(calls)].mean(axis=1), 0.95)


def test_a_chunked_bootstrap_of_an_even_sample_equals_the_unchunked_one(monkeypatch) -> None:
    # numpy draws bounded integers of an even count as one stream however they are split, so
    # the chunk size leaves the result of an even sample unchanged (an odd one is not: above)
    values = [0.5, 2.0, 3.25, 7.0, 11.0, 13.5]
    whole = bootstrap_mean_interval(values, resamples=501, seed=9)
    monkeypatch.setattr(st, "_BOOTSTRAP_CHUNK", 1)
    assert bootstrap_mean_interval(values, resamples=501, seed=9) == whole


# ---------------------------------------------------------------------------------- tail mean
@pytest.mark.parametrize(
    ("values", "share", "expected"),
    [
        ([4.0, 1.0, 3.0, 2.0, 10.0, 6.0, 5.0, 9.0, 8.0, 7.0], 0.25, 9.0),  # ceil(2.5) = 3: 8, 9, 10
        ([4.0, 1.0, 3.0, 2.0, 10.0, 6.0, 5.0, 9.0, 8.0, 7.0], 0.1, 10.0),  # one value
        ([4.0, 1.0, 3.0, 2.0, 10.0, 6.0, 5.0, 9.0, 8.0, 7.0], 0.11, 9.5),  # ceil(1.1) = 2
        ([4.0, 1.0, 3.0, 2.0, 10.0, 6.0, 5.0, 9.0, 8.0, 7.0], 1.0, 5.5),  # all of them
        ([2.0, 0.0], 0.5, 2.0),
    ],
)
def test_the_tail_mean_by_hand(values, share, expected) -> None:
    assert tail_mean(values, share) == expected
    assert tail_mean(iter(values), share) == expected


def test_the_tail_mean_default_share_is_a_tenth() -> None:
    assert tail_mean(range(1, 21)) == 19.5  # 19 and 20
    assert tail_mean([5.0] * 3 + [1.0]) == 5.0  # ceil(0.4) = 1


# --------------------------------------------------------------------------- bootstrap of a tail
TAILS = [0.1, 0.9, 0.4, 2.5, 0.3, 1.7, 0.2]


@pytest.mark.parametrize(("share", "top", "confidence"), [(0.3, 3, 0.95), (0.5, 4, 0.8), (0.1, 1, 0.9)])
def test_the_tail_bootstrap_is_the_quantiles_of_the_resampled_tails(
    generators, share, top, confidence
) -> None:
    got = bootstrap_tail_interval(TAILS, share, confidence=confidence, resamples=257, seed=6)
    (gen,) = generators
    idx = np.concatenate(gen["calls"])
    assert gen["seed"] == 6 and idx.shape == (257, 7) and idx.min() == 0 and idx.max() == 6
    tails = [np.sort(np.asarray(TAILS)[row])[-top:].mean() for row in idx]  # the worst `top` values
    assert got == _quantiles(np.asarray(tails), confidence)


def test_the_tail_bootstrap_defaults(generators) -> None:
    got = bootstrap_tail_interval(TAILS)  # share 0.1 (the worst value of 7), 95%, 2000, seed 0
    (gen,) = generators
    idx = np.concatenate(gen["calls"])
    assert gen["seed"] == 0 and idx.shape == (2000, 7)
    assert got == _quantiles(np.asarray(TAILS)[idx].max(axis=1), 0.95)


@pytest.mark.parametrize(("chunk", "rows"), [(1, 1), (14, 2), (20, 2), (1 << 20, 5)])
def test_the_tail_bootstrap_draws_at_most_a_chunk_of_indices_at_once(
    generators, monkeypatch: pytest.MonkeyPatch, chunk: int, rows: int
) -> None:
    monkeypatch.setattr(st, "_BOOTSTRAP_CHUNK", chunk)
    got = bootstrap_tail_interval(TAILS, 0.3, resamples=5, seed=2)
    calls = generators[0]["calls"]
    assert [c.shape for c in calls] == [(min(rows, 5 - start), 7) for start in range(0, 5, rows)]
    tails = [np.sort(np.asarray(TAILS)[row])[-3:].mean() for row in np.concatenate(calls)]
    assert got == _quantiles(np.asarray(tails), 0.95)


def test_the_tail_bootstrap_refuses_what_it_cannot_resample() -> None:
    with pytest.raises(ValueError, match=r"^values must be finite numbers$"):
        bootstrap_tail_interval([1.0, math.inf])
    with pytest.raises(ValueError, match=r"^values must be finite numbers$"):
        bootstrap_tail_interval([1.0, math.nan, 2.0])
    with pytest.raises(ValueError, match=r"^confidence=1\.5 must be a number with 0 < confidence < 1$"):
        bootstrap_tail_interval([1.0, 2.0], confidence=1.5)
    low, high = bootstrap_tail_interval(np.array([]))
    assert math.isnan(low) and math.isnan(high)


# ----------------------------------------------------------------------- outcomes and messages
def test_integer_arrays_are_checked_value_by_value() -> None:
    # a numpy array that is not boolean goes through the 0/1 check (only bool arrays skip it)
    with pytest.raises(
        ValueError,
        match=r"^a\[1\]=(np\.int64\()?2\)? is not allowed; outcomes must be True/False \(or 0/1\)$",
    ):
        paired_comparison(np.array([1, 2, 0]), [True, False, False])
    with pytest.raises(ValueError, match=r"^b\[0\]=(np\.float64\()?0\.5\)? is not allowed"):
        paired_comparison([True], np.array([0.5]))
    as_ints = paired_comparison(np.array([1, 1, 0, 0]), np.array([1, 0, 1, 0]))
    as_bools = paired_comparison([True, True, False, False], [True, False, True, False])
    assert as_ints == as_bools and (as_ints.both_success, as_ints.only_a, as_ints.only_b) == (1, 1, 1)


def test_the_refusals_say_exactly_what_is_wrong() -> None:
    with pytest.raises(
        ValueError, match=r"^a and b are empty \(n=0\); a paired comparison needs at least one pair$"
    ):
        paired_comparison([], [])
    with pytest.raises(
        ValueError, match=r"^a and b must pair up index by index; got len\(a\)=2 and len\(b\)=1$"
    ):
        paired_comparison([True, False], [True])
    with pytest.raises(
        ValueError, match=r"^successes=3 is not allowed; it must satisfy 0 <= successes <= n=2$"
    ):
        wilson_interval(3, 2)
    with pytest.raises(ValueError, match=r"^values must be one-dimensional; got shape \(1, 2\)$"):
        bootstrap_mean_interval([[1.0, 2.0]])
    with pytest.raises(
        ValueError, match=r"^values\[1\]=inf is not allowed; every value must be a finite number$"
    ):
        bootstrap_mean_interval([1.0, math.inf])


def test_a_single_discordant_pair_has_p_value_one() -> None:
    # 2 P(X <= 0) with X ~ Bin(1, 1/2) = 1; no discordant pair: 1 as well
    assert paired_comparison([True], [False]).p_value == 1.0
    assert paired_comparison([True, False], [True, False]).p_value == 1.0
    # two discordant pairs one way: 2 * (1/4) = 0.5; three: 2 * (1/8) = 0.25
    assert paired_comparison([True, True], [False, False]).p_value == 0.5
    assert paired_comparison([False] * 3, [True] * 3).p_value == 0.25
