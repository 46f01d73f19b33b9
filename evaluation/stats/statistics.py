"""Interval estimates and tests for the evaluator: numpy and the standard library only.

- :func:`wilson_interval`: Wilson score interval of a binomial proportion (success rates).
- :func:`bootstrap_mean_interval`: percentile bootstrap interval of a mean (final distances).
- :func:`paired_comparison`: two controllers on the same seeds: difference in success rate with
  Newcombe's (1998) paired interval ("method 10") and the exact McNemar p-value.
- :func:`holm_adjusted`: Holm's (1979) step-down adjustment of a family of p-values, for tables
  that hold many tests (it controls the family-wise error rate under any dependence between
  the tests, which paired tests on shared seeds have).

- :func:`cluster_bootstrap_rate`: a success rate over clustered episodes (those sharing a
  trial's seed) with a bootstrap that resamples whole clusters; its tables of clusters and its
  resampler are the ones :mod:`evaluation.stats.clustered` draws with.

Statistics with a suite's layouts as the unit (two-stage intervals) are in
:mod:`evaluation.stats.clustered`, paired tests over layouts in :mod:`evaluation.stats.layout_tests`, named
families of tests and power statements in :mod:`evaluation.stats.families`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Iterable
from dataclasses import asdict, dataclass
from numbers import Integral, Real
from statistics import NormalDist
from typing import Any

import numpy as np
from numpy.typing import NDArray

from koopman_envs.checks import check_int

__all__ = [
    "PairedComparison",
    "cluster_bootstrap_rate",
    "holm_adjusted",
    "bootstrap_mean_interval",
    "bootstrap_tail_interval",
    "paired_comparison",
    "tail_mean",
    "wilson_interval",
]

#: Upper bound on the number of indices drawn at once by :func:`bootstrap_mean_interval`
#: (2**20 int64 indices = 8 MiB, plus as many gathered float64 values).
_BOOTSTRAP_CHUNK = 1 << 20


def _check_confidence(confidence: float, name: str = "confidence") -> float:
    """A level strictly within (0, 1) (a confidence, an alpha), or ``ValueError`` naming it."""
    if isinstance(confidence, bool) or not isinstance(confidence, Real) or not 0.0 < confidence < 1.0:
        raise ValueError(f"{name}={confidence!r} must be a number with 0 < {name} < 1")
    return float(confidence)


def _z(confidence: float) -> float:
    """Two-sided standard normal quantile: P(|Z| <= z) = confidence."""
    return NormalDist().inv_cdf(0.5 + confidence / 2.0)


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval for a binomial proportion (no continuity correction).

    Parameters
    ----------
    successes : int
        Number of successes, ``0 <= successes <= n``.
    n : int
        Number of trials, ``n >= 0``.
    confidence : float, optional
        Two-sided confidence level, ``0 < confidence < 1`` (default 0.95).

    Returns
    -------
    (low, high) : tuple of float
        Bounds within [0, 1]; ``low`` is exactly 0 when ``successes == 0`` and ``high`` exactly 1
        when ``successes == n``. ``(nan, nan)`` when ``n == 0``.

    Raises
    ------
    ValueError
        If ``successes`` or ``n`` is not an integer (bools are refused), if not
        ``0 <= successes <= n``, or if ``confidence`` is outside (0, 1).

    References
    ----------
    Wilson, E.B. (1927). Probable inference, the law of succession, and statistical inference.
    J. Amer. Statist. Assoc. 22, 209-212.
    """
    confidence = _check_confidence(confidence)
    n = check_int("n", n, 0)
    successes = check_int("successes", successes, 0)
    if successes > n:
        raise ValueError(f"successes={successes} is not allowed; it must satisfy 0 <= successes <= n={n}")
    if n == 0:
        return (math.nan, math.nan)
    z = _z(confidence)
    z2 = z * z
    # (2k + z^2 -+ z sqrt(z^2 + 4k(n-k)/n)) / (2(n + z^2)): the usual form, free of cancellation.
    centre = 2.0 * successes + z2
    spread = z * math.sqrt(z2 + 4.0 * successes * (n - successes) / n)
    denominator = 2.0 * (n + z2)
    low = 0.0 if successes == 0 else max(0.0, (centre - spread) / denominator)
    high = 1.0 if successes == n else min(1.0, (centre + spread) / denominator)
    return (low, high)


