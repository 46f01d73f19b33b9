"""Statistics with the layout as the unit (evaluation/stats/clustered.py, evaluation/stats/layout_tests.py,
evaluation/stats/families.py): two-stage intervals that cover, a paired test whose size holds when
outcomes cluster on layouts, power statements a simulation confirms, named families of tests.

Monte Carlo tolerances: a coverage or rejection rate estimated from N simulated data sets has a
standard error sqrt(q (1 - q) / N) around its true value q; every check allows 3 of them (a
false alarm in about 1 run in 370). With N = 200 that is +-0.046 around 0.95; with N = 1000
(the slow tests) +-0.021.
"""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np
import pytest
from scipy import stats

from evaluation.stats.clustered import (
    interquartile_mean,
    layout_mean_interval,
    layout_rate_interval,
    run_aggregate_interval,
)
from evaluation.stats.families import (
    HypothesisFamily,
    detectable_difference,
    layouts_needed,
    paired_power,
    power_statement,
)
from evaluation.stats.layout_tests import (
    layout_sign_flip_test,
    paired_means_by_layout,
    paired_rates_by_layout,
    sign_flip_p_text,
)
from evaluation.stats.statistics import bootstrap_mean_interval, paired_comparison


def _tolerance(q: float, n: int) -> float:
    """Three Monte Carlo standard errors of a rate q estimated from n data sets."""
    return 3.0 * math.sqrt(q * (1.0 - q) / n)


def _beta_binomial(
    rng: np.random.Generator, layouts: int, episodes: int, rate: float, icc: float
) -> np.ndarray:
    """Outcomes (layouts, episodes): layout i succeeds with probability p_i ~ Beta with mean
    ``rate`` and intraclass correlation ``icc`` (a + b = 1 / icc - 1)."""
    total = 1.0 / icc - 1.0
    p = rng.beta(rate * total, (1.0 - rate) * total, size=layouts)
    return rng.random((layouts, episodes)) < p[:, None]


def _coverage(draws: int, icc: float, seed: int) -> tuple[float, float]:
    """Coverage of the two-stage interval and of the episode-level bootstrap (episodes taken as
    independent) on beta-binomial layouts: 60 layouts x 5 episodes, true rate 0.6."""
    rng = np.random.default_rng(seed)
    two_stage = episode_level = 0
    for i in range(draws):
        y = _beta_binomial(rng, 60, 5, 0.6, icc)
        _, low, high = layout_rate_interval(y, n_boot=1000, seed=i)
        two_stage += low <= 0.6 <= high
        e_low, e_high = bootstrap_mean_interval(y.ravel().astype(float), resamples=1000, seed=i)
        episode_level += e_low <= 0.6 <= e_high
    return two_stage / draws, episode_level / draws


def test_the_two_stage_rate_interval_covers_and_the_episode_level_one_does_not() -> None:
    """Intraclass correlation 0.3, 5 episodes per layout (a design effect of 2.2): the two-stage
    95% interval covers 0.6 in 95% +- 4.6 points of 200 samples; the episode-level bootstrap, whose
    variance is 2.2 times too small, covers about 81%, below that band."""
    two_stage, episode_level = _coverage(200, 0.3, seed=1)
    assert abs(two_stage - 0.95) <= _tolerance(0.95, 200), two_stage
    assert episode_level < 0.95 - _tolerance(0.95, 200), episode_level


@pytest.mark.slow
@pytest.mark.parametrize("icc", [0.1, 0.3, 0.6])
def test_the_two_stage_rate_interval_covers_1000_samples(icc: float) -> None:
    """1000 samples: 95% +- 2.1 points. At icc 0.1 the naive two-stage bootstrap (both stages
    with replacement, no variance matching) covers 98.9% (measured), outside this band."""
    two_stage, _ = _coverage(1000, icc, seed=2)
    assert abs(two_stage - 0.95) <= _tolerance(0.95, 1000), two_stage


def test_the_two_stages_add_up_to_the_layout_level_variance() -> None:
    """On one sample (200 layouts x 5, icc 0.1) the two-stage interval is as wide as the one-stage
    cluster bootstrap's (whose variance is the layout-level one) within 5%: drawing episodes again
    does not count the within-layout variance twice (the naive two-stage interval is 23% wider)."""
    y = _beta_binomial(np.random.default_rng(3), 200, 5, 0.6, 0.1)
    _, low, high = layout_rate_interval(y, n_boot=4000, seed=1)
    _, c_low, c_high = layout_rate_interval(y, n_boot=4000, seed=1, resample="layouts")
    assert (high - low) / (c_high - c_low) == pytest.approx(1.0, abs=0.05)


