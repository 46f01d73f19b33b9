"""Intervals over layouts: rates, means and interquartile means when episodes cluster on layouts.

On the benchmark's suites (``docs/benchmark.md``) every controller runs a few episodes (seeds) on
each of a split's layouts, and outcomes cluster on layouts: a hard layout fails at every seed. The
sample is the layouts, so every interval here resamples layouts first, and every test flips whole
layouts. Data come as one sequence per layout (``clusters[i]``: layout i's episodes; for a paired
comparison ``a[i][j]`` and ``b[i][j]`` are the two controllers' episodes on layout i with seed j);
layouts may hold different numbers of episodes, and a layout without any is left out. The
one-stage cluster bootstrap of a rate, and the tables and resampler every interval here draws
with, are in :mod:`evaluation.stats.statistics` (:func:`~evaluation.stats.statistics.cluster_bootstrap_rate`).

- :func:`layout_rate_interval`, :func:`layout_mean_interval`: a rate or a metric's mean with a
  two-stage bootstrap (layouts, then episodes within each drawn layout), stages variance-matched.
- :func:`run_aggregate_interval`: a learned policy's interquartile mean (or mean) over training
  seeds, one score per (stratum, run) as rliable scores (task, run), its interval re-drawing the
  layouts within each stratum (or the runs).

Paired comparisons over layouts (intervals and the layout-level sign-flip test) are in
:mod:`evaluation.stats.layout_tests`; named families of tests and the power statement in
:mod:`evaluation.stats.families`.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from evaluation.stats.statistics import (
    Table,
    _as_finite,
    _check_confidence,
    _layout_table,
    _mask,
    _ratio,
    _replicates,
)
from koopman_envs.checks import check_choice, check_int

__all__ = [
    "interquartile_mean",
    "layout_mean_interval",
    "layout_rate_interval",
    "run_aggregate_interval",
]

#: what a bootstrap re-draws: whole layouts; layouts, then episodes within each drawn layout; or
#: episodes (runs) within each layout, the layouts kept (rliable's stratified bootstrap)
SCHEMES = ("layouts+within", "layouts", "within")


def _require_data(name: str, table: Table) -> None:
    if table[1].size == 0:
        raise ValueError(f"{name} is empty (no layout holds an episode); an interval needs at least one")


def _iqm(values: NDArray[np.float64], mask: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Interquartile mean per replicate, as ``scipy.stats.trim_mean(x, 0.25)`` (rliable's IQM):
    the mean of the sorted values from ``int(n / 4)`` to ``n - int(n / 4)``."""
    b = values.shape[0]
    flat = np.sort(np.where(mask, values, np.inf).reshape(b, -1), axis=1)
    n = mask.reshape(b, -1).sum(axis=1)
    cut = n // 4
    sums = np.concatenate(
        [np.zeros((b, 1)), np.cumsum(np.where(np.isfinite(flat), flat, 0.0), axis=1)], axis=1
    )
    rows = np.arange(b)
    return np.asarray((sums[rows, n - cut] - sums[rows, cut]) / (n - 2 * cut))


