"""docs/make_compute_md.py (docs/compute.md, issue 60): the margins its wide-margin run sets are
the chance constraints' widening at one period of delay, its paired statistics are the
evaluator's, and it refuses to write prose the data no longer support. The page itself is rebuilt
from the committed archives byte for byte by tests/test_published_pages.py (slow)."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from controllers.estimation import PoseFrontEnd
from controllers.mpc.margins import chance_tightening
from koopman_envs import Observed
from koopman_envs.params import PARAMS

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("make_compute_md", ROOT / "docs" / "make_compute_md.py")
assert _spec is not None and _spec.loader is not None
page = importlib.util.module_from_spec(_spec)
sys.modules["make_compute_md"] = page  # its dataclasses look their module up
_spec.loader.exec_module(page)


def test_the_tightening_is_what_the_front_end_hands_on_at_one_period_of_delay() -> None:
    """The front-end, told one period of delay on a team that localizes exactly (its noise
    identified as none), hands on the covariance the page's widening is computed from."""
    import gymnasium as gym

    env = gym.make("KoopNav-TargetReaching-v0", map="map1")
    _, info = env.reset(seed=0)
    scenario = getattr(env.unwrapped, "scenario")  # noqa: B009  (a KoopNav env's, not Env's)
    front = PoseFrontEnd(delay=1, position_std="auto", heading_std="auto")
    front.reset(scenario)
    view = front.view(Observed.from_info(info))
    per_robot, per_pair = chance_tightening(view.pose_covariance, 0.05, 3)
    assert page.tightening() == pytest.approx((per_robot[0], per_pair[0]), abs=1e-12)
    assert page.tightening() == pytest.approx((0.01645, 0.02326), abs=1e-5)
    no_delay = PoseFrontEnd(delay=0, position_std="auto", heading_std="auto")
    no_delay.reset(scenario)
    assert no_delay.view(Observed.from_info(info)).pose_covariance is None  # no delay: no widening


def test_the_wide_margin_run_sets_the_paper_margin_plus_the_tightening() -> None:
    script = (ROOT / "data" / "publish.sh").read_text(encoding="utf-8")
    wide = re.search(r'WIDE="koopman-nmpc:obstacle_offset=([\d.]+),robot_offset=([\d.]+),', script)
    assert wide is not None
    to_obstacle, to_robot = page.tightening()
    assert float(wide.group(1)) == pytest.approx(PARAMS.obstacle_offset + to_obstacle, abs=1e-5)
    assert float(wide.group(2)) == pytest.approx(PARAMS.obstacle_offset + to_robot, abs=1e-5)


def _records(
    outcomes: list[bool], clearance: float = 0.01
) -> dict[tuple[str, str, str, int], dict[str, Any]]:
    return {
        ("E", "map1", "high", seed): {
            "success": won,
            "collision": None if won else "obstacle",
            "min_clearance": {"obstacle": clearance},
            "steps": 100,
            "decisions": 100,
            "controller_extra": {"tightened": 50},
        }
        for seed, won in enumerate(outcomes)
    }


def test_pairs_are_the_evaluators_mcnemar_on_shared_episodes() -> None:
    a = _records([True] * 9 + [False])
    b = _records([False] * 8 + [True, False])
    c = page.pair(a, b)
    assert (c.n, c.only_a, c.only_b) == (10, 8, 0)
    assert c.p_value == pytest.approx(2 / 2**8)
    stats = page.arm_stats(a)
    assert stats["success"] == 9 and stats["kinds"]["obstacle"] == 1 and stats["tightened"] == 0.5
    assert stats["median_clearance_cm"] == pytest.approx(1.0) and stats["skim"] == 0
    with pytest.raises(ValueError, match="share no episode"):
        page.pair(a, {("E", "map2", "high", 0): a["E", "map1", "high", 0]})


def test_prose_the_data_contradict_is_refused_by_claim() -> None:
    """Every arm alike: nothing gains, so the page's claim that the delay gains must be refused."""
    same = _records([True, False] * 20)
    arms = {arm.name: same for arm in page.ARMS}
    with pytest.raises(ValueError, match="one period of delay alone gains"):
        page.check_claims(page.run_tests(arms))


def test_every_comparison_names_two_arms_and_the_family_is_adjusted_together() -> None:
    names = {arm.name for arm in page.ARMS}
    assert all(a in names and b in names for a, b, _ in page.COMPARISONS)
    rng = np.random.default_rng(0)
    arms = {name: _records(list(rng.random(40) < 0.5)) for name in names}
    tests = page.run_tests(arms)
    raw = sorted(t.result.p_value for t in tests.values())
    assert min(t.holm for t in tests.values()) == pytest.approx(min(1.0, raw[0] * len(raw)))