def test_the_two_stage_interval_keeps_the_episodes_noise_when_layout_means_agree() -> None:
    """Every layout 3 successes in 5: resampling whole layouts gives a zero-width interval, the
    two-stage one keeps the binomial noise of the episodes."""
    y = np.tile([True, True, True, False, False], (40, 1))
    rate, low, high = layout_rate_interval(y, resample="layouts")
    assert (rate, low, high) == (0.6, 0.6, 0.6)
    rate, low, high = layout_rate_interval(y)
    assert rate == 0.6 and low < 0.55 and high > 0.65 and 0.0 <= low and high <= 1.0


def test_the_mean_interval_covers_on_clustered_normal_data() -> None:
    """y_ij = 1 + b_i + e_ij, b ~ N(0, 1), e ~ N(0, 2**2) (icc 0.2), 50 layouts x 4: the two-stage
    interval of the mean covers 1 in 95% +- 4.6 points of 200 samples."""
    rng = np.random.default_rng(4)
    covered = 0
    for i in range(200):
        y = 1.0 + rng.normal(size=(50, 1)) + 2.0 * rng.normal(size=(50, 4))
        _, low, high = layout_mean_interval(y, n_boot=1000, seed=i)
        covered += low <= 1.0 <= high
    assert abs(covered / 200 - 0.95) <= _tolerance(0.95, 200), covered / 200


def test_intervals_are_seeded_and_deterministic() -> None:
    y = _beta_binomial(np.random.default_rng(5), 200, 5, 0.5, 0.3)
    first = layout_rate_interval(y, n_boot=4000, seed=7)
    assert layout_rate_interval(y.tolist(), n_boot=4000, seed=7) == first
    assert layout_rate_interval(y, n_boot=4000, seed=8) != first
    assert first[0] == y.mean()


def test_ragged_layouts_weigh_every_episode_once() -> None:
    """Layouts of different sizes: the rate is successes over episodes, and an empty layout is left out."""
    clusters = [[True, True, True, False], [False], [], [True, False]]
    rate, low, high = layout_rate_interval(clusters, n_boot=500)
    assert rate == pytest.approx(4 / 7) and 0.0 <= low <= rate <= high <= 1.0
    mean, _, _ = layout_mean_interval([[1.0, 2.0, 3.0], [10.0]])
    assert mean == pytest.approx(4.0)


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 7, 8, 11, 40])
def test_the_interquartile_mean_is_rliables(n: int) -> None:
    x = np.random.default_rng(n).normal(size=n)
    assert interquartile_mean(x) == pytest.approx(stats.trim_mean(x, 0.25), rel=1e-12)


def test_the_run_aggregate_scores_each_run_and_redraws_layouts_within_strata() -> None:
    """One score per (stratum, run), rliable's trim_mean over them; the layouts are re-drawn
    within each stratum, one draw for every run; ``"runs"`` re-draws the runs (rliable's
    stratified bootstrap), which has no width when every run scores alike."""
    rng = np.random.default_rng(3)
    runs = [[[bool(x)] for x in rng.random(40) < p] for p in (0.5, 0.6, 0.7, 0.8, 0.9)]  # 5 runs x 40 layouts
    rates = np.array([np.mean([e[0] for e in run]) for run in runs])
    iqm, low, high = run_aggregate_interval(runs, n_boot=1000)
    assert iqm == pytest.approx(stats.trim_mean(rates, 0.25)) and low < iqm < high
    assert run_aggregate_interval(runs, statistic="mean", n_boot=10)[0] == pytest.approx(rates.mean())
    strata = ["easy"] * 20 + ["hard"] * 20
    by_stratum = np.array(
        [[np.mean([e[0] for e in run[a:b]]) for a, b in ((0, 20), (20, 40))] for run in runs]
    )
    assert run_aggregate_interval(runs, strata, n_boot=10)[0] == pytest.approx(
        stats.trim_mean(by_stratum.ravel(), 0.25)
    )
    alike = [[[True], [False], [True]]] * 4
    assert run_aggregate_interval(alike, resample="runs", n_boot=200) == pytest.approx((2 / 3, 2 / 3, 2 / 3))
    _, low, high = run_aggregate_interval(alike, n_boot=200)
    assert low < 2 / 3 < high  # the layouts differ, so re-drawing them moves every run's rate


