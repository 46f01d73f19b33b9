"""The sim-to-sim page's rank-agreement sentence when Kendall's tau-b is undefined (every
controller's success ties on a plant): it says the ranking cannot be compared, not that the
ranking "agrees with tau-b = undefined" (docs/make_sim2sim_md.py)."""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

from evaluation.stats.transfer import RankAgreement

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "docs"))
from make_sim2sim_md import agreement_sentence  # noqa: E402  (docs/ is no package)


def _level(tau: float) -> SimpleNamespace:
    run = SimpleNamespace(config={"suite": {"name": "koopnav-bench-v1"}})
    return SimpleNamespace(agreement=RankAgreement(tau, 0.1, 0.6, 19, 20, 2000), kinematic=run)


def test_an_undefined_tau_is_said_so() -> None:
    text = agreement_sentence(_level(float("nan")))  # type: ignore[arg-type]
    assert "cannot be compared" in text and "undefined" in text
    assert "agrees" not in text and "interval" not in text


def test_a_defined_tau_keeps_its_sentence() -> None:
    text = agreement_sentence(_level(0.37))  # type: ignore[arg-type]
    assert "agrees between the plants with Kendall's tau-b = 0.37 (95% interval [0.10, 0.60]" in text
