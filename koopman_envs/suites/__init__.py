"""The benchmark's layout suites: frozen splits of generated layouts, graded by difficulty.

``koopnav-bench-v1`` holds, per task, a ``train``, a ``validation`` and a ``test`` split drawn
from disjoint seed ranges, each layout of one of three families (open clutter, narrow passages
with crossing paths, rooms), measured (narrowest gap, tortuosity, density) and tiered; the data
is stored in the package and verified by its hash on loading (docs/benchmark.md)::

    import gymnasium as gym, koopman_envs

    suite = koopman_envs.load_suite("koopnav-bench-v1", "target_reaching", "test")
    print(suite.label)                    # koopnav-bench-v1/target_reaching/test@<12 hex>
    env = gym.make("KoopNav-TargetReaching-v0", map="suite:koopnav-bench-v1/test")
    obs, info = env.reset(seed=0, options={"layout": 5})   # layout 5 of the split

Modules: :mod:`~koopman_envs.suites.families` (the generator), :mod:`~koopman_envs.suites.planner`
(the grid planner), :mod:`~koopman_envs.suites.measures` (difficulty and tiers),
:mod:`~koopman_envs.suites.suite` (definitions, data, loader, the held-out guard) and
:mod:`~koopman_envs.suites.build` (``python -m koopman_envs.suites.build --check``).
"""

from __future__ import annotations

from koopman_envs.suites.families import FAMILIES, draw_layout
from koopman_envs.suites.measures import TIERS, LayoutMeasures, measure_layout
from koopman_envs.suites.suite import (
    HELD_OUT_PURPOSES,
    PURPOSES,
    SPLITS,
    SUITES,
    Suite,
    SuiteDefinition,
    SuiteLayout,
    check_split_allowed,
    load_suite,
)

__all__ = [
    "FAMILIES",
    "HELD_OUT_PURPOSES",
    "PURPOSES",
    "SPLITS",
    "SUITES",
    "TIERS",
    "LayoutMeasures",
    "Suite",
    "SuiteDefinition",
    "SuiteLayout",
    "check_split_allowed",
    "draw_layout",
    "load_suite",
    "measure_layout",
]