def test_the_random_sign_flip_tests_floor_is_printed_as_a_bound() -> None:
    # 30 layouts all +1: no random pattern is as extreme, p is the floor 1/(1 + permutations)
    p, exact = layout_sign_flip_test([[1.0]] * 30, permutations=999)
    assert (p, exact) == (1 / 1000, False)
    assert sign_flip_p_text(p, exact, permutations=999) == "<= 0.001"
    assert sign_flip_p_text(4.999750012499375e-05, False) == "<= 5e-05"  # the default 20,000
    assert sign_flip_p_text(2 / 1000, False, permutations=999) == "= 0.002"  # above the floor: a value
    assert sign_flip_p_text(1 / 1000, True, permutations=999) == "= 0.001"  # an exact test has no floor
    assert sign_flip_p_text(0.456227188640568, False, digits=4) == "= 0.4562"
    with pytest.raises(ValueError, match="permutations=0"):
        sign_flip_p_text(0.5, False, permutations=0)


def test_the_sign_flip_test_on_hand_examples() -> None:
    """Layout totals 1, 2, 3: of the 8 sign patterns, 2 reach |sum| = 6, so p = 1/4 exactly.
    20 layouts each +1: 2 of 2**20 patterns reach 20; with 999 random patterns none does and
    p = (1 + 0) / (1 + 999)."""
    assert layout_sign_flip_test([[1.0], [1.0, 1.0], [2.0, 1.0, 0.0]]) == (0.25, True)
    assert layout_sign_flip_test([[0.5, 0.5]] * 20, permutations=999) == (1 / 1000, False)
    assert layout_sign_flip_test([[0.0, 0.0], [1.0, -1.0]]) == (1.0, True)


def _paired_layouts(
    rng: np.random.Generator, layouts: int, episodes: int, discordance: float, share_a: float, spread: float
) -> tuple[np.ndarray, np.ndarray]:
    """Paired outcomes on clustered layouts: layout i's units are discordant with probability
    psi_i ~ Beta(mean ``discordance``, a + b = ``spread``) and a discordant unit favours a with
    probability q_i ~ Beta(mean ``share_a``, a + b = ``spread``); concordant units succeed or fail
    for both with probability 1/2."""
    psi = rng.beta(spread * discordance, spread * (1 - discordance), size=layouts)[:, None]
    q = rng.beta(spread * share_a, spread * (1 - share_a), size=layouts)[:, None]
    discordant = rng.random((layouts, episodes)) < psi
    a_wins = rng.random((layouts, episodes)) < q
    both = rng.random((layouts, episodes)) < 0.5
    a = np.where(discordant, a_wins, both)
    b = np.where(discordant, ~a_wins, both)
    return a, b


def _icc_of(discordance: float, share_a: float, spread: float) -> float:
    """Intraclass correlation of the unit differences d = a - b under :func:`_paired_layouts`:
    Var(E[d | layout]) / Var(d), from the two Beta laws' moments."""
    delta = discordance * (2 * share_a - 1)
    psi2 = discordance**2 + discordance * (1 - discordance) / (spread + 1)
    q2 = share_a**2 + share_a * (1 - share_a) / (spread + 1)
    return (psi2 * (4 * q2 - 4 * share_a + 1) - delta**2) / (discordance - delta**2)


def test_the_clustered_test_holds_its_size_where_mcnemar_does_not() -> None:
    """No true difference, discordance 0.3 with an icc of 0.33 (60 layouts x 5): the layout-level
    test rejects at alpha 0.05 in 5% +- 3.3 points of 400 data sets; the exact McNemar test on the
    same pairs, which takes them as independent, rejects far more often."""
    rng = np.random.default_rng(6)
    draws, clustered, mcnemar = 400, 0, 0
    for i in range(draws):
        a, b = _paired_layouts(rng, 60, 5, 0.3, 0.5, 1.0)
        clustered += paired_rates_by_layout(a, b, n_boot=1, permutations=1000, seed=i).p_value <= 0.05
        mcnemar += paired_comparison(a.ravel(), b.ravel()).p_value <= 0.05
    assert abs(clustered / draws - 0.05) <= _tolerance(0.05, draws), clustered / draws
    assert mcnemar / draws > 0.05 + _tolerance(0.05, draws), mcnemar / draws


