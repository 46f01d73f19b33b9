"""The lidar's reading noise and dropouts (koopman_envs.sim.perception._perceive) are what
LidarConfig documents, measured against the exact ranges of a twin env without them:

* a hit (exact range < range) reads exact + N(0, noise^2), each reading independent of the
  others (over beams and over periods);
* a dropout reads ``range`` exactly, with probability ``dropout`` per beam and period;
* a miss (exact range = range) reads ``range`` exactly: it carries no noise;
* every reading is clipped into [0, range].

The robots turn on the spot (no slip, so the twins' true poses are equal bit for bit) and their
beams sweep obstacles, walls and team-mates at 1.3-5 m. Every test is seeded, so it is
deterministic; the acceptance bounds are 4 standard deviations wide (about one false alarm in
16,000 seeds), and each test fails when the feature it checks is made a no-op (see the
mutations named in each docstring).
"""

from __future__ import annotations

import functools
import math

import gymnasium as gym
import numpy as np
from scipy import stats

import koopman_envs  # noqa: F401 - registers the ids

TR = "KoopNav-TargetReaching-v0"
BEAMS, RANGE = 32, 4.0
STEPS = 3000
#: acceptance half-width in standard deviations
Z = 4.0


@functools.cache
def _readings(noise: float, dropout: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(readings, exact) of STEPS + 1 periods, each shape (T, N, B): an env with the lidar's
    ``noise`` and ``dropout`` and its twin without them, both turning on the spot."""
    lidar = {"beams": BEAMS, "range": RANGE}
    noisy = gym.make(
        TR, sensing="lidar", lidar={**lidar, "noise": noise, "dropout": dropout}, max_episode_steps=STEPS + 1
    )
    exact = gym.make(TR, sensing="lidar", lidar=lidar, max_episode_steps=STEPS + 1)
    _, a = noisy.reset(seed=seed)
    _, b = exact.reset(seed=seed)
    readings, truth = [a["lidar_ranges"]], [b["lidar_ranges"]]
    turn = np.tile([0.0, 0.4], 3)
    for _ in range(STEPS):
        *_, a = noisy.step(turn)
        *_, b = exact.step(turn)
        assert np.array_equal(a["poses"], b["poses"])  # the twins stand at the same true poses
        readings.append(a["lidar_ranges"])
        truth.append(b["lidar_ranges"])
    return np.array(readings), np.array(truth)


def _binomial_ok(count: int, trials: int, p: float) -> bool:
    mean, sd = trials * p, math.sqrt(trials * p * (1 - p))
    return abs(count - mean) <= Z * sd


def test_the_exact_ranges_have_hits_and_misses() -> None:
    """The scene the other tests rely on: many hits far from both clipping bounds, many misses."""
    _, exact = _readings(0.05, 0.0)
    assert exact.min() > 1.0  # no robot is inside anything
    hits = exact < RANGE
    assert 0.1 < hits.mean() < 0.5
    assert (hits & (exact < RANGE - 0.5)).sum() > 40_000 and (~hits).sum() > 100_000


def test_range_noise_on_hits_is_gaussian_with_the_configured_std() -> None:
    """Standardized errors of the hits (away from the clipping bounds) are N(0, 1): mean, sum of
    squares (chi-square), the shape (binned chi-square goodness of fit and Kolmogorov-Smirnov).
    Fails when the noise is a no-op (every error 0) or has another scale."""
    sigma = 0.05
    readings, exact = _readings(sigma, 0.0)
    inside = (exact > 6 * sigma) & (exact < RANGE - 6 * sigma)
    z = (readings[inside] - exact[inside]) / sigma
    n = z.size
    assert n > 40_000
    assert abs(z.mean()) < Z / math.sqrt(n)
    assert abs((z**2).sum() - n) < Z * math.sqrt(2 * n)  # chi-square with n degrees of freedom
    # the shape: 20 equiprobable bins of N(0, 1)
    edges = stats.norm.ppf(np.linspace(0, 1, 21))
    observed, _ = np.histogram(z, bins=edges)
    chi2 = ((observed - n / 20) ** 2 / (n / 20)).sum()
    assert chi2 < stats.chi2.ppf(1 - 1e-4, 19), chi2
    assert stats.kstest(z, "norm").pvalue > 1e-4


def test_range_noise_is_independent_across_beams_and_periods() -> None:
    """Adjacent beams of a scan, and one beam in consecutive periods, draw independent errors
    (sample correlations within 4 / sqrt(n) of 0). Fails when one normal serves every beam of a
    period, or one period's numbers are reused for the next."""
    sigma = 0.05
    readings, exact = _readings(sigma, 0.0)
    inside = (exact > 6 * sigma) & (exact < RANGE - 6 * sigma)
    z = np.where(inside, (readings - exact) / sigma, np.nan)
    for a, b in ((z[:, :, :-1], z[:, :, 1:]), (z[:-1], z[1:])):
        both = ~np.isnan(a) & ~np.isnan(b)
        r = np.corrcoef(a[both], b[both])[0, 1]
        assert both.sum() > 10_000 and abs(r) < Z / math.sqrt(both.sum()), r


def test_misses_carry_no_noise() -> None:
    """A beam that meets nothing reads the range exactly, noise or not (fails when the noise is
    added before the miss check: about half the misses then read less than the range)."""
    readings, exact = _readings(0.05, 0.0)
    misses = exact == RANGE
    assert misses.sum() > 100_000
    assert (readings[misses] == RANGE).all()
    # and a hit never reads exactly the range without dropouts (well inside it)
    hits = exact < RANGE - 0.5
    assert not (readings[hits] == RANGE).any()


def test_dropout_frequency_within_a_binomial_bound_and_the_rest_exact() -> None:
    """Without noise a reading is its exact range or, with probability ``dropout``, the range:
    the count of dropped hits is within 4 sigma of the binomial mean. Fails when dropouts are a
    no-op (none) or read anything but the range (0, say)."""
    p = 0.1
    readings, exact = _readings(0.0, p)
    hits = exact < RANGE
    dropped = hits & (readings == RANGE)
    kept = hits & ~dropped
    assert np.array_equal(readings[kept], exact[kept])  # not dropped: exact, bit for bit
    assert (readings[~hits] == RANGE).all()
    assert _binomial_ok(int(dropped.sum()), int(hits.sum()), p), (dropped.sum(), hits.sum())
    # independent per beam: two adjacent hits drop together with probability p^2
    pairs = hits[:, :, :-1] & hits[:, :, 1:]
    together = (dropped[:, :, :-1] & dropped[:, :, 1:])[pairs].sum()
    assert _binomial_ok(int(together), int(pairs.sum()), p * p), (together, pairs.sum())


def test_a_dropped_hit_reads_the_range_without_noise() -> None:
    """With noise and dropouts together: a hit well inside the range reads exactly the range
    only when dropped (binomial count), and the others carry N(0, noise^2) errors."""
    sigma, p = 0.05, 0.2
    readings, exact = _readings(sigma, p)
    hits = exact < RANGE - 6 * sigma
    dropped = hits & (readings == RANGE)
    assert _binomial_ok(int(dropped.sum()), int(hits.sum()), p)
    rest = hits & ~dropped & (exact > 6 * sigma)
    z = (readings[rest] - exact[rest]) / sigma
    assert abs((z**2).sum() - z.size) < Z * math.sqrt(2 * z.size)


def test_readings_are_clipped_to_zero_and_the_range() -> None:
    """With noise as large as the ranges every reading stays in [0, range], and the readings
    clipped to 0 and to the range are as many as the normal law puts past each bound (a sum of
    independent Bernoulli counts: within 4 sigma of the sum of the probabilities). Fails without
    the clipping, and when a bound is applied as anything but a clip (a reflection, a redraw)."""
    sigma = 1.5
    readings, exact = _readings(sigma, 0.0)
    assert readings.min() >= 0.0 and readings.max() <= RANGE
    hits = exact < RANGE
    x = exact[hits]
    r = readings[hits]
    for count, p in (
        ((r == 0.0).sum(), stats.norm.cdf(-x / sigma)),
        ((r == RANGE).sum(), stats.norm.sf((RANGE - x) / sigma)),
    ):
        mean, sd = p.sum(), math.sqrt((p * (1 - p)).sum())
        assert mean > 500 and abs(count - mean) < Z * sd, (count, mean, sd)
    # in between, the readings are the unclipped exact + noise: their distribution function is
    # the normal's, truncated (the standardized errors are uniform under the normal law)
    between = (r > 0.0) & (r < RANGE)
    low, high = stats.norm.cdf(-x[between] / sigma), stats.norm.cdf((RANGE - x[between]) / sigma)
    u = (stats.norm.cdf((r[between] - x[between]) / sigma) - low) / (high - low)
    assert stats.kstest(u, "uniform").pvalue > 1e-4


def test_the_noise_is_seeded() -> None:
    """Another seed draws other noise, the same seed the same (so the tests above are deterministic)."""
    one, _ = _readings(0.05, 0.2)
    again, _ = _readings.__wrapped__(0.05, 0.2)
    other, _ = _readings(0.05, 0.2, 1)
    assert np.array_equal(one, again) and not np.array_equal(one[1:], other[1:])
