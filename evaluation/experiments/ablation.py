"""The ablation: which design choice decides the NMPC's outcome under slip.

Three factors, two levels each, as controller configurations of the same NMPC code:

=========== ================================= =========================================
factor      levels                            what changes
=========== ================================= =========================================
model       learned / nominal                 Koopman model vs slip-free unicycle
margins     paper / widened                   0.015 m vs 3 x the model's calibrated residual
constraints soft / hard                       exact-penalty slacks vs the paper's hard constraints
=========== ================================= =========================================

``python evaluate.py --ablation [FACTOR ...]`` runs the full factorial of the named factors (the
others held at learned / paper / soft) on the paper maps under high slip and writes
``OUT/ablation.md`` (:func:`ablation_markdown`): success per configuration and map with
intervals, and each factor's main effect paired per episode unit (:func:`main_effects`: the
configurations that differ only in that factor, on the same map and seed, a unit counted once).
The published page, docs/ablation.md, is the same report of the published run
(``bash data/publish.sh ablation``), rebuilt by ``python docs/make_pages.py docs/ablation.md``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from controllers.mpc.config import ROBUST_UNCERTAINTY_MARGIN
from evaluation.episodes.records import ran
from evaluation.reports.results import Results
from evaluation.reports.sections import task_label
from evaluation.run.configs import ControllerConfig
from evaluation.stats.families import FamilyResult, HypothesisFamily, PowerStatement, power_statement
from evaluation.stats.layout_tests import paired_means_by_layout, sign_flip_p_text
from evaluation.stats.statistics import wilson_interval
from koopman_envs.checks import check_choice

__all__ = [
    "DEFAULT_LEVELS",
    "FACTORS",
    "MainEffects",
    "ABLATION_TITLE",
    "ablation_configs",
    "ablation_markdown",
    "check_factors",
    "main_effects",
    "main_effects_family",
    "power_note",
    "main_effects_table",
]

#: factor -> level -> (controller name or None, options). The model's two levels must share every
#: other option, so that the factor changes the prediction model alone: both levels are the
#: hand-set NMPC the paper describes, ``koopman-nmpc-v0`` and ``nominal-nmpc-v0`` (the tuned presets
#: differ in horizon and margins, so a factor on them would compare tunings;
#: tests/test_fair_comparison.py checks the two configurations agree)
FACTORS: dict[str, dict[str, tuple[str | None, dict[str, Any]]]] = {
    "model": {"learned": ("koopman-nmpc-v0", {}), "nominal": ("nominal-nmpc-v0", {})},
    "margins": {
        "paper": (None, {"uncertainty_margin": 0.0}),
        "widened": (None, {"uncertainty_margin": ROBUST_UNCERTAINTY_MARGIN}),
    },
    "constraints": {"soft": (None, {"soft_constraints": True}), "hard": (None, {"soft_constraints": False})},
}
#: the report's title (docs/ablation.md's, published or pending)
ABLATION_TITLE = "Ablation: what decides the NMPC's outcome under slip"
#: the level of a factor that is not varied
DEFAULT_LEVELS = {"model": "learned", "margins": "paper", "constraints": "soft"}


def check_factors(factors: Sequence[str] | None) -> list[str]:
    """The factors to vary (all when none are named); ``ValueError`` naming an unknown one."""
    chosen = list(factors) if factors else list(FACTORS)
    for factor in chosen:
        check_choice("ablation factor", factor, FACTORS, sep=" ")
    return list(dict.fromkeys(chosen))


def _levels(config_label: str) -> dict[str, str]:
    return dict(part.split("=") for part in config_label.split(" "))


def ablation_configs(factors: Sequence[str] | None = None) -> list[ControllerConfig]:
    """One configuration per combination of levels, labelled ``model=learned margins=paper constraints=soft``."""
    chosen = check_factors(factors)
    configs = []
    for combo in itertools.product(*(FACTORS[f] for f in chosen)):
        levels = dict(DEFAULT_LEVELS, **dict(zip(chosen, combo)))
        name: str | None = None
        options: dict[str, Any] = {}
        for factor in FACTORS:
            level_name, level_options = FACTORS[factor][levels[factor]]
            name = level_name or name
            options.update(level_options)
        label = " ".join(f"{factor}={levels[factor]}" for factor in FACTORS)
        assert name is not None  # the model factor always names the controller (FACTORS["model"])
        configs.append(ControllerConfig(label, name, tuple(sorted(options.items()))))
    return configs


def _unit_outcomes(results: Results) -> dict[tuple, dict[str, bool]]:
    """Every episode unit (task, map, slip and seed: the same starts and slip draws for every
    configuration) -> configuration label -> success, of the episodes that ran."""
    units: dict[tuple, dict[str, bool]] = {}
    for r in results.records:
        if ran(r):
            units.setdefault((r["env_id"], r["map"], r["slip"], r["seed"]), {})[r["controller"]] = bool(
                r["success"]
            )
    return units


def main_effects_family(factors: Sequence[str] | None = None) -> HypothesisFamily:
    """The main-effects table's family of tests, declared from the design before any outcome:
    one comparison per factor varied (a factor without paired units still counts in ``m``)."""
    return HypothesisFamily(
        "ablation: main effects on success, one per factor", tuple(check_factors(factors))
    )


@dataclass(frozen=True)
class MainEffects:
    """The main-effects table (:func:`main_effects_table`): its rows, its family corrected by
    Holm and its power statement (None when no factor had paired units)."""

    effects: list[dict[str, Any]]
    family: FamilyResult
    power: PowerStatement | None


def main_effects_table(results: Results, factors: Sequence[str] | None = None) -> MainEffects:
    """Each factor's main effect, with the episode unit as the unit, its family and its power.

    A unit is an episode's conditions (task, map, slip level, seed), which every configuration
    meets. For a factor with levels a and b, each configuration at a is paired with the one at b
    that shares the other factors' levels, on the same unit; the unit's difference is the mean
    of its pairs' differences (four with three factors), so that a unit counts once however many
    configurations meet it (counting every pair as a sample would count each unit four times).
    The interval is a bootstrap over units, the p-value the two-sided sign-flip test over units
    (:func:`evaluation.stats.layout_tests.paired_means_by_layout`, each unit its own cluster, seed 0),
    and ``p_holm`` Holm's adjustment within :func:`main_effects_family` (every factor varied). The
    power statement (:func:`evaluation.stats.families.power_statement`) is the smallest main effect
    found with 80% power at Holm's first step, from the units' measured differences.

    Returns
    -------
    MainEffects
        ``effects``: per factor with pairs, ``factor``, ``a``, ``b``, ``units``, ``episodes`` (per
        level), ``rate_a``, ``rate_b``, ``difference``, ``low``, ``high`` (a - b, in [-1, 1]),
        ``units_a`` / ``units_b`` (units where a / b did better), ``p_value``, ``p_holm``,
        ``rejected``; ``family`` and ``power``.
    """
    units = _unit_outcomes(results)
    family = main_effects_family(factors)
    effects: list[dict[str, Any]] = []
    comparisons = []
    for factor in family.comparisons:
        first, second = list(FACTORS[factor])
        a_means: list[list[float]] = []
        b_means: list[list[float]] = []
        episodes = 0
        for outcomes in units.values():
            pairs = []
            for label, won in outcomes.items():
                levels = _levels(label)
                if levels[factor] != first:
                    continue
                other = " ".join(f"{f}={second if f == factor else levels[f]}" for f in FACTORS)
                if other in outcomes:
                    pairs.append((won, outcomes[other]))
            if pairs:
                episodes += len(pairs)
                a_means.append([sum(a for a, _ in pairs) / len(pairs)])
                b_means.append([sum(b for _, b in pairs) / len(pairs)])
        if not a_means:
            continue
        test = paired_means_by_layout(a_means, b_means)
        comparisons.append(test)
        effects.append(
            {
                "factor": factor,
                "a": first,
                "b": second,
                "units": test.units,
                "episodes": episodes,
                "rate_a": test.mean_a,
                "rate_b": test.mean_b,
                "difference": test.difference,
                "low": max(-1.0, test.low),
                "high": min(1.0, test.high),
                "units_a": sum(x[0] > y[0] for x, y in zip(a_means, b_means, strict=True)),
                "units_b": sum(x[0] < y[0] for x, y in zip(a_means, b_means, strict=True)),
                "p_value": test.p_value,
                # the p-value as printed: a bound at the random test's floor (sign_flip_p_text)
                "p_text": sign_flip_p_text(test.p_value, test.exact, test.permutations, digits=3),
            }
        )
    tested = {e["factor"]: float(e["p_value"]) for e in effects}
    corrected = family.correct({f: tested.get(f, math.nan) for f in family.comparisons})
    by_factor = {t.comparison: t for t in corrected.tests}
    for effect in effects:
        effect["p_holm"] = by_factor[effect["factor"]].p_holm
        effect["rejected"] = by_factor[effect["factor"]].rejected
    power = power_statement(comparisons, family) if comparisons else None
    return MainEffects(effects, corrected, power)


def main_effects(results: Results, factors: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """The rows of :func:`main_effects_table`: each factor's main effect with the episode unit
    as the unit, Holm-adjusted within the factors varied."""
    return main_effects_table(results, factors).effects


def power_note(table: MainEffects) -> str:
    """The main-effects table's family and power statement, in words (below the table)."""
    family = table.family
    head = (
        f"Family {family.family!r}: m = {family.size} tests, Holm at alpha = {family.alpha:g} "
        f"(first step alpha/m = {family.alpha / family.size:.3g})."
    )
    power = table.power
    if power is None:
        return f"{head} No factor had paired units."
    if math.isnan(power.difference):
        found = "no main effect is found with 80% power (too few units, or no spread in their differences)"
    else:
        found = f"a main effect of {100 * power.difference:.1f} points is found with {100 * power.power:.0f}% power"
    rejected = [t.comparison for t in family.tests if t.rejected]
    verdict = f"Rejected after Holm: {', '.join(rejected)}." if rejected else "None rejected after Holm."
    return (
        f"{head} With {power.layouts} episode units (each its own cluster) and an SD of the units' "
        f"differences of {power.sd:.3g}, {found}. {verdict}"
    )