def test_the_power_statement_agrees_with_a_simulation() -> None:
    """The difference the power statement finds with 80% power (60 layouts x 5, discordance 0.3,
    its icc) is found in 80% +- 6 points of 400 simulated data sets."""
    spread, psi = 4.0, 0.3
    icc = _icc_of(psi, 0.5, spread)
    delta = detectable_difference(60, 5, discordance=psi, icc=icc)
    share_a = (1 + delta / psi) / 2
    predicted = paired_power(delta, 60, 5, discordance=psi, icc=_icc_of(psi, share_a, spread))
    assert predicted == pytest.approx(0.8, abs=0.02)  # the icc moves a little under the alternative
    rng = np.random.default_rng(7)
    draws = 400
    found = sum(
        paired_rates_by_layout(
            *_paired_layouts(rng, 60, 5, psi, share_a, spread), n_boot=1, permutations=1000, seed=i
        ).p_value
        <= 0.05
        for i in range(draws)
    )
    assert abs(found / draws - predicted) <= _tolerance(predicted, draws), (found / draws, predicted)


@pytest.mark.slow
def test_the_metric_test_size_and_power_agree_with_the_formula() -> None:
    """Continuous differences d_ij = delta + u_i + e_ij (u ~ N(0, 0.5**2), e ~ N(0, 1)), 40
    layouts x 3, a family of 4: size at alpha/m and power at the detectable difference, each
    over 1000 data sets."""
    sd, icc = math.sqrt(1.25), 0.25 / 1.25
    delta = detectable_difference(40, 3, sd=sd, icc=icc, family_size=4)
    rng = np.random.default_rng(8)
    for shift, expected in ((0.0, 0.05 / 4), (delta, 0.8)):
        hits = 0
        for i in range(1000):
            d = shift + 0.5 * rng.normal(size=(40, 1)) + rng.normal(size=(40, 3))
            hits += (
                paired_means_by_layout(d, np.zeros_like(d), n_boot=1, permutations=2000, seed=i).p_value
                <= 0.05 / 4
            )
        assert abs(hits / 1000 - expected) <= _tolerance(expected, 1000), (shift, hits / 1000)


def test_the_power_formula_by_hand() -> None:
    """200 layouts x 2 pairs, discordance 0.3, icc 0.5, difference 0.1, one test at 0.05: a
    layout's total has mean mu = 0.2 and variance v1 = 2 (0.3 - 0.01)(1 + 0.5) = 0.87; the test's
    reference SD is s0 = sqrt(v1 + mu**2); the power is Phi((sqrt(L) mu - z s0) / sqrt(v1 (1 - c)**2
    + z**2 v1**2 / (2 L s0**2))), c = z mu / (sqrt(L) s0). Connor's (1987) form, without the two
    corrections, is lower."""
    n, mu, v1, z = 200, 0.2, 0.87, NormalDist().inv_cdf(0.975)
    s0 = math.sqrt(v1 + mu**2)
    c = z * mu / (math.sqrt(n) * s0)
    by_hand = NormalDist().cdf(
        (math.sqrt(n) * mu - z * s0) / math.sqrt(v1 * (1 - c) ** 2 + z**2 * v1**2 / (2 * n * s0**2))
    )
    power = paired_power(0.1, n, 2, discordance=0.3, icc=0.5)
    assert power == pytest.approx(by_hand, rel=1e-12)
    connor = NormalDist().cdf((math.sqrt(n) * mu - z * s0) / math.sqrt(v1))
    assert connor < power


def test_layouts_needed_and_detectable_difference_are_inverse() -> None:
    """The suite size for a 10-point difference: the power reaches 80% at that size and not one
    layout before; at that size the detectable difference is at most 10 points. Holm's first step
    is Bonferroni's: a family of 10 at alpha 0.05 is one test at 0.005."""
    design = {"discordance": 0.3, "icc": 0.3, "family_size": 10}
    needed = layouts_needed(0.10, 5, **design)
    assert paired_power(0.10, needed, 5, **design) >= 0.8 > paired_power(0.10, needed - 1, 5, **design)
    assert detectable_difference(needed, 5, **design) <= 0.10 < detectable_difference(needed - 1, 5, **design)
    assert detectable_difference(
        200, 5, discordance=0.3, icc=0.3, family_size=1, alpha=0.005
    ) == pytest.approx(detectable_difference(200, 5, **design))
    assert math.isnan(detectable_difference(3, 1, discordance=0.05))  # no allowed difference gets there