def _variance_matched(table: Table) -> Table:
    """The table a two-stage bootstrap of a mean draws from: each layout's mean shrunk towards the
    grand mean by ``c`` and its deviations from it scaled by ``sqrt(k_i / (k_i - 1))``.

    Drawn naively (data as they are, both stages with replacement), the second stage adds the
    within-layout variance once more, though the layout means already carry it: the bootstrap
    variance of the grand mean is then ``B + W`` where the one-stage cluster bootstrap's, ``B =
    sum k_i**2 (m_i - m)**2 / N**2``, is the right one, and ``W = sum k_i s_i**2 / N**2`` (``s_i``
    layout i's SD, ddof 1) is counted twice; a 95% interval covered 97-99% on beta-binomial
    layouts (intraclass correlation 0.1-0.3, 5 episodes per layout). With ``c = sqrt(max(0, 1 -
    W / B))`` the two stages add up to ``max(B, W)``: ``B`` as it should be, and never less than
    the within-layout noise alone (when the layout means happen to agree). The construction is the
    residual two-level bootstrap of Davison & Hinkley (1997, sec. 3.8) and Carpenter, Goldstein &
    Rasbash (2003): shrunk layout effects, rescaled within-layout residuals.
    """
    values, sizes = table
    mask = _mask(sizes, values.shape[1])
    n = sizes.sum()
    means = np.where(mask, values, 0.0).sum(axis=1) / sizes
    grand = float((means * sizes).sum() / n)
    residuals = np.where(mask, values - means[:, None], 0.0)
    ddof1 = np.maximum(sizes - 1, 1)
    between = float((sizes**2 * (means - grand) ** 2).sum() / n**2)
    within = float((sizes * (residuals**2).sum(axis=1) / ddof1).sum() / n**2)
    shrink = math.sqrt(max(0.0, 1.0 - within / between)) if between > 0 else 0.0
    scale = np.sqrt(np.where(sizes > 1, sizes / ddof1, 0.0))
    return (grand + shrink * (means - grand))[:, None] + residuals * scale[:, None], sizes


def _interval(
    table: Table, statistic: str, confidence: float, n_boot: int, seed: int, resample: str
) -> tuple[float, float, float]:
    """(estimate, low, high): the statistic of ``table`` and its percentile bootstrap interval."""
    confidence = _check_confidence(confidence)
    n_boot = check_int("n_boot", n_boot, 1)
    seed = check_int("seed", seed, 0)
    kernel = _ratio if statistic == "mean" else _iqm
    estimate = float(kernel(table[0][None], _mask(table[1], table[0].shape[1])[None])[0])
    drawn_from = _variance_matched(table) if resample == "layouts+within" and statistic == "mean" else table
    replicates = _replicates(drawn_from, kernel, resample, n_boot, np.random.default_rng(seed))
    tail = (1.0 - confidence) / 2.0
    low, high = np.quantile(replicates, [tail, 1.0 - tail])
    return estimate, float(low), float(high)


def layout_rate_interval(
    clusters: Iterable[Iterable[Any]],
    confidence: float = 0.95,
    n_boot: int = 4000,
    seed: int = 0,
    resample: str = "layouts+within",
) -> tuple[float, float, float]:
    """A success rate over a suite's layouts and its two-stage bootstrap interval.

    Parameters
    ----------
    clusters : iterable of iterable of bool
        ``clusters[i]``: the outcomes of layout i's episodes (bools, or 0/1).
    confidence : float, optional
        Two-sided level, ``0 < confidence < 1`` (default 0.95).
    n_boot : int, optional
        Bootstrap replicates, ``>= 1`` (default 4000).
    seed : int, optional
        Seed of ``numpy.random.default_rng``, ``>= 0``; the result is a deterministic function of
        the arguments.
    resample : {"layouts+within", "layouts", "within"}, optional
        ``"layouts+within"`` (default): layouts with replacement, then episodes with replacement
        within each drawn layout, variance-matched (see Notes); ``"layouts"``: whole layouts (the
        one-stage cluster bootstrap); ``"within"``: episodes within each layout, the layouts kept
        (an interval for this suite, not for the population of layouts it was drawn from).

    Returns
    -------
    (rate, low, high) : tuple of float
        Successes over episodes (each episode weighs the same) and the percentile interval,
        within [0, 1].

    Raises
    ------
    ValueError
        No layout holds an episode, an outcome is not boolean, or ``confidence``, ``n_boot``,
        ``seed`` or ``resample`` is out of range (each named with the allowed values).

    Notes
    -----
    Resampling both stages as the data are counts the within-layout variance twice (the layout
    means already carry it) and over-covers; the stages are variance-matched so that the
    bootstrap variance of the rate is the layout-level one (details in the private
    ``_variance_matched``; Davison & Hinkley 1997, sec. 3.8; Carpenter, Goldstein & Rasbash 2003,
    J. R. Statist. Soc. C 52, 431-443). Coverage on beta-binomial layouts is checked in
    ``tests/test_clustered_statistics.py``.
    """
    resample = check_choice("resample", resample, SCHEMES)
    table = _layout_table("clusters", clusters, binary=True)
    _require_data("clusters", table)
    rate, low, high = _interval(table, "mean", confidence, n_boot, seed, resample)
    return rate, max(0.0, low), min(1.0, high)


