"""Nearest first: the one ordering of discs by clearance that the observations, the RL set
features and the controllers' obstacle and neighbour slots all use.

The order is the stable sort of the clearances: nearest first, equal clearances in index order.
:func:`nearest_first` computes it inside compiled (numba) kernels, :func:`nearest_order` on numpy
arrays; both give the same order for the same values (``tests/test_nearest.py``).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = [
    "disc_clearance",
    "nearest_by_clearance",
    "nearest_first",
    "nearest_first_by_rank",
    "nearest_order",
    "obstacle_clearances",
    "smallest_clearances",
]


@njit(cache=True)
def nearest_first(gap: NDArray[np.float64], order: NDArray[np.int64], count: int) -> None:
    """Write into ``order[:count]`` the indices 0..count-1 sorted by ``gap`` (stable insertion
    sort: equal gaps keep index order). For compiled kernels; allocates nothing."""
    for m in range(count):
        order[m] = m
        q = m
        while q > 0 and gap[order[q - 1]] > gap[m]:
            order[q] = order[q - 1]
            q -= 1
        order[q] = m


@njit(cache=True)
def nearest_first_by_rank(gap: NDArray[np.float64], order: NDArray[np.int64], count: int) -> None:
    """:func:`nearest_first`'s order, found by counting each entry's rank (how many are nearer,
    or as near with a lower index). Quadratic, but without a data-dependent branch: for the few
    (up to a few dozen) entries of a per-robot list it is faster than the insertion sort, whose
    mispredicted branches dominate on random distances."""
    for m in range(count):
        g = gap[m]
        rank = 0
        for j in range(count):
            rank += (gap[j] < g) | ((gap[j] == g) & (j < m))
        order[rank] = m


def nearest_order(gap: NDArray[np.float64], k: int) -> NDArray[np.intp]:
    """Indices of the ``k`` smallest gaps along the last axis, nearest first (stable: equal gaps
    in index order), shape ``gap.shape[:-1] + (min(k, m),)``."""
    return np.argsort(gap, axis=-1, kind="stable")[..., :k]


def disc_clearance(points: NDArray[np.float64], discs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance from each point (N, 2) to each disc's surface (M, 3: x, y, r), shape (N, M) [m]."""
    clearance: NDArray[np.float64] = (
        np.hypot(*(points[:, None, :] - discs[None, :, :2]).transpose(2, 0, 1)) - discs[:, 2]
    )
    return clearance


def nearest_by_clearance(points: NDArray[np.float64], discs: NDArray[np.float64], k: int) -> NDArray[np.intp]:
    """Each point's ``k`` nearest discs by surface clearance, nearest first, shape (N, min(k, M))."""
    return nearest_order(disc_clearance(points, discs), k)


@njit(cache=True, nogil=True)
def smallest_clearances(
    xy: NDArray[np.float64],
    radius: NDArray[np.float64],
    obstacles: NDArray[np.float64],
    movers: NDArray[np.float64],
    mover_radius: float,
) -> tuple[float, float, float]:
    """The smallest surface clearance of any robot (``xy`` (N, 2), ``radius`` (N,)) to the
    obstacles (M, 3: x, y, r), to a team-mate, and to the movers (C, >= 2: x, y, ...) of
    ``mover_radius`` [m]; inf where there is none.

    Each clearance is computed as the numpy expression ``norm(a - b) - r_a - r_b`` evaluates it
    (the squares summed x first, then the radii subtracted in that order), so the minima are
    those of the vectorised form to the bit.
    """
    n = xy.shape[0]
    low_obstacle = low_robot = low_mover = np.inf
    for i in range(n):
        x, y, r = xy[i, 0], xy[i, 1], radius[i]
        for m in range(obstacles.shape[0]):
            dx, dy = x - obstacles[m, 0], y - obstacles[m, 1]
            low_obstacle = min(low_obstacle, np.sqrt(dx * dx + dy * dy) - r - obstacles[m, 2])
        for j in range(i + 1, n):
            dx, dy = x - xy[j, 0], y - xy[j, 1]
            low_robot = min(low_robot, np.sqrt(dx * dx + dy * dy) - r - radius[j])
        for c in range(movers.shape[0]):
            dx, dy = x - movers[c, 0], y - movers[c, 1]
            low_mover = min(low_mover, np.sqrt(dx * dx + dy * dy) - r - mover_radius)
    return low_obstacle, low_robot, low_mover


@njit(cache=True, nogil=True)
def obstacle_clearances(
    xy: NDArray[np.float64], radius: NDArray[np.float64], obstacles: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Each robot's smallest surface clearance to the obstacles, shape (N,) [m] (inf without
    obstacles); computed as :func:`smallest_clearances` computes it, so that the smallest of
    them is that function's obstacle clearance to the bit."""
    n = xy.shape[0]
    out = np.full(n, np.inf)
    for i in range(n):
        x, y, r = xy[i, 0], xy[i, 1], radius[i]
        for m in range(obstacles.shape[0]):
            dx, dy = x - obstacles[m, 0], y - obstacles[m, 1]
            out[i] = min(out[i], np.sqrt(dx * dx + dy * dy) - r - obstacles[m, 2])
    return out
