"""Paired tests over layouts: two controllers on shared (layout, seed) units, the layout the unit.

- :func:`layout_sign_flip_test`: the layout-level sign-flip (randomization) test of a paired
  difference, exact for binary outcomes and metrics alike.
- :func:`paired_rates_by_layout`, :func:`paired_means_by_layout`: the difference with its
  two-stage bootstrap interval (:mod:`evaluation.stats.clustered`), the test, and the discordance and
  between-layout correlation the power statement reads (:mod:`evaluation.stats.families`).
- :func:`sign_flip_p_text`, :func:`holm_clause`, :func:`found_clause`: the tests' and power
  statements' words, one wording for every page (the layout-clustered statement of
  :mod:`evaluation.stats.families` and the per-pair one of :mod:`evaluation.stats.designs`).

Data come as one sequence per layout: ``a[i][j]`` and ``b[i][j]`` are the two controllers'
episodes on layout i with the j-th seed.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from evaluation.stats.clustered import _interval
from evaluation.stats.statistics import _BOOTSTRAP_CHUNK, Table, _check_confidence, _layout_table, _mask
from koopman_envs.checks import check_int

__all__ = [
    "EXACT_FLIPS",
    "LayoutComparison",
    "found_clause",
    "holm_clause",
    "layout_sign_flip_test",
    "paired_means_by_layout",
    "paired_rates_by_layout",
    "sign_flip_p_text",
]

#: up to this many layouts with a non-zero difference, the sign-flip test enumerates all 2**n
#: sign patterns (65,536 at 16) and its p-value is exact
EXACT_FLIPS = 16


def _flip_sums(
    totals: NDArray[np.float64], permutations: int, rng: np.random.Generator
) -> Iterator[NDArray[np.float64]]:
    """|sum of s_i D_i| over sign patterns: all 2**n of them for n <= EXACT_FLIPS, else
    ``permutations`` random ones (in chunks of at most 2**20 signs)."""
    n = totals.size
    if n <= EXACT_FLIPS:
        bits = (np.arange(2**n)[:, None] >> np.arange(n)) & 1
        yield np.abs((1 - 2 * bits) @ totals)
        return
    rows = max(1, _BOOTSTRAP_CHUNK // n)
    for start in range(0, permutations, rows):
        signs = rng.integers(0, 2, size=(min(rows, permutations - start), n)) * 2 - 1
        yield np.abs(signs @ totals)


def layout_sign_flip_test(
    differences: Iterable[Iterable[float]], permutations: int = 20_000, seed: int = 0
) -> tuple[float, bool]:
    """Two-sided layout-level sign-flip (randomization) test of a paired difference.

    Under the null hypothesis the two controllers are exchangeable on every layout, so each
    layout's total difference ``D_i = sum_j d_ij`` is as likely to carry either sign, whatever
    the correlation of the episodes within the layout. The statistic is ``|sum_i D_i|``, referred
    to its distribution over sign flips of whole layouts (Fisher 1935; for clustered matched
    pairs, Gail et al. 1996, Statistics in Medicine 15, 1069-1092). Chosen over Obuchowski's
    (1998) clustered McNemar test because it needs no large-sample approximation (its size holds
    for any number of layouts, and whatever the layouts' sizes), and because one test serves binary
    outcomes (``d`` in {-1, 0, 1}: the discordant pairs) and continuous metrics alike. Flipping
    signs leaves ``sum D_i**2`` unchanged, so the test is the same as the paired t-test's
    statistic on layout totals referred to its permutation distribution.

    Parameters
    ----------
    differences : iterable of iterable of float
        ``differences[i][j] = a_ij - b_ij``, the paired units (seeds) of layout i.
    permutations : int, optional
        Random sign patterns, ``>= 1`` (default 20,000: the p-value's resolution, 5e-5, is ten
        times below Holm's first step for 100 tests at alpha 0.05). Unused when at most
        :data:`EXACT_FLIPS` layouts have a non-zero total: then all 2**n patterns are enumerated.
    seed : int, optional
        Seed of the sign patterns, ``>= 0``.

    Returns
    -------
    (p_value, exact) : (float, bool)
        ``exact``: all patterns enumerated, ``p`` = the share at least as extreme as the data's;
        otherwise ``p = (1 + count) / (1 + permutations)``, which keeps the test's size at most
        alpha (Phipson & Smyth 2010). 1.0 when no layout has a non-zero total.
    """
    permutations = check_int("permutations", permutations, 1)
    seed = check_int("seed", seed, 0)
    return _sign_flip(
        _layout_totals(_layout_table("differences", differences, binary=False)), permutations, seed
    )


def sign_flip_p_text(p_value: float, exact: bool, permutations: int = 20_000, digits: int = 2) -> str:
    """The relation and value to print after "p" for :func:`layout_sign_flip_test`'s result.

    A random (not exact) test's p-value is at least ``1 / (1 + permutations)``, reached when no
    sign pattern was as extreme as the data: printed as ``"= 5e-05"`` it would read as a
    measured value, so the floor is printed as a bound, ``"<= 5e-05"``; any other p as
    ``"= 0.46"`` (``digits`` significant digits).
    """
    floor = 1.0 / (1 + check_int("permutations", permutations, 1))
    if not exact and p_value <= floor * (1 + 1e-9):
        return f"<= {floor:.{digits}g}"
    return f"= {p_value:.{digits}g}"


def _layout_totals(table: Table) -> NDArray[np.float64]:
    values, sizes = table
    return np.asarray(np.where(_mask(sizes, values.shape[1]), values, 0.0).sum(axis=1))


def _sign_flip(totals: NDArray[np.float64], permutations: int, seed: int) -> tuple[float, bool]:
    """:func:`layout_sign_flip_test` on the layouts' total differences."""
    totals = totals[totals != 0.0]
    if totals.size == 0:
        return 1.0, True
    observed = abs(float(totals.sum()))
    # a pattern equal to the data's (or its mirror) must count as "at least as extreme" though
    # the two sums add in different orders: compare with a tolerance far below any real gap
    threshold = observed - 1e-9 * float(np.abs(totals).sum())
    rng = np.random.default_rng(seed)
    count = sum(int((sums >= threshold).sum()) for sums in _flip_sums(totals, permutations, rng))
    if totals.size <= EXACT_FLIPS:
        return count / 2**totals.size, True
    return (1 + count) / (1 + permutations), False


@dataclass(frozen=True)
class LayoutComparison:
    """Two controllers on shared (layout, seed) units, compared with the layout as the unit.

    Attributes
    ----------
    layouts, units : int
        Layouts with at least one pair, and pairs (units) in all.
    mean_a, mean_b : float
        Each controller's rate (or metric mean) over the units.
    difference, low, high : float
        ``mean_a - mean_b`` and its two-stage bootstrap interval (layouts, then units within each
        drawn layout, variance-matched: :func:`layout_rate_interval`).
    p_value : float
        Two-sided layout-level sign-flip test (:func:`layout_sign_flip_test`).
    exact : bool
        The p-value enumerated every sign pattern.
    permutations : int
        Sign patterns the p-value counted over (2**n when exact).
    discordance : float
        Binary outcomes: share of units where the two outcomes differ (NaN for a metric).
    sd : float
        SD of the units' differences (ddof 1; NaN for a single unit).
    icc : float
        Between-layout (intraclass) correlation of the units' differences, the one-way ANOVA
        estimator ``(MSB - MSW) / (MSB + (k0 - 1) MSW)`` with ``k0 = (N - sum k_i**2 / N) / (L - 1)``;
        NaN when undefined (one layout, one unit per layout, or no variance).
    """

    layouts: int
    units: int
    mean_a: float
    mean_b: float
    difference: float
    low: float
    high: float
    p_value: float
    exact: bool
    permutations: int
    discordance: float
    sd: float
    icc: float

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON types (a NaN stays ``float('nan')``)."""
        return asdict(self)


def _paired_tables(
    a: Iterable[Iterable[Any]], b: Iterable[Iterable[Any]], binary: bool
) -> tuple[Table, Table]:
    """The two sides as tables, refused by name unless they pair up layout by layout and seed by seed."""
    rows_a, rows_b = [list(x) for x in a], [list(y) for y in b]
    if len(rows_a) != len(rows_b):
        raise ValueError(
            f"a and b must pair up layout by layout; got {len(rows_a)} layouts in a and {len(rows_b)} in b"
        )
    for i, (x, y) in enumerate(zip(rows_a, rows_b, strict=True)):
        if len(x) != len(y):
            raise ValueError(
                f"a[{i}] and b[{i}] must pair up seed by seed; got {len(x)} units in a[{i}] and {len(y)} in b[{i}]"
            )
    tables = (_layout_table("a", rows_a, binary), _layout_table("b", rows_b, binary))
    if tables[0][1].size == 0:
        raise ValueError("a and b are empty (no layout holds a pair); a paired comparison needs at least one")
    return tables


def _icc(table: Table) -> float:
    """One-way ANOVA estimate of the intraclass correlation (see :class:`LayoutComparison`)."""
    values, sizes = table
    n_layouts, n = sizes.size, int(sizes.sum())
    if n_layouts < 2 or n <= n_layouts:
        return math.nan
    mask = _mask(sizes, values.shape[1])
    means = np.where(mask, values, 0.0).sum(axis=1) / sizes
    grand = float((means * sizes).sum() / n)
    msb = float((sizes * (means - grand) ** 2).sum()) / (n_layouts - 1)
    msw = float((np.where(mask, values - means[:, None], 0.0) ** 2).sum()) / (n - n_layouts)
    k0 = (n - float((sizes**2).sum()) / n) / (n_layouts - 1)
    denominator = msb + (k0 - 1.0) * msw
    return (msb - msw) / denominator if denominator > 0 else math.nan


def _compare(
    a: Iterable[Iterable[Any]],
    b: Iterable[Iterable[Any]],
    binary: bool,
    confidence: float,
    n_boot: int,
    permutations: int,
    seed: int,
) -> LayoutComparison:
    confidence = _check_confidence(confidence)
    n_boot = check_int("n_boot", n_boot, 1)
    permutations = check_int("permutations", permutations, 1)
    seed = check_int("seed", seed, 0)
    (va, sizes), (vb, _) = _paired_tables(a, b, binary)
    d = (va - vb, sizes)
    difference, low, high = _interval(d, "mean", confidence, n_boot, seed, "layouts+within")
    totals = _layout_totals(d)
    p_value, exact = _sign_flip(totals, permutations, seed)
    flat = d[0][_mask(sizes, d[0].shape[1])]
    n = int(sizes.sum())
    return LayoutComparison(
        layouts=int(sizes.size),
        units=n,
        mean_a=float(va.sum() / n),  # the tables are padded with zeros
        mean_b=float(vb.sum() / n),
        difference=difference,
        low=max(-1.0, low) if binary else low,
        high=min(1.0, high) if binary else high,
        p_value=p_value,
        exact=exact,
        permutations=2 ** int((totals != 0).sum()) if exact else permutations,
        discordance=float((flat != 0).mean()) if binary else math.nan,
        sd=float(flat.std(ddof=1)) if n > 1 else math.nan,
        icc=_icc(d),
    )


def paired_rates_by_layout(
    a: Iterable[Iterable[Any]],
    b: Iterable[Iterable[Any]],
    confidence: float = 0.95,
    n_boot: int = 4000,
    permutations: int = 20_000,
    seed: int = 0,
) -> LayoutComparison:
    """Two controllers' success on shared (layout, seed) units, with the layout as the unit.

    Parameters
    ----------
    a, b : iterable of iterable of bool
        ``a[i][j]``, ``b[i][j]``: the outcomes of the two controllers on layout i with the j-th
        seed (the same episode conditions); the two must have the same layouts and, per layout,
        the same number of units.
    confidence : float, optional
        Two-sided level of the interval, ``0 < confidence < 1`` (default 0.95).
    n_boot : int, optional
        Bootstrap replicates, ``>= 1`` (default 4000).
    permutations : int, optional
        Random sign patterns of the test, ``>= 1`` (default 20,000; :func:`layout_sign_flip_test`).
    seed : int, optional
        Seed of the bootstrap and of the sign patterns, ``>= 0``.

    Returns
    -------
    LayoutComparison
        Rates, the difference with its interval (clipped to [-1, 1]), the p-value, the
        discordance and the between-layout correlation that :mod:`evaluation.stats.families`' power
        statement reads.

    Raises
    ------
    ValueError
        ``a`` and ``b`` differ in layouts or in units on a layout (named), hold no pair, an
        outcome is not boolean, or a number is out of range.
    """
    return _compare(a, b, True, confidence, n_boot, permutations, seed)


def paired_means_by_layout(
    a: Iterable[Iterable[float]],
    b: Iterable[Iterable[float]],
    confidence: float = 0.95,
    n_boot: int = 4000,
    permutations: int = 20_000,
    seed: int = 0,
) -> LayoutComparison:
    """Two controllers' metric (clearance, time to goal, jerk) on shared (layout, seed) units:
    :func:`paired_rates_by_layout` for finite numbers (``discordance`` is NaN)."""
    return _compare(a, b, False, confidence, n_boot, permutations, seed)


def holm_clause(alpha: float, alpha_per_test: float) -> str:
    """The words every power statement names its correction with: ``Holm at alpha = ... (...)``."""
    return f"Holm at alpha = {alpha:g} (first step alpha/m = {alpha_per_test:.3g})"


def found_clause(
    difference: float,
    units: int,
    unit_word: str,
    fewest_units: int,
    *,
    spread_is_zero: bool,
    binary: bool = True,
) -> str:
    """What a power statement says is found: the detectable difference, or why there is none.

    One wording for :meth:`evaluation.stats.families.PowerStatement.sentence` (clustered on layouts, the sign-flip test) and
    :meth:`evaluation.stats.designs.TablePower.sentence` (unclustered pairs, the exact McNemar test).

    Parameters
    ----------
    difference
        The smallest detectable difference, NaN when none is.
    units
        How many independent units the test sees (layouts, or pairs).
    unit_word
        Their name in the sentence: ``"layouts"`` or ``"pairs"``.
    fewest_units
        The fewest units at which the exact test can reach Holm's first-step level alpha/m
        (:func:`evaluation.stats.families.fewest_units`).
    spread_is_zero
        Whether the comparisons show no spread (no discordant pair, or alike differences).
    binary
        Whether the outcome is success (a difference in points) rather than a metric.
    """
    if not math.isnan(difference):
        return f"a paired difference of {f'{100 * difference:.1f} points' if binary else f'{difference:.3g}'}"
    if units < fewest_units:
        test = "sign-flip test" if unit_word == "layouts" else "exact test"
        return (
            f"no paired difference (the {test}'s smallest p-value over {units} {unit_word}, "
            f"2/2^{units} = {2.0 ** (1 - units):.3g}, is above alpha/m)"
        )
    if spread_is_zero:
        # nothing to compute the power from: no discordant pair, or differences all alike
        if unit_word == "layouts":
            return "no paired difference (the comparisons show no spread to compute a power from)"
        return "no paired difference (no discordant pair to compute a power from)"
    return f"no paired difference ({'not even the largest the discordance allows' if binary else 'none reaches it'})"