def test_a_family_is_corrected_with_holm_and_reported_by_name() -> None:
    """p = 0.01, 0.04, 0.03, 0.005 (m = 4): Holm's step-down compares 0.005 <= 0.05/4 (reject),
    0.01 <= 0.05/3 (reject), 0.03 <= 0.05/2 (no: stop); adjusted 0.03, 0.06, 0.06, 0.02."""
    family = HypothesisFamily("success, test split", ("a-b", "a-c", "b-c", "a-d"))
    result = family.correct({"a-b": 0.01, "a-c": 0.04, "b-c": 0.03, "a-d": 0.005})
    assert (result.family, result.size, result.alpha) == ("success, test split", 4, 0.05)
    assert [t.comparison for t in result.tests] == ["a-b", "a-c", "b-c", "a-d"]
    assert [t.p_holm for t in result.tests] == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert [t.rejected for t in result.tests] == [True, False, False, True]
    # a comparison that could not be run still counts in m (declared before the data)
    three = HypothesisFamily("three", ("x", "y", "z")).correct({"x": 0.01, "y": math.nan, "z": 0.02})
    assert three.size == 3 and math.isnan(three.tests[1].p_holm) and not three.tests[1].rejected
    assert [three.tests[0].p_holm, three.tests[2].p_holm] == pytest.approx([0.03, 0.04])
    # one test run twice on the same data is one hypothesis
    twins = HypothesisFamily("twins", ("x", "y", "y-twin")).correct(
        {"x": 0.01, "y": 0.02, "y-twin": 0.02}, same={"y-twin": "y"}
    )
    assert twins.size == 2 and [t.p_holm for t in twins.tests] == pytest.approx([0.02, 0.02, 0.02])


def test_a_table_states_its_power() -> None:
    rng = np.random.default_rng(9)
    comparisons = [
        paired_rates_by_layout(*_paired_layouts(rng, 50, 4, 0.3, 0.5, 4.0), n_boot=10) for _ in range(3)
    ]
    family = HypothesisFamily("target_reaching/test: success", ("a-b", "a-c", "b-c"))
    statement = power_statement(comparisons, family)
    assert statement.layouts == 50 and statement.per_layout == 4.0 and statement.family_size == 3
    assert statement.alpha_per_test == pytest.approx(0.05 / 3)
    assert statement.discordance == sorted(c.discordance for c in comparisons)[1]
    assert statement.difference == pytest.approx(
        detectable_difference(50, 4, discordance=statement.discordance, icc=statement.icc, family_size=3)
    )
    text = statement.sentence()
    assert "'target_reaching/test: success'" in text and "m = 3" in text and "alpha/m = 0.0167" in text


