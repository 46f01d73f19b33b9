"""From episode records to numbers: intervals and tests (:mod:`~evaluation.stats.statistics`),
the same with the layout as the unit (:mod:`~evaluation.stats.clustered`,
:mod:`~evaluation.stats.layout_tests`), families of tests and their power
(:mod:`~evaluation.stats.families`), a suite run's tables (:mod:`~evaluation.stats.suite_statistics`) and their designs
(:mod:`~evaluation.stats.designs`),
cells, leaderboard rows and paired comparisons (:mod:`~evaluation.stats.aggregate`), a run's data
for the renderers (:class:`~evaluation.stats.run_data.RunData`) a sweep's robustness profiles
(:mod:`~evaluation.stats.robustness`), the sim-to-sim comparison of two plants
(:mod:`~evaluation.stats.transfer`) and how far a partial run is (:mod:`~evaluation.stats.progress`). No output format is known here.

The package is their face: the public names of its modules (their ``__all__``), importable from
here (tests/test_architecture.py checks the list), except ``aggregate``, which names the module
(the function is :func:`evaluation.stats.aggregate.aggregate`).
"""

from __future__ import annotations

from evaluation.stats.aggregate import Cell, DistanceSummary, leaderboard, paired_comparisons, pooled_rate
from evaluation.stats.clustered import (
    interquartile_mean,
    layout_mean_interval,
    layout_rate_interval,
    run_aggregate_interval,
)
from evaluation.stats.designs import (
    ALL,
    EVERY_PAIR,
    declared_pairs,
    pair_label,
    pooled_families,
    pooled_reference_pairs,
    reference_design,
    reference_pairs,
    tuned_pairs,
)
from evaluation.stats.families import (
    CorrectedTest,
    FamilyResult,
    HypothesisFamily,
    PowerStatement,
    detectable_difference,
    layouts_needed,
    paired_power,
    power_statement,
)
from evaluation.stats.layout_tests import (
    EXACT_FLIPS,
    LayoutComparison,
    layout_sign_flip_test,
    paired_means_by_layout,
    paired_rates_by_layout,
    sign_flip_p_text,
)
from evaluation.stats.progress import Progress, planned_episodes
from evaluation.stats.robustness import TAIL_SHARE, AxisProfile, LevelCost, LevelRow, level_costs, profiles
from evaluation.stats.run_data import RunData
from evaluation.stats.statistics import (
    PairedComparison,
    bootstrap_mean_interval,
    bootstrap_tail_interval,
    cluster_bootstrap_rate,
    holm_adjusted,
    paired_comparison,
    tail_mean,
    wilson_interval,
)
from evaluation.stats.suite_statistics import (
    BREAKDOWNS,
    MEASURES,
    METRICS,
    OUTCOMES,
    Measure,
    breakdown,
    is_suite_run,
    layout_summary,
    measure_table,
    suite_mean_interval,
    suite_rate_interval,
    suite_tables,
)
from evaluation.stats.transfer import (
    RANK_RESAMPLES,
    RANK_SEED,
    TRANSFER_ALPHA,
    Ordering,
    PlantRow,
    RankAgreement,
    check_same_protocol,
    kendall_tau_b,
    ordering_verdict,
    orderings,
    plant_differences,
    rank_agreement,
    restricted,
    run_progress,
    significant_changes,
)

__all__ = [
    "PairedComparison",
    "cluster_bootstrap_rate",
    "holm_adjusted",
    "bootstrap_mean_interval",
    "bootstrap_tail_interval",
    "paired_comparison",
    "tail_mean",
    "wilson_interval",
    "interquartile_mean",
    "layout_mean_interval",
    "layout_rate_interval",
    "run_aggregate_interval",
    "EXACT_FLIPS",
    "LayoutComparison",
    "layout_sign_flip_test",
    "paired_means_by_layout",
    "paired_rates_by_layout",
    "sign_flip_p_text",
    "CorrectedTest",
    "FamilyResult",
    "HypothesisFamily",
    "PowerStatement",
    "detectable_difference",
    "layouts_needed",
    "paired_power",
    "power_statement",
    "ALL",
    "EVERY_PAIR",
    "declared_pairs",
    "pair_label",
    "pooled_families",
    "pooled_reference_pairs",
    "reference_design",
    "tuned_pairs",
    "reference_pairs",
    "BREAKDOWNS",
    "METRICS",
    "MEASURES",
    "OUTCOMES",
    "Measure",
    "breakdown",
    "is_suite_run",
    "layout_summary",
    "suite_mean_interval",
    "suite_rate_interval",
    "suite_tables",
    "measure_table",
    "Cell",
    "DistanceSummary",
    "leaderboard",
    "paired_comparisons",
    "pooled_rate",
    "RunData",
    "TAIL_SHARE",
    "AxisProfile",
    "LevelCost",
    "LevelRow",
    "level_costs",
    "profiles",
    "TRANSFER_ALPHA",
    "Ordering",
    "PlantRow",
    "check_same_protocol",
    "ordering_verdict",
    "orderings",
    "plant_differences",
    "RANK_RESAMPLES",
    "RANK_SEED",
    "Progress",
    "RankAgreement",
    "kendall_tau_b",
    "planned_episodes",
    "rank_agreement",
    "restricted",
    "run_progress",
    "significant_changes",
]
