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
``OUT/ablation.md`` (``--ablation-out docs/ablation.md``: the published page): success per configuration and map with intervals, and each factor's main
effect as a paired comparison (configurations that differ only in that factor, same seeds).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

from controllers.mpc.config import ROBUST_UNCERTAINTY_MARGIN
from evaluation.episodes.records import ran
from evaluation.reports.results import Results
from evaluation.reports.sections import task_label
from evaluation.run.configs import ControllerConfig
from evaluation.stats.statistics import paired_comparison, wilson_interval

__all__ = ["DEFAULT_LEVELS", "FACTORS", "ablation_configs", "ablation_markdown", "check_factors"]

#: factor -> level -> (controller name or None, options)
FACTORS: dict[str, dict[str, tuple[str | None, dict[str, Any]]]] = {
    "model": {"learned": ("koopman-nmpc", {}), "nominal": ("nominal-nmpc", {})},
    "margins": {
        "paper": (None, {"uncertainty_margin": 0.0}),
        "widened": (None, {"uncertainty_margin": ROBUST_UNCERTAINTY_MARGIN}),
    },
    "constraints": {"soft": (None, {"soft_constraints": True}), "hard": (None, {"soft_constraints": False})},
}
#: the level of a factor that is not varied
DEFAULT_LEVELS = {"model": "learned", "margins": "paper", "constraints": "soft"}


def check_factors(factors: Sequence[str] | None) -> list[str]:
    """The factors to vary (all when none are named); ``ValueError`` naming an unknown one."""
    chosen = list(factors) if factors else list(FACTORS)
    for factor in chosen:
        if factor not in FACTORS:
            raise ValueError(f"ablation factor {factor!r} is not one of {list(FACTORS)}")
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


def _main_effect(results: Results, factor: str) -> dict[str, Any] | None:
    """Paired comparison of the two levels of ``factor``, all else equal, on shared seeds."""
    first, second = list(FACTORS[factor])
    outcomes: dict[tuple, bool] = {}
    for r in results.records:
        if ran(r):
            outcomes[(r["controller"], r["env_id"], r["map"], r["slip"], r["seed"])] = bool(r["success"])
    a, b = [], []
    for (label, env_id, map_name, slip, seed), won in outcomes.items():
        levels = _levels(label)
        if levels[factor] != first:
            continue
        other = " ".join(f"{f}={second if f == factor else levels[f]}" for f in FACTORS)
        partner = outcomes.get((other, env_id, map_name, slip, seed))
        if partner is not None:
            a.append(won)
            b.append(partner)
    if not a:
        return None
    return {"factor": factor, "a": first, "b": second, **paired_comparison(a, b).to_dict()}


def ablation_markdown(results: Results, factors: Sequence[str] | None = None, command: str = "") -> str:
    """The ablation report: configurations x maps with intervals, main effects, and what they say."""
    chosen = check_factors(factors)
    labels = list(dict.fromkeys(c.controller for c in results.cells))
    maps = list(dict.fromkeys((c.env_id, c.map) for c in results.cells))
    slips = sorted({c.slip for c in results.cells})
    episodes = results.config.get("episodes")
    lines = ["# Ablation: what decides the NMPC's outcome under slip", ""]
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
    effects = [e for e in (_main_effect(results, f) for f in chosen) if e is not None]
    if effects:
        lines += [
            "",
            "## Main effects (paired)",
            "",
            "Each row pairs every episode of a configuration at the first level with the same episode "
            "(same map, seed, and other factors) at the second level: difference in success rate with "
            "Newcombe's 95% interval and the exact McNemar p-value.",
            "",
            "| Factor | Levels (a vs b) | Pairs | Success a | Success b | a - b [95% CI] | only a / only b | p |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for e in effects:
            lines.append(
                f"| {e['factor']} | {e['a']} vs {e['b']} | {e['n']} | {100 * e['rate_a']:.0f}% | {100 * e['rate_b']:.0f}% | "
                f"{100 * e['difference']:+.0f} pp [{100 * e['low']:+.0f}, {100 * e['high']:+.0f}] | "
                f"{e['only_a']} / {e['only_b']} | {e['p_value']:.3g} |"
            )
        lines += ["", "## What the numbers say", ""]
        for e in sorted(effects, key=lambda e: -abs(e["difference"])):
            significant = e["low"] > 0 or e["high"] < 0
            direction = "raises" if e["difference"] > 0 else "lowers"
            verdict = (
                f"{direction} success by {100 * abs(e['difference']):.0f} percentage points "
                f"(95% CI {100 * e['low']:+.0f} to {100 * e['high']:+.0f}; McNemar p = {e['p_value']:.3g})"
                if significant
                else f"makes no difference we can distinguish from chance ({100 * e['difference']:+.0f} pp, "
                f"95% CI {100 * e['low']:+.0f} to {100 * e['high']:+.0f}; p = {e['p_value']:.3g})"
            )
            lines.append(
                f"- **{e['factor']}**: {e['a']} instead of {e['b']} {verdict}, averaged over the other factors."
            )
    return "\n".join(lines) + "\n"