def test_a_paired_comparison_reports_its_design() -> None:
    a = [[True, True, False], [False, False], [True]]
    b = [[False, True, False], [True, False], [True]]
    c = paired_rates_by_layout(a, b, n_boot=200)
    assert (c.layouts, c.units, c.mean_a, c.mean_b, c.difference) == (3, 6, 0.5, 0.5, 0.0)
    assert c.discordance == pytest.approx(2 / 6) and (c.p_value, c.exact) == (1.0, True)
    assert -1.0 <= c.low <= 0.0 <= c.high <= 1.0
    m = paired_means_by_layout([[1.0, 2.0], [3.0]], [[0.5, 1.0], [3.5]])
    assert m.difference == pytest.approx(1.0 / 3) and math.isnan(m.discordance)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: layout_rate_interval([]), r"clusters is empty"),
        (lambda: layout_rate_interval([[], []]), r"clusters is empty"),
        (lambda: layout_mean_interval([[1.0], [math.nan]]), r"clusters\[1\]\[0\]=nan is not allowed"),
        (lambda: layout_rate_interval([[True, 2]]), r"clusters\[0\]\[1\]=2 is not allowed"),
        (
            lambda: layout_rate_interval([[True]], confidence=1.0),
            r"confidence=1.0 must be .* 0 < confidence < 1",
        ),
        (lambda: layout_rate_interval([[True]], confidence=0), r"confidence=0 must be"),
        (lambda: layout_rate_interval([[True]], n_boot=0), r"n_boot=0 must be an integer >= 1"),
        (lambda: layout_rate_interval([[True]], resample="seeds"), r"resample='seeds' is not one of"),
        (
            lambda: run_aggregate_interval([[[1.0]]], resample="layouts+within"),
            r"resample='layouts\+within' is not one of \['layouts', 'runs'\]",
        ),
        (lambda: run_aggregate_interval([]), r"runs is empty"),
        (lambda: run_aggregate_interval([[[1]], [[1], [0]]]), r"runs played \[1, 2\] layouts"),
        (lambda: run_aggregate_interval([[[1], []]]), r"runs\[0\]\[1\] holds no episode"),
        (
            lambda: run_aggregate_interval([[[1], [0]]], strata=["a"]),
            r"strata has 1 entries; the runs played 2",
        ),
        (lambda: run_aggregate_interval([[[1]]], statistic="median"), r"statistic='median' is not one of"),
        (lambda: paired_rates_by_layout([], []), r"a and b are empty"),
        (lambda: paired_rates_by_layout([[True]], [[True], [False]]), r"1 layouts in a and 2 in b"),
        (
            lambda: paired_rates_by_layout([[True, False]], [[True]]),
            r"a\[0\] and b\[0\] must pair up seed by seed",
        ),
        (lambda: paired_rates_by_layout([[True]], [[True]], n_boot=0), r"n_boot=0"),
        (lambda: paired_rates_by_layout([[True]], [[True]], confidence=1.5), r"confidence=1.5"),
        (lambda: layout_sign_flip_test([[1.0]], permutations=0), r"permutations=0 must be an integer >= 1"),
        (lambda: paired_power(0.1, 50, 5), r"give exactly one"),
        (lambda: paired_power(0.4, 50, 5, discordance=0.3), r"difference=0.4 must be .*<= 0.3"),
        (lambda: paired_power(0.1, 50, 5, sd=1.0, icc=1.5), r"icc=1.5 must be"),
        (lambda: detectable_difference(50, 5, sd=1.0, power=0.3), r"power=0.3 must be .* 0.5 <= power < 1"),
        (lambda: layouts_needed(0.0, 5, sd=1.0), r"difference=0 is not allowed"),
        (lambda: HypothesisFamily("", ("a",)), r"name='' must be a non-empty string"),
        (lambda: HypothesisFamily("f", ()), r"family 'f' declares no comparison"),
        (lambda: HypothesisFamily("f", ("a", "a")), r"declares \['a'\] more than once"),
        (lambda: HypothesisFamily("f", ("a",), alpha=1.0), r"alpha=1.0 must be a number with 0 < alpha < 1"),
        (
            lambda: HypothesisFamily("f", ("a",)).correct({"a": 0.1, "b": 0.2}),
            r"\['b'\] not declared in family 'f'",
        ),
        (lambda: HypothesisFamily("f", ("a", "b")).correct({"a": 0.1}), r"no p-value for \['b'\]"),
        (lambda: HypothesisFamily("f", ("a",)).correct({"a": 1.5}), r"p_values\['a'\]=1.5 must be within"),
        (lambda: power_statement([], HypothesisFamily("f", ("a",))), r"comparisons is empty"),
    ],
)
def test_bad_input_is_refused_by_name(call, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        call()


def test_too_few_layouts_for_the_level_have_no_power() -> None:
    """The exact sign-flip test's smallest p over L layouts is 2 / 2**L: at 5 layouts 0.0625, above
    0.05, so nothing is ever found; the normal approximation alone would promise power there."""
    assert paired_power(0.5, 5, 10, sd=0.1) == 0.0
    assert paired_power(0.5, 6, 10, sd=0.1) > 0.99
    assert paired_power(0.5, 6, 10, sd=0.1, family_size=2) == 0.0  # 2/64 > 0.05/2
    # a metric on 4 layouts: no difference reaches 80% power (NaN, not a refusal of a huge value)
    assert math.isnan(detectable_difference(4, 1, sd=10.0, family_size=2))
    assert layouts_needed(0.5, 10, sd=0.1) == 6
    statement = power_statement(
        [paired_means_by_layout([[1.0], [2.0], [3.0], [5.0]], [[0.0], [0.5], [1.0], [0.0]], n_boot=10)],
        HypothesisFamily("t: metric", ("a-b", "a-c")),
    )
    assert math.isnan(statement.difference)
    assert "smallest p-value over 4 layouts, 2/2^4 = 0.125, is above alpha/m" in statement.sentence()
