"""The ablation's main effects with the episode unit as the unit (issue 60): a unit (map and seed)
that four configuration pairs meet counts once, not four times; and docs/ablation.md is the
evaluator's report of the published run (docs/make_ablation_md.py), here on a small real run."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from evaluation.experiments.ablation import (
    FACTORS,
    ablation_configs,
    ablation_markdown,
    main_effects,
    main_effects_table,
    power_note,
)
from evaluation.reports.results import Results
from evaluation.stats.families import detectable_difference
from evaluation.stats.layout_tests import layout_sign_flip_test

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from make_ablation_md import main as make_ablation_main  # noqa: E402  (docs/ is no package)
from make_ablation_md import page  # noqa: E402
from test_fair_comparison import _record  # noqa: E402  (a hand-made episode record)

#: a run of the ablation protocol with one trial per cell (32 episodes: seed 0 of every map and
#: configuration; `python evaluate.py --ablation --episodes 1 --workers 1`, packed)
FIXTURE = ROOT / "tests" / "data" / "ablation_trial0.tar.xz"


def _factorial(rng: np.random.Generator, maps: int = 2, seeds: int = 5) -> tuple[Results, dict]:
    """Every configuration on every (map, seed) unit, success drawn per episode; and the
    outcomes by (unit, label)."""
    outcomes = {}
    records = []
    for m in range(maps):
        for seed in range(seeds):
            for config in ablation_configs():
                won = bool(rng.random() < (0.8 if "widened" in config.label else 0.3))
                outcomes[(f"map{m}", seed, config.label)] = won
                record = _record(won, None if won else "obstacle", [0.01, 0.02], seed, config.label)
                records.append({**record, "map": f"map{m}", "slip": "high", "trial": seed})
    return Results(records, {"episodes": seeds, "calibration": {"budget": 100}}), outcomes


def test_a_unit_counts_once_however_many_pairs_meet_it() -> None:
    results, outcomes = _factorial(np.random.default_rng(3))
    effects = {e["factor"]: e for e in main_effects(results)}
    assert set(effects) == set(FACTORS)
    units = sorted({(m, s) for m, s, _ in outcomes})
    for factor, effect in effects.items():
        a, b = list(FACTORS[factor])
        # by hand: per unit, the mean over the four pairs of the other factors' levels
        per_unit = []
        for m, s in units:
            pairs = [
                (won, outcomes[(m, s, label.replace(f"{factor}={a}", f"{factor}={b}"))])
                for (mm, ss, label), won in outcomes.items()
                if (mm, ss) == (m, s) and f"{factor}={a}" in label
            ]
            assert len(pairs) == 4
            per_unit.append(np.mean([x for x, _ in pairs]) - np.mean([y for _, y in pairs]))
        assert effect["units"] == len(units) == 10  # not 40: a unit is one sample
        assert effect["episodes"] == 40
        assert effect["difference"] == pytest.approx(np.mean(per_unit))
        p_value, _ = layout_sign_flip_test([[d] for d in per_unit])
        assert effect["p_value"] == pytest.approx(p_value)
        assert effect["units_a"] == sum(d > 0 for d in per_unit)
        assert effect["units_b"] == sum(d < 0 for d in per_unit)
        assert effect["low"] <= effect["difference"] <= effect["high"]
    # Holm over the three factors: the smallest raw p times three, never below the raw p
    ordered = sorted(effects.values(), key=lambda e: e["p_value"])
    assert ordered[0]["p_holm"] == pytest.approx(min(1.0, 3 * ordered[0]["p_value"]))
    assert all(e["p_holm"] >= e["p_value"] for e in effects.values())


def test_the_report_names_the_unit_and_the_correction() -> None:
    results, _ = _factorial(np.random.default_rng(5))
    text = ablation_markdown(results)
    assert "Main effects (paired per episode unit)" in text
    assert "| Factor | Levels (a vs b) | Units | Episodes per level |" in text
    row = next(line for line in text.splitlines() if line.startswith("| margins |"))
    assert row.split(" | ")[2:4] == ["10", "40"]
    assert "Holm p = " in text


@pytest.mark.skipif(not FIXTURE.exists(), reason="the small ablation run is not committed")
def test_the_page_is_the_evaluators_report_of_the_published_run() -> None:
    text = page(FIXTURE)
    assert text.startswith("# Ablation: what decides the NMPC's outcome under slip\n\nRebuilt from")
    assert "(32 episodes)" in text and "bash data/publish.sh ablation" in text
    assert "| margins | paper vs widened | 4 | 16 |" in text  # 4 units (map x seed 0), 16 pairs


def test_the_table_states_its_family_and_its_power() -> None:
    """Holm within the declared family of the factors varied, and the smallest main effect found
    with 80% power, from the units' measured differences (each unit one cluster of one)."""
    results, _ = _factorial(np.random.default_rng(5), maps=4, seeds=20)
    table = main_effects_table(results)
    assert table.family.size == 3 and [t.comparison for t in table.family.tests] == list(FACTORS)
    assert table.power is not None
    assert (table.power.layouts, table.power.per_layout, table.power.family_size) == (80, 1, 3)
    sds = sorted(float(np.std(_unit_differences(results, f), ddof=1)) for f in FACTORS)
    assert table.power.sd == pytest.approx(sds[1])  # the median over the three factors
    expected = detectable_difference(80, 1, sd=sds[1], icc=0.0, family_size=3)
    assert table.power.difference == pytest.approx(expected)
    note = power_note(table)
    assert f"a main effect of {100 * expected:.1f} points is found with 80% power" in note
    assert note in ablation_markdown(results)


def _unit_differences(results: Results, factor: str) -> list[float]:
    """Per unit the mean over its pairs of a minus b, by hand."""
    a, b = list(FACTORS[factor])
    units: dict[tuple, dict[str, bool]] = {}
    for r in results.records:
        units.setdefault((r["map"], r["seed"]), {})[r["controller"]] = bool(r["success"])
    out = []
    for outcomes in units.values():
        pairs = [
            outcomes[label] - outcomes[label.replace(f"{factor}={a}", f"{factor}={b}")]
            for label in outcomes
            if f"{factor}={a}" in label
        ]
        out.append(float(np.mean(pairs)))
    return out


def test_a_factor_without_pairs_still_counts_in_the_family() -> None:
    results, _ = _factorial(np.random.default_rng(1))
    only_model = Results(
        [r for r in results.records if "margins=paper constraints=soft" in r["controller"]], results.config
    )
    table = main_effects_table(only_model)
    assert [e["factor"] for e in table.effects] == ["model"]
    assert table.family.size == 3  # declared before the data: margins and constraints count as p = 1
    assert table.effects[0]["p_holm"] == pytest.approx(min(1.0, 3 * table.effects[0]["p_value"]))


def test_a_missing_publication_gives_a_pending_page(tmp_path, capsys) -> None:
    out = tmp_path / "ablation.md"
    assert make_ablation_main([str(tmp_path / "ablation"), "--out", str(out)]) == 0
    text = out.read_text(encoding="utf-8")
    assert text.startswith("# Ablation: what decides the NMPC's outcome under slip\n\n**Pending")
    assert "bash data/publish.sh ablation" in text and "| " not in text  # no table, no result
    assert "not published yet" in capsys.readouterr().out
