"""How hard a layout is, measured as BARN grades its worlds (Perille et al., 2020), and its tier.

Each robot's path is :func:`~koopman_envs.suites.planner.shortest_path` from its start to its
target (the obstacles inflated by the robot radius plus :data:`PLANNER_MARGIN`). Per layout:

``gap`` [m]
    The narrowest gap on the shortest paths: the smallest surface-to-surface distance of an
    obstacle pair whose connecting segment (between the two surfaces) a robot's path crosses,
    the minimum over robots; :data:`GAP_CAP` when no path threads a pair closer than that.
    A shortest path hugs the inflated obstacles, so the clearance along it is the inflation
    wherever it bends; the gap it passes through is the width that matters.
``tortuosity``
    Shortest path length / straight-line distance, the largest over robots (1 for a free run).
``density``
    The share of :data:`ARENA` covered by obstacles (their union, counted on a
    :data:`DENSITY_RESOLUTION` grid).

``difficulty`` in [0, 1] is the mean of three scores, each in [0, 1] by fixed constants (not
fitted to any split): narrowness ``(GAP_CAP - gap) / (GAP_CAP - GAP_PASSABLE)``, bending
``(tortuosity - 1) / TORTUOSITY_SPAN`` and crowding ``density / DENSITY_SPAN`` (clipped). The
tier cuts it at :data:`TIER_THRESHOLDS`: per task, the 1/3 and 2/3 quantiles of the ``train``
split of ``koopnav-bench-v1``, declared here, so that the tiers of ``validation`` and ``test``
never depend on their own data (``python -m koopman_envs.suites.build --check`` recomputes them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from koopman_envs.params import PARAMS
from koopman_envs.suites.planner import PLANNER_MARGIN, path_length, shortest_path

__all__ = [
    "ARENA",
    "DENSITY_SPAN",
    "GAP_CAP",
    "GAP_PASSABLE",
    "TIERS",
    "TIER_THRESHOLDS",
    "TORTUOSITY_SPAN",
    "LayoutMeasures",
    "difficulty_of",
    "measure_layout",
    "narrowest_gap",
    "obstacle_density",
    "tier_of",
]

#: the square every suite layout lies in, (x_min, x_max, y_min, y_max) [m] (ours): the paper's
#: maps span about 8 x 6 m; a layout is drawn within 6.9 m of a centre at most 1 m from the origin,
#: and the workspace leaves 2 m around it to go round a wall
ARENA = (-8.0, 8.0, -8.0, 8.0)
#: a gap at least this wide [m] is open ground (narrowness 0); also the gap of a layout whose
#: paths thread no closer pair (ours: three robot diameters plus the formation spacing)
GAP_CAP = 2.0
#: the narrowest gap the planner lets a robot through [m] (narrowness 1)
GAP_PASSABLE = 2.0 * (PARAMS.robot_radius + PLANNER_MARGIN)
#: tortuosity 1 + this scores bending 1 (ours: a path half again as long as the straight line)
TORTUOSITY_SPAN = 0.5
#: obstacle density that scores crowding 1 (ours)
DENSITY_SPAN = 0.08
#: grid cell side of the density count [m]
DENSITY_RESOLUTION = 0.05
#: the tiers, easiest first
TIERS = ("easy", "medium", "hard")
#: difficulty cuts between the tiers of koopnav-bench-v1, per task: the 1/3 and 2/3 quantiles of
#: that task's train split (numpy's default linear quantile), rounded to 4 decimals. Declared, so
#: that no other split's tiers depend on its own data; ``python -m koopman_envs.suites.build
#: --check`` recomputes them from train
TIER_THRESHOLDS: dict[str, tuple[float, float]] = {
    "target_reaching": (0.48, 0.5274),
    "formation": (0.4745, 0.5295),
}


@dataclass(frozen=True)
class LayoutMeasures:
    """The difficulty measures of one layout (module docstring); values rounded to 4 decimals.

    Attributes
    ----------
    gap : float
        Narrowest gap on the robots' shortest paths [m], at most :data:`GAP_CAP`.
    tortuosity : float
        Largest ratio of shortest path length to straight-line distance over the robots.
    density : float
        Share of :data:`ARENA` covered by obstacles.
    difficulty : float
        The scalar difficulty in [0, 1] (:func:`difficulty_of`).
    """

    gap: float
    tortuosity: float
    density: float
    difficulty: float

    def to_dict(self) -> dict[str, float]:
        """Plain-JSON form (a suite layout's ``measures``)."""
        return {
            "gap": self.gap,
            "tortuosity": self.tortuosity,
            "density": self.density,
            "difficulty": self.difficulty,
        }


def _crosses(
    p: NDArray[np.float64], q: NDArray[np.float64], a: NDArray[np.float64], b: NDArray[np.float64]
) -> bool:
    """True when segments p-q and a-b intersect (touching counts)."""

    def side(o: NDArray[np.float64], u: NDArray[np.float64], v: NDArray[np.float64]) -> float:
        return float((u[0] - o[0]) * (v[1] - o[1]) - (u[1] - o[1]) * (v[0] - o[0]))

    d1, d2 = side(a, b, p), side(a, b, q)
    d3, d4 = side(p, q, a), side(p, q, b)
    return d1 * d2 <= 0.0 and d3 * d4 <= 0.0


def narrowest_gap(path: NDArray[np.float64], obstacles: NDArray[np.float64], cap: float = GAP_CAP) -> float:
    """The narrowest gap a polyline passes through [m] (``cap`` when it threads none narrower).

    A gap is the segment between the surfaces of two obstacles (on the line through their
    centres); its width is their surface-to-surface distance. Pairs that touch or overlap (a
    wall of discs) leave no gap.

    Parameters
    ----------
    path : ndarray, shape (P, 2)
        The polyline [m].
    obstacles : ndarray, shape (M, 3)
        x [m], y [m], radius [m].
    cap : float
        The width reported when the path threads no gap narrower than it [m].
    """
    obstacles = np.asarray(obstacles, dtype=np.float64).reshape(-1, 3)
    narrowest = float(cap)
    for i in range(obstacles.shape[0]):
        for j in range(i + 1, obstacles.shape[0]):
            delta = obstacles[j, :2] - obstacles[i, :2]
            distance = float(np.hypot(delta[0], delta[1]))
            width = distance - obstacles[i, 2] - obstacles[j, 2]
            if not 0.0 < width < narrowest:
                continue
            unit = delta / distance
            a = obstacles[i, :2] + obstacles[i, 2] * unit
            b = obstacles[j, :2] - obstacles[j, 2] * unit
            if any(_crosses(path[k], path[k + 1], a, b) for k in range(path.shape[0] - 1)):
                narrowest = width
    return narrowest


def obstacle_density(
    obstacles: NDArray[np.float64], arena: tuple[float, float, float, float] = ARENA
) -> float:
    """Share of ``arena`` covered by the union of the obstacle discs (grid count)."""
    x0, x1, y0, y1 = arena
    xs = np.arange(x0 + DENSITY_RESOLUTION / 2, x1, DENSITY_RESOLUTION)
    ys = np.arange(y0 + DENSITY_RESOLUTION / 2, y1, DENSITY_RESOLUTION)
    covered = np.zeros((ys.size, xs.size), dtype=bool)
    for x, y, r in np.asarray(obstacles, dtype=np.float64).reshape(-1, 3):
        inside_x = np.abs(xs - x) < r
        inside_y = np.abs(ys - y) < r
        if inside_x.any() and inside_y.any():
            dx, dy = xs[inside_x] - x, ys[inside_y] - y
            block = dx[None, :] ** 2 + dy[:, None] ** 2 < r * r
            covered[np.ix_(inside_y, inside_x)] |= block
    return float(covered.mean())


def difficulty_of(gap: float, tortuosity: float, density: float) -> float:
    """The scalar difficulty in [0, 1] of a layout's measures (module docstring), 4 decimals."""
    narrow = (GAP_CAP - gap) / (GAP_CAP - GAP_PASSABLE)
    bend = (tortuosity - 1.0) / TORTUOSITY_SPAN
    crowd = density / DENSITY_SPAN
    scores = [min(1.0, max(0.0, score)) for score in (narrow, bend, crowd)]
    return round(float(sum(scores)) / 3.0, 4)


def tier_of(difficulty: float, thresholds: tuple[float, float]) -> str:
    """The tier of a difficulty: ``"easy"`` below ``thresholds[0]``, ``"hard"`` from ``thresholds[1]``
    (a suite's cuts: :data:`TIER_THRESHOLDS`)."""
    if not math.isfinite(difficulty):
        raise ValueError(f"difficulty={difficulty!r} must be a finite number in [0, 1]")
    return TIERS[int(difficulty >= thresholds[0]) + int(difficulty >= thresholds[1])]


def measure_layout(
    obstacles: NDArray[np.float64],
    starts: NDArray[np.float64],
    targets: NDArray[np.float64],
    robot_radius: float = PARAMS.robot_radius,
) -> LayoutMeasures | None:
    """The measures of a layout, or None when some robot cannot reach its target.

    Parameters
    ----------
    obstacles : ndarray, shape (M, 3)
        x [m], y [m], radius [m].
    starts, targets : ndarray, shape (N, 3)
        Start and target poses per robot.
    robot_radius : float
        Disc radius of every robot [m].
    """
    gap, tortuosity = GAP_CAP, 1.0
    for start, target in zip(np.asarray(starts), np.asarray(targets)):
        path = shortest_path(obstacles, start, target, robot_radius)
        if path is None:
            return None
        straight = float(np.hypot(*(target[:2] - start[:2])))
        tortuosity = max(tortuosity, path_length(path) / straight if straight > 0 else 1.0)
        gap = min(gap, narrowest_gap(path, obstacles))
    density = obstacle_density(obstacles)
    gap, tortuosity, density = (round(float(v), 4) for v in (gap, tortuosity, density))
    return LayoutMeasures(gap, tortuosity, density, difficulty_of(gap, tortuosity, density))
