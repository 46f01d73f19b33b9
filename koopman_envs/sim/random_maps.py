"""The seeded random-map generator: a team in formation travels across the workspace between
isolated circular obstacles (and, optionally, slip zones), the same layout for the same seed.

:func:`generate_random_map` draws a layout from a generator, with the settings of
:class:`RandomMapConfig` (:mod:`koopman_envs.sim.random_map_config`: the settings, their checks
and which formation shape a team takes, re-exported here).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from koopman_envs.params import PARAMS
from koopman_envs.sim.formations import formation_shape
from koopman_envs.sim.maps import MapSpec
from koopman_envs.sim.random_map_config import (
    AUTO_FORMATION,
    MIN_PLACEMENT_SHARE,
    RandomMapConfig,
    placement_share,
)
from koopman_envs.sim.random_map_config import MIN_TRAVEL as MIN_TRAVEL  # importable here as before
from koopman_envs.sim.zones import SlipZone

__all__ = [
    "AUTO_FORMATION",
    "MIN_PLACEMENT_SHARE",
    "NoValidMap",
    "RandomMapConfig",
    "generate_random_map",
    "placement_share",
]


class NoValidMap(ValueError, RuntimeError):
    """No layout in ``max_attempts`` draws: a ``ValueError`` naming the ``random_map`` settings
    that cannot be met (as every bad keyword's), and the ``RuntimeError`` it was before."""


def generate_random_map(
    rng: np.random.Generator,
    n_robots: int,
    config: RandomMapConfig = RandomMapConfig(),  # noqa: B008 (frozen: an immutable default)
    robot_radius: float = PARAMS.robot_radius,
    workspace: tuple[float, float, float, float] = PARAMS.workspace,
) -> MapSpec:
    """Draw a valid random map from ``rng`` (reproducible: same generator state, same map).

    Every returned map passes :meth:`MapSpec.validate` and keeps, in addition, ``config.clearance``
    between starts/targets and obstacles and ``config.gap`` between obstacles.

    Parameters
    ----------
    rng : numpy.random.Generator
        The only source of randomness.
    n_robots : int
        Team size (the formation ``config.formation`` grows with it).
    config : RandomMapConfig
        Generator parameters.
    robot_radius : float
        Robot radius [m].
    workspace : tuple of float
        (x_min, x_max, y_min, y_max) [m].

    Returns
    -------
    MapSpec
        Named ``"random"``.

    Raises
    ------
    ValueError
        The team's shape does not fit the workspace (:meth:`RandomMapConfig.shape_for`).
    NoValidMap
        No layout in ``config.max_attempts`` draws (a ``ValueError`` naming the settings).
    """
    if n_robots < 1:
        raise ValueError(f"n_robots={n_robots!r} must be >= 1")
    local = formation_shape(config.shape_for(n_robots, robot_radius, workspace), n_robots, config.spacing)
    x0, x1, y0, y1 = workspace
    margin = config.border + robot_radius
    low, high = [x0 + margin, y0 + margin], [x1 - margin, y1 - margin]
    inner = np.array([x0 + margin, x1 - margin, y0 + margin, y1 - margin])
    for _ in range(config.max_attempts):
        # the draws, in this order, define the layout of a seed (tests/data/random_layouts.json)
        heading = rng.uniform(-math.pi, math.pi)
        cos_h, sin_h = math.cos(heading), math.sin(heading)
        offsets = local @ np.array([[cos_h, sin_h], [-sin_h, cos_h]])  # local @ rot.T
        travel = rng.uniform(*config.travel) * np.array([cos_h, sin_h])
        lead = rng.uniform(low, high)
        start_xy, target_xy, inside = _team_placement(offsets, travel, lead, inner)
        if config.swap_targets and rng.uniform() < config.swap_targets:
            target_xy = target_xy[rng.permutation(n_robots)]  # the same points: ``inside`` holds
        if not inside:
            continue
        start_theta = heading + rng.uniform(-math.pi / 2, math.pi / 2, size=n_robots)
        corridor = _corridor(start_xy, target_xy)
        obstacles = _place_obstacles(rng, corridor, start_xy, target_xy, config, robot_radius, workspace)
        if obstacles is None:
            continue
        starts = np.column_stack([start_xy, (start_theta + math.pi) % (2 * math.pi) - math.pi])
        targets = np.column_stack([target_xy, np.full(n_robots, heading)])
        # after every draw of the layout and only when asked for: without zones a seed consumes
        # the generator as before and gives the same layout (tests/data/random_layouts.json)
        zones = _place_slip_zones(rng, corridor, config) if config.n_slip_zones else ()
        return MapSpec("random", obstacles, starts, targets, "seeded random layout", slip_zones=zones)
    raise NoValidMap(
        f"random_map: no valid random map in max_attempts={config.max_attempts} attempts for "
        f"n_robots={n_robots}: the team must fit the workspace, and n_obstacles={config.n_obstacles} "
        f"obstacles of radius {tuple(config.obstacle_radius)} m the corridor between starts and targets "
        f"(obstacle_along={tuple(config.obstacle_along)}) with clearance={config.clearance:g} m from every "
        f"start and target and gap={config.gap:g} m between them; use fewer or smaller obstacles, a "
        "smaller clearance or gap, or fewer robots"
    )


@njit(cache=True)
def _team_placement(
    offsets: NDArray[np.float64],
    travel: NDArray[np.float64],
    lead: NDArray[np.float64],
    inner: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]:
    """Starts (lead + offsets) and targets (starts + travel) of a team, and whether all of them
    lie inside ``inner`` (x0, x1, y0, y1); compiled because a random-map reset tries several
    placements and each took ~20 small numpy calls."""
    n = offsets.shape[0]
    start = np.empty((n, 2))
    target = np.empty((n, 2))
    inside = True
    for i in range(n):
        for axis in range(2):
            start[i, axis] = lead[axis] + offsets[i, axis]
            target[i, axis] = start[i, axis] + travel[axis]
        for point in (start[i], target[i]):
            if point[0] < inner[0] or point[0] > inner[1] or point[1] < inner[2] or point[1] > inner[3]:
                inside = False
    return start, target, inside


def _corridor(
    start_xy: NDArray[np.float64], target_xy: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float]:
    """The corridor of a random layout: start centroid a, target centroid b, unit normal of a -> b
    and half width [m] (the team's spread across the travel direction plus 1 m)."""
    a, b = start_xy.mean(axis=0), target_xy.mean(axis=0)
    direction = (b - a) / np.linalg.norm(b - a)
    normal = np.array([-direction[1], direction[0]])
    half_width = np.abs((start_xy - a) @ normal).max() + 1.0
    return a, b, normal, float(half_width)


def _place_slip_zones(
    rng: np.random.Generator,
    corridor: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float],
    config: RandomMapConfig,
) -> tuple[SlipZone, ...]:
    """``config.n_slip_zones`` circles in the corridor (:func:`_corridor`), overlapping anything
    (slip is no obstacle).

    One ``rng.uniform(size=(n_slip_zones, 4))`` call; row j places zone j: position along a -> b
    in [0.25, 0.75], offset across in [-half_width, half_width], radius and lambda in their
    configured ranges, each linear in its uniform number. Python floats: this runs every reset.
    """
    (ax, ay), (bx, by), (nx, ny), half_width = corridor
    r_low, r_high = config.slip_zone_radius
    l_low, l_high = config.slip_zone_lambda
    zones = []
    for u_along, u_across, u_radius, u_lambda in rng.uniform(size=(config.n_slip_zones, 4)).tolist():
        along = 0.25 + 0.5 * u_along
        across = half_width * (2.0 * u_across - 1.0)
        centre = (ax + along * (bx - ax) + across * nx, ay + along * (by - ay) + across * ny)
        radius = r_low + (r_high - r_low) * u_radius
        lam = l_low + (l_high - l_low) * u_lambda
        zones.append(SlipZone("circle", (*centre, radius), lam, config.slip_zone_mode))
    return tuple(zones)


