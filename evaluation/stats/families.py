"""Families of tests declared before the data, and what a table's tests can detect.

- :class:`HypothesisFamily`: a named family (a table's comparisons, declared before the run);
  :meth:`HypothesisFamily.correct` applies Holm's step-down within it and reports the family's
  name and size beside every corrected p-value.
- :func:`paired_power`, :func:`detectable_difference`, :func:`layouts_needed`: the power of the
  layout-level paired test (:func:`evaluation.stats.layout_tests.layout_sign_flip_test`) after the
  family's correction, the smallest paired difference it finds with a given power, and the
  layouts a suite needs for a given difference.
- :func:`power_statement`: the statement a table prints, from its measured comparisons.
- :func:`evaluation.stats.designs.table_power` (in designs.py: this module is at its size limit):
  the same for a table of paired success tests on unclustered units (the paper protocol's seeds, a
  sweep's episode units), from its pooled discordance.

The convention for the correction (stated in every power statement): Holm's first step is
Bonferroni's, ``alpha / m``; a difference found at that level is found by Holm whatever the other
tests give, so the power computed at ``alpha / m`` is a lower bound of Holm's.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import asdict, dataclass
from numbers import Real
from statistics import NormalDist, median
from typing import Any

from evaluation.stats.layout_tests import LayoutComparison, found_clause, holm_clause
from evaluation.stats.statistics import _check_confidence, _z, holm_adjusted
from koopman_envs.checks import MAX_NUMBER, check_int, check_number

__all__ = [
    "CorrectedTest",
    "FamilyResult",
    "HypothesisFamily",
    "PowerStatement",
    "detectable_difference",
    "layouts_needed",
    "paired_power",
    "power_statement",
]


@dataclass(frozen=True)
class CorrectedTest:
    """One comparison of a family: its raw p-value, Holm's adjusted value and the decision."""

    comparison: str
    p_value: float
    p_holm: float
    rejected: bool


