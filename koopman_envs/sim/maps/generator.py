"""The seeded random-map generator: a team in formation travels across the workspace between
isolated circular obstacles (and, optionally, slip zones), the same layout for the same seed.

:func:`generate_random_map` draws a layout from a generator, with the settings of
:class:`RandomMapConfig` (:mod:`koopman_envs.sim.maps.generator_config`: the settings, their checks
and which formation shape a team takes, re-exported here).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any, cast

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic
from numpy.typing import NDArray

from koopman_envs.params import PARAMS
from koopman_envs.sim.formations import formation_shape
from koopman_envs.sim.maps.generator_config import (
    AUTO_FORMATION,
    MIN_PLACEMENT_SHARE,
    RandomMapConfig,
    placement_share,
)
from koopman_envs.sim.maps.generator_config import MIN_TRAVEL as MIN_TRAVEL  # importable here as before
from koopman_envs.sim.maps.map_spec import MapSpec
from koopman_envs.sim.slip.zones import SlipZone

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
    found, starts, targets, obstacles, a, b, normal, half_width = _draw_layout(
        rng, *_kernel_settings(config, n_robots, robot_radius, tuple(workspace))
    )
    if found:
        # after every draw of the layout and only when asked for: without zones a seed consumes
        # the generator as before and gives the same layout (tests/data/random_layouts.json)
        zones = _place_slip_zones(rng, (a, b, normal, half_width), config) if config.n_slip_zones else ()
        return MapSpec.generated("random", obstacles, starts, targets, "seeded random layout", tuple(zones))
    raise NoValidMap(
        f"random_map: no valid random map in max_attempts={config.max_attempts} attempts for "
        f"n_robots={n_robots}: the team must fit the workspace, and n_obstacles={config.n_obstacles} "
        f"obstacles of radius {tuple(config.obstacle_radius)} m the corridor between starts and targets "
        f"(obstacle_along={tuple(config.obstacle_along)}) with clearance={config.clearance:g} m from every "
        f"start and target and gap={config.gap:g} m between them; use fewer or smaller obstacles, a "
        "smaller clearance or gap, or fewer robots"
    )


@functools.lru_cache(maxsize=256)
def _kernel_settings(
    config: RandomMapConfig, n_robots: int, robot_radius: float, workspace: tuple[float, float, float, float]
) -> tuple[Any, ...]:
    """The arguments of :func:`_draw_layout` after the generator (read-only arrays), kept: a
    vector env draws many maps of one setting."""
    shape = config.shape_for(n_robots, robot_radius, workspace)
    x0, x1, y0, y1 = workspace
    margin = config.border + robot_radius
    arrays = (
        np.ascontiguousarray(formation_shape(shape, n_robots, config.spacing), dtype=np.float64),
        np.array([x0 + margin, x1 - margin, y0 + margin, y1 - margin]),
        np.array(
            [*config.obstacle_radius, *config.obstacle_along, robot_radius, config.clearance, config.gap]
        ),
        np.asarray(workspace, dtype=np.float64),
    )
    for array in arrays:
        array.setflags(write=False)
    local, inner, settings, box = arrays
    travel_low, travel_high = (float(v) for v in config.travel)
    return (local, travel_low, travel_high, inner, float(config.swap_targets), int(config.max_attempts),
            int(config.n_obstacles), settings, box)  # fmt: skip


@njit(cache=True)
def _draw_layout(
    rng: np.random.Generator,
    local: NDArray[np.float64],
    travel_low: float,
    travel_high: float,
    inner: NDArray[np.float64],
    swap: float,
    max_attempts: int,
    n_obstacles: int,
    settings: NDArray[np.float64],
    workspace: NDArray[np.float64],
) -> tuple[Any, ...]:
    """Every draw of a random layout, compiled (a reset of a vector env with ``map="random"``
    spent ~100 us here in Python). The draws, in this order, define the layout of a seed
    (tests/data/random_layouts.json): per attempt the heading, the travel length, the lead's
    position, the target swap (when asked for), the start headings, then the obstacles.

    Arithmetic equal to the NumPy version's, bit for bit: the two small products NumPy hands to
    BLAS are written out as BLAS computes them (:func:`_rotate`, :func:`_spread`: fused
    multiply-adds), every other operation as NumPy does it (the means summed row by row).
    ``settings``: obstacle radius low/high, along low/high, robot radius, clearance, gap.
    Returns (found, starts, targets, obstacles, a, b, normal, half_width) of the first valid
    attempt (found False after ``max_attempts``): a, b, normal and half_width describe the
    corridor (the start and target centroids, the unit normal of a -> b, the team's spread
    across it plus 1 m)."""
    n = local.shape[0]
    empty = np.zeros((0, 3))
    for _ in range(max_attempts):
        heading = rng.uniform(-math.pi, math.pi)
        cos_h, sin_h = math.cos(heading), math.sin(heading)
        offsets = _rotate(local, cos_h, sin_h)
        length = rng.uniform(travel_low, travel_high)
        travel = np.array([length * cos_h, length * sin_h])
        lead = np.empty(2)
        lead[0] = rng.uniform(inner[0], inner[1])
        lead[1] = rng.uniform(inner[2], inner[3])
        start_xy, target_xy, inside = _team_placement(offsets, travel, lead, inner)
        if swap > 0.0 and rng.uniform() < swap:
            target_xy = target_xy[rng.permutation(n)]  # the same points: ``inside`` holds
        if not inside:
            continue
        start_theta = np.empty(n)
        for i in range(n):
            start_theta[i] = heading + rng.uniform(-math.pi / 2, math.pi / 2)
        a, b = _row_mean(start_xy), _row_mean(target_xy)
        dx, dy = b[0] - a[0], b[1] - a[1]
        norm = math.sqrt(dx * dx + dy * dy)
        normal = np.array([-(dy / norm), dx / norm])
        half_width = _spread(start_xy, a, normal) + 1.0
        keep_clear = np.empty((2 * n, 2))
        keep_clear[:n], keep_clear[n:] = start_xy, target_xy
        placed, ok = _place_obstacles_kernel(
            rng, a, b, normal, half_width, keep_clear, n_obstacles, settings, workspace
        )
        if ok:
            starts, targets = np.empty((n, 3)), np.empty((n, 3))
            starts[:, :2], targets[:, :2] = start_xy, target_xy
            for i in range(n):  # Python's float remainder: NumPy's too
                starts[i, 2] = (start_theta[i] + math.pi) % (2 * math.pi) - math.pi
                targets[i, 2] = heading
            return True, starts, targets, placed, a, b, normal, half_width
    return False, empty, empty, empty, np.zeros(2), np.zeros(2), np.zeros(2), 0.0


def _fma_intrinsic(typingctx: Any, a: Any, b: Any, c: Any) -> Any:
    """``_fma(a, b, c)``: ``a * b + c`` rounded once (LLVM's ``llvm.fma``: the CPU's fused
    multiply-add, exact in software where there is none), as BLAS's kernels compute their
    products; callable from compiled code only."""
    signature = types.float64(types.float64, types.float64, types.float64)

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        double = ir.DoubleType()
        fma = builder.module.declare_intrinsic("llvm.fma", [double], ir.FunctionType(double, [double] * 3))
        return builder.call(fma, args)

    return signature, codegen


_fma = cast("Callable[[float, float, float], float]", intrinsic(_fma_intrinsic))


@njit(cache=True)
def _rotate(local: NDArray[np.float64], cos_h: float, sin_h: float) -> NDArray[np.float64]:
    """``local @ [[cos, sin], [-sin, cos]]`` as NumPy computes it (OpenBLAS's dgemm: each entry
    ``fma(l1, r1j, l0 * r0j)``; a single row is NumPy's own unfused product), checked against
    NumPy in tests/test_maps.py. Written out, the layouts no longer depend on the BLAS."""
    out = np.empty_like(local)
    for i in range(local.shape[0]):
        if local.shape[0] == 1:
            out[i, 0] = local[i, 0] * cos_h + local[i, 1] * -sin_h
            out[i, 1] = local[i, 0] * sin_h + local[i, 1] * cos_h
        else:
            out[i, 0] = _fma(local[i, 1], -sin_h, local[i, 0] * cos_h)
            out[i, 1] = _fma(local[i, 1], cos_h, local[i, 0] * sin_h)
    return out


@njit(cache=True)
def _spread(points: NDArray[np.float64], centre: NDArray[np.float64], normal: NDArray[np.float64]) -> float:
    """``abs((points - centre) @ normal).max()`` as NumPy computes it (OpenBLAS's dgemv: each
    entry ``fma(d0, n0, d1 * n1)``)."""
    widest = 0.0
    for i in range(points.shape[0]):
        d0 = points[i, 0] - centre[0]
        d1 = points[i, 1] - centre[1]
        widest = max(widest, abs(_fma(d0, normal[0], d1 * normal[1])))
    return widest


@njit(cache=True)
def _row_mean(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """``points.mean(axis=0)`` as NumPy computes it: rows summed in order, then divided."""
    total = points[0].copy()
    for i in range(1, points.shape[0]):
        total = total + points[i]
    mean: NDArray[np.float64] = total / points.shape[0]
    return mean


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


def _place_slip_zones(
    rng: np.random.Generator,
    corridor: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float],
    config: RandomMapConfig,
) -> tuple[SlipZone, ...]:
    """``config.n_slip_zones`` circles in the corridor (a, b: the start and target centroids, the
    unit normal of a -> b, the half width: the team's spread across it plus 1 m), overlapping anything
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


@njit(cache=True)
def _place_obstacles_kernel(
    rng: np.random.Generator,
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    normal: NDArray[np.float64],
    half_width: float,
    keep_clear: NDArray[np.float64],
    n_obstacles: int,
    settings: NDArray[np.float64],
    workspace: NDArray[np.float64],
) -> tuple[NDArray[np.float64], bool]:
    """Obstacles along the corridor between the start and target centroids (a rejection sampler;
    ``placed, False`` if stuck), compiled: a reset of a vector env with ``map="random"`` spent
    ~3 ms here in Python. It draws from ``rng`` exactly as the Python
    version did (numba's Generator shares NumPy's bit stream and algorithms), so the same seed
    gives the same layout (tests/data/random_layouts.json). ``settings`` as
    :func:`_draw_layout`'s: obstacle radius low/high, along low/high, robot radius, clearance,
    gap."""
    r_low, r_high, along_low, along_high = settings[0], settings[1], settings[2], settings[3]
    robot_radius, clearance, gap = settings[4], settings[5], settings[6]
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