def _place_obstacles(
    rng: np.random.Generator,
    corridor: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float],
    start_xy: NDArray[np.float64],
    target_xy: NDArray[np.float64],
    config: RandomMapConfig,
    robot_radius: float,
    workspace: tuple[float, float, float, float],
) -> NDArray[np.float64] | None:
    """Obstacles along the corridor (:func:`_corridor`) between the start and target centroids,
    or None if stuck."""
    a, b, normal, half_width = corridor
    keep_clear = np.ascontiguousarray(np.vstack([start_xy, target_xy]))
    placed, ok = _place_obstacles_kernel(
        rng,
        a,
        b,
        normal,
        float(half_width),
        keep_clear,
        int(config.n_obstacles),
        float(config.obstacle_radius[0]),
        float(config.obstacle_radius[1]),
        float(config.obstacle_along[0]),
        float(config.obstacle_along[1]),
        float(robot_radius),
        float(config.clearance),
        float(config.gap),
        np.asarray(workspace, dtype=np.float64),
    )
    return placed if ok else None


@njit(cache=True)
def _place_obstacles_kernel(
    rng: np.random.Generator,
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    normal: NDArray[np.float64],
    half_width: float,
    keep_clear: NDArray[np.float64],
    n_obstacles: int,
    r_low: float,
    r_high: float,
    along_low: float,
    along_high: float,
    robot_radius: float,
    clearance: float,
    gap: float,
    workspace: NDArray[np.float64],
) -> tuple[NDArray[np.float64], bool]:
    """The rejection sampler of :func:`_place_obstacles`, compiled: a reset of a vector env with
    ``map="random"`` spent ~3 ms here in Python. It draws from ``rng`` exactly as the Python
    version did (numba's Generator shares NumPy's bit stream and algorithms), so the same seed
    gives the same layout (tests/data/random_layouts.json)."""
    placed = np.zeros((n_obstacles, 3))
    for k in range(n_obstacles):
        found = False
        for _attempt in range(100):
            along = rng.uniform(along_low, along_high)
            across = rng.uniform(-half_width, half_width)
            radius = rng.uniform(r_low, r_high)
            cx = a[0] + along * (b[0] - a[0]) + across * normal[0]
            cy = a[1] + along * (b[1] - a[1]) + across * normal[1]
            if (
                cx - radius < workspace[0]
                or cx + radius > workspace[1]
                or cy - radius < workspace[2]
                or cy + radius > workspace[3]
            ):  # noqa: E501
                continue
            clear = np.inf
            for i in range(keep_clear.shape[0]):
                d = math.hypot(keep_clear[i, 0] - cx, keep_clear[i, 1] - cy) - radius - robot_radius
                clear = min(clear, d)
            if clear < clearance:
                continue
            spacing = np.inf
            for j in range(k):
                d = math.hypot(placed[j, 0] - cx, placed[j, 1] - cy) - placed[j, 2] - radius
                spacing = min(spacing, d)
            if k > 0 and spacing < gap:
                continue
            placed[k, 0], placed[k, 1], placed[k, 2] = cx, cy, radius
            found = True
            break
        if not found:
            return placed, False
    return placed, True