@dataclass(frozen=True)
class FamilyResult:
    """A family's tests corrected together, reported with the family's name and size ``m``."""

    family: str
    size: int
    alpha: float
    tests: tuple[CorrectedTest, ...]

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON types."""
        return asdict(self)


@dataclass(frozen=True)
class HypothesisFamily:
    """A named family of tests, declared before the data: the comparisons one table holds.

    Parameters
    ----------
    name : str
        What the table reports (e.g. ``"target_reaching/test: success, every pair"``).
    comparisons : sequence of str
        One label per test, distinct; the family's size ``m`` is their number.
    alpha : float, optional
        Family-wise error rate, ``0 < alpha < 1`` (default 0.05).
    """

    name: str
    comparisons: tuple[str, ...]
    alpha: float = 0.05

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"name={self.name!r} must be a non-empty string")
        labels = tuple(self.comparisons)
        if not labels:
            raise ValueError(f"family {self.name!r} declares no comparison; it needs at least one")
        repeated = sorted({c for c in labels if labels.count(c) > 1})
        if repeated:
            raise ValueError(
                f"family {self.name!r} declares {repeated} more than once; labels must be distinct"
            )
        object.__setattr__(self, "comparisons", labels)
        object.__setattr__(self, "alpha", _check_confidence(self.alpha, "alpha"))

    @property
    def size(self) -> int:
        """``m``: the number of comparisons declared."""
        return len(self.comparisons)

    def correct(
        self, p_values: Mapping[str, float], same: Mapping[str, Hashable] | None = None
    ) -> FamilyResult:
        """Holm's step-down adjustment within the family (:func:`evaluation.stats.statistics.holm_adjusted`).

        Parameters
        ----------
        p_values : mapping of str to float
            A p-value for every declared comparison, and none other (both refused by name). A NaN
            (a comparison that could not be run) is counted in ``m`` as ``p = 1``: the family was
            declared before the data, and leaving a test out after seeing them would loosen the
            correction; its adjusted value is NaN and it is not rejected.
        same : mapping of str to hashable, optional
            Comparisons run on the same data (:func:`evaluation.episodes.distinct.paired_identity`) are one
            hypothesis, counted once in ``m``.

        Returns
        -------
        FamilyResult
            The family's name, the size ``m`` the correction used, ``alpha`` and one
            :class:`CorrectedTest` per comparison, in the declared order.
        """
        unknown = sorted(set(p_values) - set(self.comparisons))
        if unknown:
            raise ValueError(
                f"{unknown} not declared in family {self.name!r}; declared: {list(self.comparisons)} "
                "(a family is fixed before the data: declare a new one)"
            )
        missing = [c for c in self.comparisons if c not in p_values]
        if missing:
            raise ValueError(f"family {self.name!r}: no p-value for {missing}; every declared test counts")
        raw = [float(p_values[c]) for c in self.comparisons]
        for label, p in zip(self.comparisons, raw, strict=True):
            if not (math.isnan(p) or 0.0 <= p <= 1.0):
                raise ValueError(f"p_values[{label!r}]={p!r} must be within [0, 1] (or NaN: not run)")
        identities = [c if same is None else same.get(c, c) for c in self.comparisons]
        adjusted = holm_adjusted([1.0 if math.isnan(p) else p for p in raw], same=identities)
        tests = tuple(
            CorrectedTest(c, p, math.nan if math.isnan(p) else q, (not math.isnan(p)) and q <= self.alpha)
            for c, p, q in zip(self.comparisons, raw, adjusted, strict=True)
        )
        return FamilyResult(self.name, len(set(identities)), self.alpha, tests)


def _unit_variance(difference: float, discordance: float | None, sd: float | None) -> float:
    """Variance of one unit's difference under the alternative: ``psi - delta**2`` for binary
    outcomes (``d`` in {-1, 0, 1} with ``P(d != 0) = psi``), ``sd**2`` for a metric."""
    if (discordance is None) == (sd is None):
        raise ValueError(
            f"discordance={discordance!r}, sd={sd!r}: give exactly one (binary outcomes: discordance; a metric: sd)"
        )
    if discordance is not None:
        psi = check_number("discordance", discordance, above=0.0, at_most=1.0)
        check_number("difference", abs(difference), at_most=psi, note="|difference| <= discordance")
        return psi - difference**2
    return check_number("sd", sd, above=0.0) ** 2


def paired_power(
    difference: float,
    layouts: int,
    per_layout: float,
    *,
    discordance: float | None = None,
    sd: float | None = None,
    icc: float = 0.0,
    family_size: int = 1,
    alpha: float = 0.05,
) -> float:
    """Power of the two-sided layout-level paired test at level ``alpha / family_size``.

    Parameters
    ----------
    difference : float
        The true paired difference (a rate difference, or a metric's mean difference).
    layouts : int
        Layouts ``L`` with paired units, ``>= 1``.
    per_layout : float
        Paired units (seeds) per layout ``k``, ``> 0`` (a mean when layouts differ).
    discordance : float, optional
        Binary outcomes: the share ``psi`` of units whose two outcomes differ, ``0 < psi <= 1``.
    sd : float, optional
        A metric: the SD of the units' differences, ``> 0``. Exactly one of the two is given.
    icc : float, optional
        Between-layout (intraclass) correlation ``rho`` of the units' differences, within [0, 1].
    family_size : int, optional
        ``m``, the tests of the family; the level is Holm's first step, ``alpha / m``.
    alpha : float, optional
        Family-wise level, ``0 < alpha < 1``.

    Returns
    -------
    float
        ``Phi((sqrt(L) mu - z s0) / sqrt(v1 (1 - c)**2 + z**2 v1**2 / (2 L s0**2)))`` with
        ``mu = k |delta|`` a layout's mean total difference, ``v1 = k var_d (1 + (k - 1) rho)``
        its variance (``var_d = psi - delta**2`` as in Connor 1987, or ``sd**2``; the design
        effect ``1 + (k - 1) rho`` as in Donner & Klar 2000), ``s0 = sqrt(v1 + mu**2)`` the
        sign-flip test's reference SD (it flips the totals about 0, so it sees their mean as
        spread), ``c = z mu / (sqrt(L) s0)`` and ``z`` the two-sided normal quantile at
        ``alpha / m``.

    Notes
    -----
    The test rejects when ``T = sum D_i`` reaches ``z sqrt(Q)``, ``Q = sum D_i**2`` (the normal
    approximation of its sign-flip distribution). ``T`` and ``Q`` move together under an
    alternative, so the power is that of ``T - z sqrt(Q)`` being positive, taken by the delta
    method with normal layout totals: the first term of its variance is ``T``'s shrunk by the
    correlation (``(1 - c)**2``), the second ``Q``'s own spread. Without them (Connor's form,
    ``Phi((sqrt(L) mu - z s0) / sqrt(v1))``) the power of a family of 4 at 40 layouts x 3 was
    0.80 where 1000 simulations gave 0.846; with them 0.843. The opposite tail is left out.
    With fewer layouts than the exact test needs to reach the level at all (its smallest p-value
    is ``2 / 2**L``: 5 layouts cannot reach 0.05) the power is 0.

    References
    ----------
    Connor, R.J. (1987). Sample size for testing differences in proportions for the paired-sample
    design. Biometrics 43, 207-211. Donner, A. & Klar, N. (2000). Design and Analysis of Cluster
    Randomization Trials in Health Research. Arnold, London.
    """
    delta = abs(check_number("difference", difference))
    n_layouts = check_int("layouts", layouts, 1)
    k = check_number("per_layout", per_layout, above=0.0)
    rho = check_number("icc", icc, at_least=0.0, at_most=1.0)
    m = check_int("family_size", family_size, 1)
    alpha = _check_confidence(alpha, "alpha")
    v1 = k * _unit_variance(delta, discordance, sd) * (1.0 + (k - 1.0) * rho)
    if n_layouts < _fewest_layouts(alpha / m):
        return 0.0
    return _power(k * delta, v1, n_layouts, _z(1.0 - alpha / m))


def _fewest_layouts(level: float) -> int:
    """The fewest layouts with which the sign-flip test can reject at ``level``: its smallest
    p-value over L layouts is ``2 / 2**L`` (the data's sign pattern and its mirror), so with fewer
    it never rejects, whatever the difference (the normal approximation of :func:`_power` does not
    see this; it matters below about 10 layouts)."""
    return max(1, math.ceil(1.0 - math.log2(level) - 1e-12))


def _power(mu: float, v1: float, n_layouts: int, z: float) -> float:
    """:func:`paired_power` from a layout total's mean ``mu`` and variance ``v1``."""
    s0 = math.sqrt(v1 + mu * mu)
    numerator = math.sqrt(n_layouts) * mu - z * s0
    c = z * mu / (math.sqrt(n_layouts) * s0)
    variance = v1 * (1.0 - c) ** 2 + z * z * v1 * v1 / (2.0 * n_layouts * s0 * s0)
    if variance <= 0.0:  # every layout's total is mu: found exactly when the mean clears the bar
        return 1.0 if numerator > 0 else 0.0
    return NormalDist().cdf(numerator / math.sqrt(variance))


def _check_power(power: float) -> float:
    if isinstance(power, bool) or not isinstance(power, Real) or not 0.5 <= power < 1.0:
        raise ValueError(f"power={power!r} must be a number with 0.5 <= power < 1")
    return float(power)


def detectable_difference(
    layouts: int,
    per_layout: float,
    *,
    discordance: float | None = None,
    sd: float | None = None,
    icc: float = 0.0,
    family_size: int = 1,
    alpha: float = 0.05,
    power: float = 0.8,
) -> float:
    """The smallest paired difference the layout-level test finds with probability ``power``
    after the family's correction: the root of :func:`paired_power` ``= power`` (bisection; the
    power grows with the difference from where it passes 0.5). Arguments as in
    :func:`paired_power`; ``power`` within [0.5, 1).

    Returns
    -------
    float
        The difference (a rate difference: 0.1 is 10 points), or NaN when no difference allowed
        (binary: up to the discordance) reaches that power.
    """
    power = _check_power(power)

    def reach(delta: float) -> float:
        return paired_power(
            delta,
            layouts,
            per_layout,
            discordance=discordance,
            sd=sd,
            icc=icc,
            family_size=family_size,
            alpha=alpha,
        )

    high = discordance if discordance is not None else check_number("sd", sd, above=0.0)
    if discordance is None:
        # the power of a metric's test grows without bound once L > z**2 (and the exact test can
        # reject at all); beyond a million SDs no difference is worth stating
        for _ in range(20):
            if reach(high) >= power or 2.0 * high > MAX_NUMBER:
                break
            high *= 2.0
    if reach(high) < power:
        return math.nan
    low = 0.0
    for _ in range(100):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if reach(middle) < power else (low, middle)
    return high


def layouts_needed(
    difference: float,
    per_layout: float,
    *,
    discordance: float | None = None,
    sd: float | None = None,
    icc: float = 0.0,
    family_size: int = 1,
    alpha: float = 0.05,
    power: float = 0.8,
) -> int:
    """The layouts a suite needs for the layout-level test to find ``difference`` with
    probability ``power`` after the family's correction (for sizing a test suite).

    The smallest ``L`` whose :func:`paired_power` reaches ``power`` (from Connor's closed form
    ``((z s0 + z_power sqrt(v1)) / (k |delta|))**2``, stepped to the root). Arguments as in :func:`paired_power`;
    ``difference`` must not be 0.
    """
    power = _check_power(power)
    delta = abs(check_number("difference", difference))
    if delta == 0.0:
        raise ValueError("difference=0 is not allowed; no number of layouts detects a zero difference")
    k = check_number("per_layout", per_layout, above=0.0)
    rho = check_number("icc", icc, at_least=0.0, at_most=1.0)
    m = check_int("family_size", family_size, 1)
    alpha = _check_confidence(alpha, "alpha")
    v1 = k * _unit_variance(delta, discordance, sd) * (1.0 + (k - 1.0) * rho)
    mu, z = k * delta, _z(1.0 - alpha / m)
    # start from Connor's closed form, then step to the smallest L whose power reaches the target
    first = (z * math.sqrt(v1 + mu * mu) + NormalDist().inv_cdf(power) * math.sqrt(v1)) / mu
    n_layouts = max(_fewest_layouts(alpha / m), math.ceil(first**2))
    while n_layouts > _fewest_layouts(alpha / m) and _power(mu, v1, n_layouts - 1, z) >= power:
        n_layouts -= 1
    while _power(mu, v1, n_layouts, z) < power:
        n_layouts += 1
    return n_layouts


@dataclass(frozen=True)
class PowerStatement:
    """What a table's paired tests can detect, stated beside the table.

    Attributes
    ----------
    family : str
        The family's name; ``family_size`` its ``m``.
    alpha, alpha_per_test : float
        The family-wise level and Holm's first step, ``alpha / m`` (the level the power is computed
        at: a lower bound of Holm's power).
    layouts : int
        The fewest layouts any of the table's comparisons has.
    per_layout : float
        The fewest paired units per layout (units over layouts) of the comparisons.
    discordance, sd : float
        Binary outcomes: the median discordance of the comparisons (``sd`` NaN); a metric: the
        median SD of the units' differences (``discordance`` NaN).
    icc : float
        The median between-layout correlation of the comparisons, within [0, 1] (a negative or
        undefined estimate taken as 0).
    power, difference : float
        The smallest paired difference found with probability ``power`` (NaN: none).
    """

    family: str
    family_size: int
    alpha: float
    alpha_per_test: float
    layouts: int
    per_layout: float
    discordance: float
    sd: float
    icc: float
    power: float
    difference: float

    def sentence(self) -> str:
        """The statement in words, as a table's caption prints it."""
        binary = not math.isnan(self.discordance)
        spread = f"discordance {self.discordance:.2f}" if binary else f"SD of the differences {self.sd:.3g}"
        value = self.discordance if binary else self.sd
        found = found_clause(
            self.difference,
            self.layouts,
            "layouts",
            _fewest_layouts(self.alpha_per_test),
            spread_is_zero=math.isnan(value) or value == 0,
            binary=binary,
        )
        return (
            f"Family {self.family!r}: m = {self.family_size} tests, {holm_clause(self.alpha, self.alpha_per_test)}. "
            f"With {self.layouts} layouts x "
            f"{self.per_layout:g} pairs, {spread} and a between-layout correlation of {self.icc:.2f}, "
            f"{found} is found with {100 * self.power:.0f}% power."
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON types, with the sentence."""
        return {**asdict(self), "sentence": self.sentence()}


def power_statement(
    comparisons: Sequence[LayoutComparison], family: HypothesisFamily, power: float = 0.8
) -> PowerStatement:
    """A table's power statement from its measured comparisons (:mod:`evaluation.stats.layout_tests`).

    The table's design is the least favourable of its comparisons' (fewest layouts, fewest units
    per layout) and its spread the median of theirs (discordance for success, the SD of the
    differences for a metric); the smallest difference detected is
    :func:`detectable_difference` at the family's ``m`` and ``alpha``. One comparison's own
    statement is :func:`detectable_difference` with its numbers.

    Raises
    ------
    ValueError
        No comparison, comparisons that mix success and metrics, or ``power`` outside [0.5, 1).
    """
    power = _check_power(power)
    items = list(comparisons)
    if not items:
        raise ValueError("comparisons is empty; a power statement needs the table's measured comparisons")
    binary = {not math.isnan(c.discordance) for c in items}
    if len(binary) > 1:
        raise ValueError(
            "comparisons mix success (with a discordance) and metrics (without); state them apart"
        )
    is_binary = binary.pop()
    spreads = [c.discordance if is_binary else c.sd for c in items]
    finite = [s for s in spreads if not math.isnan(s)]
    spread = median(finite) if finite else math.nan
    iccs = [c.icc for c in items if not math.isnan(c.icc)]
    rho = min(1.0, max(0.0, median(iccs))) if iccs else 0.0
    layouts = min(c.layouts for c in items)
    per_layout = min(c.units / c.layouts for c in items)
    difference = math.nan
    if spread > 0:  # NaN or 0: without a discordant pair (or any spread) nothing can be said
        difference = detectable_difference(
            layouts,
            per_layout,
            discordance=spread if is_binary else None,
            sd=None if is_binary else spread,
            icc=rho,
            family_size=family.size,
            alpha=family.alpha,
            power=power,
        )
    return PowerStatement(
        family=family.name,
        family_size=family.size,
        alpha=family.alpha,
        alpha_per_test=family.alpha / family.size,
        layouts=layouts,
        per_layout=per_layout,
        discordance=spread if is_binary else math.nan,
        sd=math.nan if is_binary else spread,
        icc=rho,
        power=power,
        difference=difference,
    )
