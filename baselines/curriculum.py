"""The training curriculum of the set policies: random layouts only, from easy to the full mix.

Training never sees a paper map. It runs on a fixed set of *parts* (team size N, number of
simulated envs K: SB3 sees K * N robots per part, so every team size 2..12 is sampled in
every rollout) and moves through *stages* that change what the random maps hold:

=========  ==================================================================================
stage      what the random layouts hold
=========  ==================================================================================
basics     few obstacles, targets in formation order, nominal or random constant slip
crossing   more obstacles, crossing targets (target reaching) or other formation shapes,
           random constant slip, slip zones in half the parts; formation: obstacles also
           beside the targets
full       2-8 obstacles by part, crossing targets, slip zones (0-2 per map), random and
           drifting slip; every formation shape (formation task)
=========  ==================================================================================

A stage is a fraction of the budget (robot-steps). The table is data, recorded in the
policy's metadata with the budget, so a policy is reproducible from its metadata alone.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from koopman_envs import FORMATION_SHAPES

__all__ = ["PARTS", "STAGES", "VALIDATION", "Stage", "stage_parts"]

#: (team size N, simulated envs K) of every part: about 430 robots per step in all
PARTS: tuple[tuple[int, int], ...] = ((2, 32), (3, 32), (4, 16), (6, 12), (8, 8), (12, 6))


@dataclass(frozen=True)
class Stage:
    """One curriculum stage: its share of the budget and its per-part env settings.

    Each per-part tuple has one entry per part of :data:`PARTS` (in order).
    """

    name: str
    share: float
    n_obstacles: tuple[int, ...]
    swap_targets: float
    n_slip_zones: tuple[int, ...]
    slip: tuple[str, ...]
    #: formation task only: the shape of each part
    formations: tuple[str, ...] = field(default=("wedge",) * len(PARTS))
    #: where along the route obstacles are drawn (RandomMapConfig.obstacle_along)
    obstacle_along: tuple[float, float] = (0.25, 0.75)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


_CYCLE = tuple(FORMATION_SHAPES[i % len(FORMATION_SHAPES)] for i in range(len(PARTS)))

STAGES: dict[str, tuple[Stage, ...]] = {
    "target_reaching": (
        Stage("basics", 0.2, (2,) * 6, 0.0, (0,) * 6, ("nominal", "random") * 3),
        Stage("crossing", 0.3, (4, 4, 4, 5, 5, 5), 0.5, (0, 1) * 3, ("random",) * 6),
        Stage(
            "full",
            0.5,
            (5, 3, 6, 8, 4, 6),
            0.5,
            (1, 0, 2, 1, 0, 1),
            ("random", "drift", "random", "random", "drift", "random"),
        ),
    ),
    "formation": (
        Stage("basics", 0.2, (2,) * 6, 0.0, (0,) * 6, ("nominal", "random") * 3),
        # obstacles also beside the targets from the second stage on: a follower settling onto
        # its place must keep clear of an obstacle next to it (the first formation policy,
        # trained without, grazed such obstacles)
        Stage("crossing", 0.3, (4, 4, 4, 5, 5, 5), 0.0, (0, 1) * 3, ("random",) * 6, _CYCLE, (0.15, 0.95)),
        Stage(
            "full",
            0.5,
            (5, 3, 6, 5, 4, 5),  # a column of 6 finds no room among 8 obstacles
            0.2,
            (1, 0, 2, 1, 0, 1),
            ("random", "drift", "random", "random", "drift", "random"),
            _CYCLE[::-1],
            (0.15, 0.95),
        ),
    ),
}

#: the held-out validation cells that pick the checkpoint: (N, random-map settings, slip); seeds
#: start at baselines.sb3.select.VALIDATION_SEED, far from every training seed
VALIDATION: dict[str, tuple[tuple[int, dict[str, Any], str], ...]] = {
    "target_reaching": (
        (3, {"n_obstacles": 5, "swap_targets": 0.5, "n_slip_zones": 1}, "random"),
        (6, {"n_obstacles": 5, "swap_targets": 0.5}, "random"),
        (10, {"n_obstacles": 5, "swap_targets": 0.5}, "nominal"),
    ),
    "formation": (
        (3, {"n_obstacles": 4}, "random"),
        (5, {"n_obstacles": 4, "formation": "line", "n_slip_zones": 1}, "random"),
        (8, {"n_obstacles": 4}, "nominal"),
    ),
}


def stage_parts(task: str, stage: Stage) -> list[tuple[int, int, dict[str, Any]]]:
    """(N, K, env keywords) of every part in ``stage`` of ``task``."""
    parts = []
    for i, (n, k) in enumerate(PARTS):
        random_map: dict[str, Any] = {
            "n_obstacles": stage.n_obstacles[i],
            "swap_targets": stage.swap_targets,
            "n_slip_zones": stage.n_slip_zones[i],
            "obstacle_along": stage.obstacle_along,
        }
        if task == "formation":
            random_map["formation"] = stage.formations[i]
        parts.append(
            (n, k, {"n_robots": n, "map": "random", "slip": stage.slip[i], "random_map": random_map})
        )
    return parts