def layout_mean_interval(
    clusters: Iterable[Iterable[float]],
    confidence: float = 0.95,
    n_boot: int = 4000,
    seed: int = 0,
    resample: str = "layouts+within",
) -> tuple[float, float, float]:
    """A continuous metric's mean over a suite's layouts (e.g. minimum clearance, time to goal)
    and its two-stage bootstrap interval: :func:`layout_rate_interval` for finite numbers.

    Returns
    -------
    (mean, low, high) : tuple of float
        The mean over episodes and its percentile interval.
    """
    resample = check_choice("resample", resample, SCHEMES)
    table = _layout_table("clusters", clusters, binary=False)
    _require_data("clusters", table)
    return _interval(table, "mean", confidence, n_boot, seed, resample)


def interquartile_mean(values: Iterable[float]) -> float:
    """rliable's interquartile mean: ``scipy.stats.trim_mean(values, 0.25)`` (the mean of the
    sorted values from ``int(n / 4)`` to ``n - int(n / 4)``); NaN when empty."""
    x = _as_finite("values", values)
    if x.size == 0:
        return math.nan
    return float(_iqm(x[None], np.ones((1, x.size), dtype=bool))[0])


#: replicates x runs x layouts per bootstrap chunk
_CHUNK = 2**22


def run_aggregate_interval(
    runs: Sequence[Iterable[Iterable[Any]]],
    strata: Sequence[Hashable] | None = None,
    statistic: str = "iqm",
    confidence: float = 0.95,
    n_boot: int = 4000,
    seed: int = 0,
    resample: str = "layouts",
) -> tuple[float, float, float]:
    """The IQM (or mean) over runs of a learned policy (training seeds), each run scored on a
    suite's layouts, with a bootstrap interval stratified by layout group.

    rliable's unit is one score per (task, run): a run's mean score over its evaluation episodes,
    ``scores[n][m]`` in ``rliable.metrics.aggregate_iqm``, whose IQM is
    ``scipy.stats.trim_mean(scores, 0.25, axis=None)`` over the (run, task) matrix; its
    ``library.StratifiedBootstrap`` re-draws runs within each task (Agarwal et al. 2021, NeurIPS,
    google-research/rliable ``rliable/metrics.py`` and ``library.py``). Here a score is run r's
    success rate (or metric mean) over the layouts of one stratum (the whole split by default, or a
    tier or family per layout): one score per (stratum, run). Scoring each (layout, run) pair
    instead makes every score 0 or 1 at one episode per layout, and the IQM of 0/1 scores is
    about ``clip((p - 0.25) / 0.5, 0, 1)``: 1.0 for a policy at 78% and for one at 97%.

    Parameters
    ----------
    runs : sequence of sequences of sequences
        ``runs[r][i]``: run r's episodes on layout i (successes as bools or 0/1, or a metric's
        finite values); every run on the same layouts, in the same order.
    strata : sequence of hashable, optional
        The stratum of each layout (``len(strata)`` layouts), e.g. its tier; default one stratum.
    statistic : {"iqm", "mean"}, optional
        rliable's interquartile mean of the (stratum, run) scores (default), or their mean. With
        fewer than 4 scores ``trim_mean(x, 0.25)`` trims nothing and the two agree.
    confidence, n_boot, seed
        As in :func:`layout_rate_interval`.
    resample : {"layouts", "runs"}, optional
        ``"layouts"`` (default): within each stratum the layouts are re-drawn with replacement, one
        draw for every run (the runs played the same layouts, so a hard layout is hard for each of
        them): the uncertainty from the finite suite, the trained runs as they are.
        ``"runs"``: rliable's stratified bootstrap, the runs re-drawn within each stratum, the
        layouts kept: the uncertainty from the training seeds (coarse with 3-5 runs).

    Returns
    -------
    (estimate, low, high) : tuple of float
        The statistic and its percentile interval.

    Raises
    ------
    ValueError
        No run, runs on different numbers of layouts, a layout without episodes, ``strata`` of the
        wrong length, or a bad ``statistic``, ``resample``, ``confidence``, ``n_boot`` or ``seed``.
    """
    statistic = check_choice("statistic", statistic, ("iqm", "mean"))
    resample = check_choice("resample", resample, ("layouts", "runs"))
    confidence = _check_confidence(confidence)
    n_boot = check_int("n_boot", n_boot, 1)
    seed = check_int("seed", seed, 0)
    sums, counts = _run_layout_sums(runs)
    n_runs, n_layouts = sums.shape
    labels = [0] * n_layouts if strata is None else list(strata)
    if len(labels) != n_layouts:
        raise ValueError(f"strata has {len(labels)} entries; the runs played {n_layouts} layouts")
    groups = [np.flatnonzero([x == g for x in labels]) for g in dict.fromkeys(labels)]
    kernel = _ratio if statistic == "mean" else _iqm

    def aggregate(scores: NDArray[np.float64]) -> NDArray[np.float64]:
        # scores (b, runs, strata) -> (b,): the statistic over every (stratum, run) score
        flat = scores.reshape(scores.shape[0], -1)
        return kernel(flat, np.ones(flat.shape, dtype=bool))

    def scored(picks: NDArray[np.int64]) -> NDArray[np.float64]:
        # picks (b, L): layout indices; each (run, stratum) score its successes over its episodes
        return np.stack(
            [sums[:, picks[:, g]].sum(axis=2).T / counts[:, picks[:, g]].sum(axis=2).T for g in groups],
            axis=2,
        )

    everything = np.arange(n_layouts)[None]
    observed = scored(everything)
    rng = np.random.default_rng(seed)
    out = np.empty(n_boot)
    step = max(1, _CHUNK // max(1, n_runs * n_layouts))
    for start in range(0, n_boot, step):
        b = min(step, n_boot - start)
        if resample == "layouts":
            picks = np.broadcast_to(everything, (b, n_layouts)).copy()
            for g in groups:
                picks[:, g] = g[rng.integers(0, g.size, size=(b, g.size))]
            out[start : start + b] = aggregate(scored(picks))
        else:
            drawn = rng.integers(0, n_runs, size=(b, n_runs, len(groups)))
            out[start : start + b] = aggregate(np.take_along_axis(observed[0][None], drawn, axis=1))
    tail = (1.0 - confidence) / 2.0
    low, high = np.quantile(out, [tail, 1.0 - tail])
    return float(aggregate(observed)[0]), float(low), float(high)


def _run_layout_sums(
    runs: Sequence[Iterable[Iterable[Any]]],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(sums, counts), shape (runs, layouts): each run's episode totals and episode counts per layout."""
    if len(runs) == 0:
        raise ValueError("runs is empty; an aggregate over runs needs at least one run")
    sums, counts = [], []
    for r, layouts in enumerate(runs):
        rows = [_as_finite(f"runs[{r}][{i}]", episodes) for i, episodes in enumerate(layouts)]
        for i, row in enumerate(rows):
            if row.size == 0:
                raise ValueError(f"runs[{r}][{i}] holds no episode; every run plays every layout")
        sums.append([row.sum() for row in rows])
        counts.append([row.size for row in rows])
    if len({len(row) for row in sums}) != 1 or not sums[0]:
        raise ValueError(
            f"runs played {[len(row) for row in sums]} layouts; every run plays the same layouts (at least one)"
        )
    return np.asarray(sums, dtype=np.float64), np.asarray(counts, dtype=np.float64)