def ablation_markdown(results: Results, factors: Sequence[str] | None = None, command: str = "") -> str:
    """The ablation report: configurations x maps with intervals, main effects, and what they say."""
    chosen = check_factors(factors)
    labels = list(dict.fromkeys(c.controller for c in results.cells))
    maps = list(dict.fromkeys((c.env_id, c.map) for c in results.cells))
    slips = sorted({c.slip for c in results.cells})
    episodes = results.config.get("episodes")
    lines = [f"# {ABLATION_TITLE}", ""]
    if command:
        lines += [f"Regenerate with `{command}`.", ""]
    lines += [
        f"Paper maps, slip {', '.join(slips)}, {episodes} seeded episodes per cell (seed i for trial i, the "
        "same slip draws and starts for every configuration). Success: every robot settled within "
        "tolerance without collision; k/n with the 95% Wilson interval. Every configuration was calibrated "
        f"on the same plant and budget ({results.config.get('calibration', {}).get('budget', 0):,} "
        "team-transitions).",
        "",
    ]
    head = (
        "| Configuration | "
        + " | ".join(f"{task_label(e)} {m}" for e, m in maps)
        + " | All maps | Solver failures |"
    )
    lines += [head, "|" + "---|" * (len(maps) + 3)]
    for label in labels:
        row, total_k, total_n, failures = [], 0, 0, 0
        for env_id, map_name in maps:
            cells = [c for c in results.cells if (c.controller, c.env_id, c.map) == (label, env_id, map_name)]
            k, n = sum(c.successes for c in cells), sum(c.valid for c in cells)
            failures += sum(c.solver_failures for c in cells)
            total_k, total_n = total_k + k, total_n + n
            low, high = wilson_interval(k, n)
            row.append(f"{k}/{n} [{100 * low:.0f}-{100 * high:.0f}%]" if n else "-")
        low, high = wilson_interval(total_k, total_n)
        overall = f"**{100 * total_k / total_n:.0f}%** [{100 * low:.0f}-{100 * high:.0f}]" if total_n else "-"
        lines.append(f"| {label} | " + " | ".join(row) + f" | {overall} | {failures} |")
    table = main_effects_table(results, chosen)
    effects = table.effects
    if effects:
        lines += [
            "",
            "## Main effects (paired per episode unit)",
            "",
            "The unit is an episode's conditions (map, slip level, seed), which every configuration "
            "meets. For each factor, every configuration at the first level is paired with the one at "
            "the second that shares the other factors' levels, on the same unit, and a unit's difference "
            "is the mean over its pairs: each unit counts once. Difference in success rate with a 95% "
            "bootstrap interval over units; two-sided sign-flip test over units; Holm's adjustment over "
            "the factors of the table (its family, declared before the run: every factor varied), and "
            "below it the smallest main effect the table finds with 80% power at Holm's first step.",
            "",
            "| Factor | Levels (a vs b) | Units | Episodes per level | Success a | Success b | a - b [95% CI] "
            "| units a better / b better | p | Holm p |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for e in effects:
            lines.append(
                f"| {e['factor']} | {e['a']} vs {e['b']} | {e['units']} | {e['episodes']} | "
                f"{100 * e['rate_a']:.0f}% | {100 * e['rate_b']:.0f}% | "
                f"{100 * e['difference']:+.0f} pp [{100 * e['low']:+.0f}, {100 * e['high']:+.0f}] | "
                f"{e['units_a']} / {e['units_b']} | {_p_cell(e['p_text'])} | {_holm_text(e).removeprefix('= ')} |"
            )
        lines += ["", power_note(table), "", "## What the numbers say", ""]
        for e in sorted(effects, key=lambda e: -abs(e["difference"])):
            lines.append(
                f"- **{e['factor']}**: {e['a']} instead of {e['b']} {effect_verdict(e)}, averaged over the other factors."
            )
    return "\n".join(lines) + "\n"


def _p_cell(text: str) -> str:
    return text.removeprefix("= ")


def _holm_text(effect: dict[str, Any]) -> str:
    """Holm's adjusted p of ``effect`` as printed: a bound (``<=``) when its raw p is one (the
    random sign-flip test's floor): the adjustment is monotone in each raw p."""
    relation = "<=" if effect["p_text"].startswith("<=") else "="
    return f"{relation} {effect['p_holm']:.3g}"


def effect_verdict(effect: dict[str, Any]) -> str:
    """What a main effect of :func:`main_effects` says, in words: its direction and size when
    its Holm-adjusted p is below 0.05, else that it cannot be told from chance."""
    size = f"{100 * abs(effect['difference']):.0f} percentage points"
    interval = f"95% CI {100 * effect['low']:+.0f} to {100 * effect['high']:+.0f}"
    tests = f"sign-flip p {effect['p_text']}, Holm p {_holm_text(effect)}"
    if effect["p_holm"] < 0.05:
        direction = "raises" if effect["difference"] > 0 else "lowers"
        return f"{direction} success by {size} ({interval}; {tests})"
    return f"makes no difference we can distinguish from chance ({100 * effect['difference']:+.0f} pp, {interval}; {tests})"