def _as_finite(name: str, values: Iterable[Any]) -> NDArray[np.float64]:
    """``values`` as a one-dimensional float array, or ``ValueError`` naming the first entry that
    is not a finite number (``name[i]=value``) or the shape."""
    items = values if isinstance(values, np.ndarray) else list(values)
    try:
        x = np.asarray(items, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be finite numbers; could not convert them to float ({exc})") from None
    if x.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional; got shape {x.shape}")
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        i = int(bad[0])
        shown = float(x[i]) if isinstance(items, np.ndarray) else items[i]
        raise ValueError(f"{name}[{i}]={shown!r} is not allowed; every value must be a finite number")
    return x


def bootstrap_mean_interval(
    values: Iterable[float],
    confidence: float = 0.95,
    resamples: int = 10_000,
    seed: int = 0,
) -> tuple[float, float]:
    """Percentile bootstrap interval of the mean.

    Draws ``resamples`` samples with replacement (``numpy.random.default_rng(seed)``), takes the
    mean of each and returns its ``(1 - confidence) / 2`` and ``(1 + confidence) / 2`` quantiles
    (numpy's default linear interpolation). Indices are drawn in chunks of at most 2**20, so the
    memory stays a few MiB whatever ``resamples`` is. The result is a deterministic function of
    ``(values, confidence, resamples, seed)``.

    Parameters
    ----------
    values : iterable of float
        The sample, one-dimensional; every value must be finite.
    confidence : float, optional
        Two-sided confidence level, ``0 < confidence < 1`` (default 0.95).
    resamples : int, optional
        Number of bootstrap samples, ``>= 1`` (default 10 000).
    seed : int, optional
        Seed of the generator, ``>= 0`` (default 0).

    Returns
    -------
    (low, high) : tuple of float
        ``(nan, nan)`` for an empty sample; ``(c, c)`` when every value equals ``c`` (so also
        for a single value).

    Raises
    ------
    ValueError
        If a value is not a finite number, ``values`` is not one-dimensional, or ``confidence``,
        ``resamples`` or ``seed`` is out of range.
    """
    confidence = _check_confidence(confidence)
    resamples = check_int("resamples", resamples, 1)
    seed = check_int("seed", seed, 0)
    x = _as_finite("values", values)
    n = x.size
    if n == 0:
        return (math.nan, math.nan)
    if np.all(x == x[0]):
        return (float(x[0]), float(x[0]))
    rng = np.random.default_rng(seed)
    means = np.empty(resamples)
    rows = max(1, _BOOTSTRAP_CHUNK // n)
    for start in range(0, resamples, rows):
        stop = min(start + rows, resamples)
        idx = rng.integers(0, n, size=(stop - start, n))
        means[start:stop] = x[idx].mean(axis=1)
    tail = (1.0 - confidence) / 2.0
    low, high = np.quantile(means, [tail, 1.0 - tail])
    return (float(low), float(high))


def tail_mean(values: Iterable[float], share: float = 0.1) -> float:
    """Mean of the largest ``ceil(share * n)`` values (the worst episodes' final distance); NaN when empty."""
    x = np.sort(np.asarray(list(values), dtype=float))
    if x.size == 0:
        return math.nan
    return float(x[-math.ceil(share * x.size) :].mean())


def bootstrap_tail_interval(
    values: Iterable[float],
    share: float = 0.1,
    confidence: float = 0.95,
    resamples: int = 2_000,
    seed: int = 0,
) -> tuple[float, float]:
    """Percentile bootstrap interval of :func:`tail_mean` (resampling the values with
    replacement from ``numpy.random.default_rng(seed)``); ``(nan, nan)`` when empty."""
    confidence = _check_confidence(confidence)
    x = np.asarray(list(values), dtype=float)
    if x.size == 0:
        return (math.nan, math.nan)
    if not np.isfinite(x).all():
        raise ValueError("values must be finite numbers")
    rng = np.random.default_rng(seed)
    top = math.ceil(share * x.size)
    rows = max(1, _BOOTSTRAP_CHUNK // x.size)
    tails = np.empty(resamples)
    for start in range(0, resamples, rows):
        stop = min(start + rows, resamples)
        sample = np.sort(x[rng.integers(0, x.size, size=(stop - start, x.size))], axis=1)
        tails[start:stop] = sample[:, -top:].mean(axis=1)
    tail = (1.0 - confidence) / 2.0
    low, high = np.quantile(tails, [tail, 1.0 - tail])
    return (float(low), float(high))


@dataclass(frozen=True)
class PairedComparison:
    """Two boolean outcome vectors paired index by index (same seeds), summarised.

    Attributes
    ----------
    n : int
        Number of pairs.
    rate_a, rate_b : float
        Success rates of ``a`` and ``b``.
    difference : float
        ``rate_a - rate_b``.
    low, high : float
        Confidence interval of ``difference`` by Newcombe's (1998) method 10, within [-1, 1].
    both_success, only_a, only_b, both_fail : int
        The 2x2 table: both succeeded, only ``a`` succeeded, only ``b`` succeeded, neither did.
    p_value : float
        Exact two-sided McNemar test: ``min(1, 2 P(X <= min(only_a, only_b)))`` with
        ``X ~ Binomial(only_a + only_b, 1/2)``; 1.0 without discordant pairs.
    """

    n: int
    rate_a: float
    rate_b: float
    difference: float
    low: float
    high: float
    both_success: int
    only_a: int
    only_b: int
    both_fail: int
    p_value: float

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON types (int and float; a NaN stays ``float('nan')``)."""
        return {k: (int(v) if isinstance(v, Integral) else float(v)) for k, v in asdict(self).items()}


def _as_outcomes(name: str, values: Iterable[Any]) -> list[bool]:
    """``values`` as a list of bool; entries must be bools or numbers equal to 0 or 1."""
    if isinstance(values, np.ndarray):
        if values.ndim != 1:
            raise ValueError(f"{name} must be one-dimensional; got shape {values.shape}")
        if values.dtype == bool:
            return values.tolist()
    out = []
    for i, v in enumerate(values):
        if isinstance(v, (bool, np.bool_)) or (isinstance(v, Real) and v in (0, 1)):
            out.append(bool(v))
        else:
            raise ValueError(f"{name}[{i}]={v!r} is not allowed; outcomes must be True/False (or 0/1)")
    return out


def _mcnemar_exact(only_a: int, only_b: int) -> float:
    """Exact two-sided McNemar p-value: the binomial test of the discordant pairs at 1/2."""
    m = only_a + only_b
    if m == 0:
        return 1.0
    k = min(only_a, only_b)
    tail = sum(math.comb(m, i) for i in range(k + 1))  # exact integers: 2 P(X <= k) = tail / 2**(m-1)
    return min(1.0, tail / 2 ** (m - 1))


def _newcombe_paired(
    both: int, only_a: int, only_b: int, neither: int, confidence: float
) -> tuple[float, float]:
    """Newcombe's (1998) hybrid score interval (method 10) for a difference of paired proportions."""
    n = both + only_a + only_b + neither
    successes_a, successes_b = both + only_a, both + only_b
    p1, p2 = successes_a / n, successes_b / n
    l1, u1 = wilson_interval(successes_a, n, confidence)
    l2, u2 = wilson_interval(successes_b, n, confidence)
    # Newcombe's corrected phi: the product of the margins is zero when a rate is 0 or 1, and
    # then phi = 0; otherwise B = ad - bc is shrunk towards 0 by n/2 when positive.
    margins = successes_a * (n - successes_a) * successes_b * (n - successes_b)
    phi = 0.0
    if margins > 0:
        b = both * neither - only_a * only_b
        c = b - n / 2 if b > n / 2 else (0.0 if b >= 0 else float(b))
        phi = c / math.sqrt(margins)
    d = (only_a - only_b) / n  # = p1 - p2, rounded once
    da, db = p1 - l1, u2 - p2  # lower limit: a's rate down, b's rate up
    low = d - math.sqrt(max(0.0, da * da - 2.0 * phi * da * db + db * db))
    ua, ub = u1 - p1, p2 - l2  # upper limit: a's rate up, b's rate down
    high = d + math.sqrt(max(0.0, ub * ub - 2.0 * phi * ub * ua + ua * ua))
    return (max(-1.0, low), min(1.0, high))


def paired_comparison(a: Iterable[Any], b: Iterable[Any], confidence: float = 0.95) -> PairedComparison:
    """Compare two boolean outcome vectors paired index by index (e.g. the same seeds).

    Parameters
    ----------
    a, b : iterable of bool
        Outcomes of the two controllers; ``a[i]`` and ``b[i]`` come from the same episode
        (seed). Entries must be bools (Python or numpy) or numbers equal to 0 or 1.
    confidence : float, optional
        Two-sided confidence level of the interval, ``0 < confidence < 1`` (default 0.95).

    Returns
    -------
    PairedComparison
        Rates, their difference ``rate_a - rate_b`` with Newcombe's method 10 interval, the
        2x2 table and the exact McNemar p-value.

    Raises
    ------
    ValueError
        If the lengths differ, there are no pairs, an entry is not boolean-like, or
        ``confidence`` is outside (0, 1).

    Notes
    -----
    Method 10 combines the Wilson intervals ``(l1, u1)`` and ``(l2, u2)`` of the two rates with
    the corrected correlation ``phi`` of the 2x2 table (``phi = 0`` when a margin is 0 or n):
    ``low = D - sqrt((p1 - l1)**2 - 2 phi (p1 - l1)(u2 - p2) + (u2 - p2)**2)`` and
    ``high = D + sqrt((p2 - l2)**2 - 2 phi (p2 - l2)(u1 - p1) + (u1 - p1)**2)``.

    References
    ----------
    Newcombe, R.G. (1998). Improved confidence intervals for the difference between binomial
    proportions based on paired data. Statistics in Medicine 17, 2635-2650.
    """
    confidence = _check_confidence(confidence)
    xa, xb = _as_outcomes("a", a), _as_outcomes("b", b)
    if len(xa) != len(xb):
        raise ValueError(f"a and b must pair up index by index; got len(a)={len(xa)} and len(b)={len(xb)}")
    n = len(xa)
    if n == 0:
        raise ValueError("a and b are empty (n=0); a paired comparison needs at least one pair")
    both = sum(1 for u, v in zip(xa, xb) if u and v)
    only_a = sum(1 for u, v in zip(xa, xb) if u and not v)
    only_b = sum(1 for u, v in zip(xa, xb) if v and not u)
    neither = n - both - only_a - only_b
    low, high = _newcombe_paired(both, only_a, only_b, neither, confidence)
    return PairedComparison(
        n=n,
        rate_a=(both + only_a) / n,
        rate_b=(both + only_b) / n,
        difference=(only_a - only_b) / n,
        low=low,
        high=high,
        both_success=both,
        only_a=only_a,
        only_b=only_b,
        both_fail=neither,
        p_value=_mcnemar_exact(only_a, only_b),
    )


def holm_adjusted(p_values: Iterable[float], same: Iterable[Hashable] | None = None) -> list[float]:
    """Holm's step-down adjusted p-values, in the order given (NaN stays NaN and is not counted).

    The i-th smallest of m p-values becomes max over j <= i of min(1, (m - j + 1) p_(j)): reject
    where the adjusted value is below alpha, and the family-wise error rate is at most alpha.

    ``same`` (one identity per p-value, e.g. :func:`evaluation.episodes.distinct.paired_identity`) names
    tests run on the same data: two controllers whose episodes agree bit for bit (a ``-robust``
    twin at nominal slip) give the same test against a third, and one test is one hypothesis,
    counted once in m and given one adjusted value (a repeated test is not a new one, as an
    identical rerun is not a sample).
    """
    values = [float(p) for p in p_values]
    identities: list[Hashable] = list(range(len(values))) if same is None else list(same)
    if len(identities) != len(values):
        raise ValueError(f"same names {len(identities)} tests, p_values {len(values)}")
    first: dict[Hashable, int] = {}
    for i, (identity, p) in enumerate(zip(identities, values, strict=True)):
        if not math.isnan(p):
            first.setdefault(identity, i)
    order = sorted((values[i], i) for i in first.values())
    m = len(order)
    adjusted: dict[Hashable, float] = {}
    running = 0.0
    for rank, (p, i) in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p))
        adjusted[identities[i]] = running
    return [
        math.nan if math.isnan(p) else adjusted[identity]
        for identity, p in zip(identities, values, strict=True)
    ]


Table = tuple[NDArray[np.float64], NDArray[np.int64]]


def _layout_table(name: str, clusters: Iterable[Iterable[Any]], binary: bool) -> Table:
    """``clusters`` as (values (L, K_max) padded with 0, sizes (L,)), layouts without episodes
    left out; entries checked by name (``name[i][j]``): outcomes 0/1 when ``binary``, else finite."""
    rows = []
    for i, cluster in enumerate(clusters):
        if binary:
            rows.append(np.asarray(_as_outcomes(f"{name}[{i}]", list(cluster)), dtype=np.float64))
        else:
            rows.append(_as_finite(f"{name}[{i}]", cluster))
    return _padded(rows)


def _padded(rows: list[NDArray[np.float64]]) -> Table:
    rows = [r for r in rows if r.size]
    sizes = np.array([r.size for r in rows], dtype=np.int64)
    values = np.zeros((len(rows), int(sizes.max()) if rows else 0))
    for i, r in enumerate(rows):
        values[i, : r.size] = r
    return values, sizes


def _mask(sizes: NDArray[np.int64], width: int) -> NDArray[np.bool_]:
    return np.arange(width) < sizes[..., None]


def _replicates(
    table: Table,
    statistic: Callable[[NDArray[np.float64], NDArray[np.bool_]], NDArray[np.float64]],
    scheme: str,
    n_boot: int,
    rng: np.random.Generator,
) -> NDArray[np.float64]:
    """``statistic`` of ``n_boot`` resampled tables (shape (b, L, K) values and mask in, (b,) out).

    The layouts of every replicate are drawn first, all at once (``rng.integers(0, L, (n_boot,
    L))``: the draws of the one-stage cluster bootstrap, whatever the scheme), then the episodes
    within the drawn layouts, in chunks of at most 2**20 entries."""
    values, sizes = table
    n_layouts, width = values.shape
    picks = (
        rng.integers(0, n_layouts, size=(n_boot, n_layouts))
        if scheme != "within"
        else np.broadcast_to(np.arange(n_layouts), (n_boot, n_layouts))
    )
    out = np.empty(n_boot)
    rows = max(1, _BOOTSTRAP_CHUNK // (n_layouts * width))
    for start in range(0, n_boot, rows):
        chunk = picks[start : start + rows]
        drawn_sizes = sizes[chunk]
        if scheme == "layouts":
            drawn = values[chunk]
        else:
            # episode j of a drawn layout of size k: floor(u k), u uniform in [0, 1)
            within = (rng.random((*chunk.shape, width)) * drawn_sizes[..., None]).astype(np.int64)
            drawn = values[chunk[..., None], within]
        out[start : start + chunk.shape[0]] = statistic(drawn, _mask(drawn_sizes, width))
    return out


def _ratio(values: NDArray[np.float64], mask: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Episodes' mean per replicate: the sum over drawn episodes over their number."""
    axes = tuple(range(1, values.ndim))
    return np.asarray(np.where(mask, values, 0.0).sum(axis=axes) / mask.sum(axis=axes))


def cluster_bootstrap_rate(
    clusters: Iterable[Iterable[Any]], confidence: float = 0.95, n_boot: int = 4000, seed: int = 0
) -> tuple[float, float, float]:
    """A success rate over clustered outcomes and its cluster (percentile) bootstrap interval:
    whole clusters are resampled with replacement and the rate of each sample is its successes
    over its episodes (a ratio estimator): (rate, low, high); NaN for no outcomes.

    The clusters are what episodes share: a trial's seed (its layout on random maps, its start
    perturbation and slip draws) is shared across the cells of a protocol, so a hard layout
    fails at every slip and pooling its episodes as independent would overstate the evidence.
    :func:`evaluation.stats.clustered.layout_rate_interval` with ``resample="layouts"`` is the same
    interval, refusing empty input instead.
    """
    confidence = _check_confidence(confidence)
    n_boot = check_int("n_boot", n_boot, 1)
    seed = check_int("seed", seed, 0)
    table = _layout_table("clusters", clusters, binary=True)
    if table[1].size == 0:
        return math.nan, math.nan, math.nan
    rates = _replicates(table, _ratio, "layouts", n_boot, np.random.default_rng(seed))
    tail = (1.0 - confidence) / 2.0
    low, high = np.quantile(rates, [tail, 1.0 - tail])
    return float(table[0].sum() / table[1].sum()), float(low), float(high)
