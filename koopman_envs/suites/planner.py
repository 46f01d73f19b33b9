"""The grid planner of the layout suites: is a robot's target reachable, and along which path.

A robot of radius ``robot_radius`` fits through the layout where its centre keeps
``robot_radius + margin`` from every obstacle (the obstacles *inflated* by that much) and stays
inside the workspace. :func:`shortest_path` searches an 8-connected grid of the workspace
(cells of ``resolution`` metres, a cell free when its centre is clear of every inflated
obstacle; no diagonal step past a blocked corner) with Dijkstra's algorithm, then pulls the
grid path taut: from each vertex it jumps to the farthest later vertex in straight line of
sight of the exact inflated discs. The returned polyline runs from the exact start to the exact
target, so its length is within a few centimetres of the shortest path in the grid's homotopy.

Compiled with numba; deterministic (ties in the search are broken by insertion order).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from koopman_envs.params import PARAMS

__all__ = ["PLANNER_MARGIN", "PLANNER_RESOLUTION", "path_length", "segment_clear", "shortest_path"]

#: grid cell side of the planner [m] (ours): passages within one cell of the inflated minimum
#: may be judged blocked, which only ever rejects a layout (never accepts an infeasible one)
PLANNER_RESOLUTION = 0.1
#: clearance the planner keeps beyond the robot radius [m] (ours): a robot must fit with 5 cm
#: to spare on both sides, so the narrowest passable gap is 2 * (0.2 + 0.05) = 0.5 m
PLANNER_MARGIN = 0.05


@njit(cache=True)
def _free_grid(
    obstacles: NDArray[np.float64], inflation: float, x0: float, y0: float, nx: int, ny: int, res: float
) -> NDArray[np.bool_]:  # pragma: no cover - compiled
    """(ny, nx) cells, True where the centre keeps ``inflation`` from every obstacle's surface."""
    free = np.ones((ny, nx), dtype=np.bool_)
    for k in range(obstacles.shape[0]):
        cx, cy, reach = obstacles[k, 0], obstacles[k, 1], obstacles[k, 2] + inflation
        i0 = max(0, int(math.floor((cy - reach - y0) / res - 0.5)))
        i1 = min(ny - 1, int(math.ceil((cy + reach - y0) / res - 0.5)))
        j0 = max(0, int(math.floor((cx - reach - x0) / res - 0.5)))
        j1 = min(nx - 1, int(math.ceil((cx + reach - x0) / res - 0.5)))
        for i in range(i0, i1 + 1):
            y = y0 + (i + 0.5) * res
            for j in range(j0, j1 + 1):
                x = x0 + (j + 0.5) * res
                if (x - cx) * (x - cx) + (y - cy) * (y - cy) < reach * reach:
                    free[i, j] = False
    return free


@njit(cache=True)
def _push(heap_d: NDArray[np.float64], heap_i: NDArray[np.int64], size: int, d: float, v: int) -> int:
    """Push (d, v) onto the binary heap of ``size`` entries; the new size."""
    at = size
    heap_d[at], heap_i[at] = d, v
    while at > 0:
        up = (at - 1) // 2
        if heap_d[up] <= heap_d[at]:
            break
        heap_d[up], heap_d[at] = heap_d[at], heap_d[up]
        heap_i[up], heap_i[at] = heap_i[at], heap_i[up]
        at = up
    return size + 1


@njit(cache=True)
def _pop(heap_d: NDArray[np.float64], heap_i: NDArray[np.int64], size: int) -> tuple[float, int, int]:
    """Pop the smallest entry: (d, v, new size)."""
    d, v = heap_d[0], heap_i[0]
    size -= 1
    heap_d[0], heap_i[0] = heap_d[size], heap_i[size]
    at = 0
    while True:
        left, right, low = 2 * at + 1, 2 * at + 2, at
        if left < size and heap_d[left] < heap_d[low]:
            low = left
        if right < size and heap_d[right] < heap_d[low]:
            low = right
        if low == at:
            break
        heap_d[low], heap_d[at] = heap_d[at], heap_d[low]
        heap_i[low], heap_i[at] = heap_i[at], heap_i[low]
        at = low
    return d, v, size


@njit(cache=True)
def _grid_path(free: NDArray[np.bool_], start: int, goal: int) -> NDArray[np.int64]:
    """Cells (flat indices) of a shortest 8-connected path from ``start`` to ``goal``; empty when
    the goal cannot be reached. A diagonal step needs both cells beside it free."""
    ny, nx = free.shape
    n = ny * nx
    dist = np.full(n, np.inf)
    prev = np.full(n, -1, dtype=np.int64)
    heap_d = np.empty(8 * n + 1)
    heap_i = np.empty(8 * n + 1, dtype=np.int64)
    size = _push(heap_d, heap_i, 0, 0.0, start)
    dist[start] = 0.0
    steps_i = (-1, -1, -1, 0, 0, 1, 1, 1)
    steps_j = (-1, 0, 1, -1, 1, -1, 0, 1)
    while size > 0:
        d, v, size = _pop(heap_d, heap_i, size)
        if v == goal:
            break
        if d > dist[v]:
            continue
        i, j = v // nx, v % nx
        for s in range(8):
            a, b = i + steps_i[s], j + steps_j[s]
            if a < 0 or a >= ny or b < 0 or b >= nx or not free[a, b]:
                continue
            diagonal = steps_i[s] != 0 and steps_j[s] != 0
            if diagonal and not (free[i, b] and free[a, j]):
                continue
            w = a * nx + b
            nd = d + (math.sqrt(2.0) if diagonal else 1.0)
            if nd < dist[w]:
                dist[w] = nd
                prev[w] = v
                size = _push(heap_d, heap_i, size, nd, w)
    if not np.isfinite(dist[goal]):
        return np.empty(0, dtype=np.int64)
    count = 1
    v = goal
    while v != start:
        v = prev[v]
        count += 1
    out = np.empty(count, dtype=np.int64)
    v = goal
    for k in range(count - 1, -1, -1):
        out[k] = v
        v = prev[v]
    return out


@njit(cache=True)
def segment_clear(
    ax: float, ay: float, bx: float, by: float, obstacles: NDArray[np.float64], inflation: float
) -> bool:  # pragma: no cover - compiled
    """True when the segment a-b keeps ``inflation`` from every obstacle's surface (exactly)."""
    dx, dy = bx - ax, by - ay
    length2 = dx * dx + dy * dy
    for k in range(obstacles.shape[0]):
        cx, cy, reach = obstacles[k, 0], obstacles[k, 1], obstacles[k, 2] + inflation
        t = 0.0 if length2 == 0.0 else ((cx - ax) * dx + (cy - ay) * dy) / length2
        t = min(1.0, max(0.0, t))
        px, py = ax + t * dx - cx, ay + t * dy - cy
        if px * px + py * py < reach * reach:
            return False
    return True


@njit(cache=True)
def _pull_taut(
    points: NDArray[np.float64], obstacles: NDArray[np.float64], inflation: float
) -> NDArray[np.float64]:
    """The vertices kept by jumping from each vertex to the farthest later one in line of sight
    (the next one when none is: two neighbouring cells may clip an inflated disc's edge)."""
    count = points.shape[0]
    keep = np.empty(count, dtype=np.int64)
    kept = 1
    keep[0] = 0
    at = 0
    while at < count - 1:
        to = count - 1
        while to > at + 1 and not segment_clear(
            points[at, 0], points[at, 1], points[to, 0], points[to, 1], obstacles, inflation
        ):
            to -= 1
        keep[kept] = to
        kept += 1
        at = to
    return points[keep[:kept]].copy()


def shortest_path(
    obstacles: NDArray[np.float64],
    start: NDArray[np.float64],
    goal: NDArray[np.float64],
    robot_radius: float = PARAMS.robot_radius,
    margin: float = PLANNER_MARGIN,
    resolution: float = PLANNER_RESOLUTION,
    workspace: tuple[float, float, float, float] = PARAMS.workspace,
) -> NDArray[np.float64] | None:
    """A short collision-free path of a disc robot from ``start`` to ``goal``, or None.

    Parameters
    ----------
    obstacles : ndarray, shape (M, 3)
        Circular obstacles: x [m], y [m], radius [m].
    start, goal : ndarray, shape (2,) or (3,)
        Robot centres [m] (a heading entry is ignored).
    robot_radius : float
        Disc radius of the robot [m].
    margin : float
        Clearance kept beyond the radius [m].
    resolution : float
        Grid cell side [m].
    workspace : tuple of float
        (x_min, x_max, y_min, y_max) [m]: the robot's disc stays inside.

    Returns
    -------
    ndarray, shape (P, 2) or None
        The taut polyline from ``start`` to ``goal`` (its first and last rows are the exact
        points), or None when the goal cannot be reached (or either end sits in a blocked cell).
    """
    obstacles = np.ascontiguousarray(obstacles, dtype=np.float64).reshape(-1, 3)
    inflation = float(robot_radius) + float(margin)
    x0, x1, y0, y1 = (float(v) for v in workspace)
    # the centre keeps the inflation from the workspace's edges too: grid only inside that box
    gx0, gy0 = x0 + inflation, y0 + inflation
    nx = int(math.floor((x1 - inflation - gx0) / resolution))
    ny = int(math.floor((y1 - inflation - gy0) / resolution))
    free = _free_grid(obstacles, inflation, gx0, gy0, nx, ny, float(resolution))
    ends = []
    for point in (start, goal):
        j = min(nx - 1, max(0, int(math.floor((float(point[0]) - gx0) / resolution))))
        i = min(ny - 1, max(0, int(math.floor((float(point[1]) - gy0) / resolution))))
        if not free[i, j]:
            return None
        ends.append(i * nx + j)
    cells = _grid_path(free, ends[0], ends[1])
    if cells.size == 0:
        return None
    points = np.empty((cells.size, 2))
    points[:, 0] = gx0 + (cells % nx + 0.5) * resolution
    points[:, 1] = gy0 + (cells // nx + 0.5) * resolution
    points[0] = start[:2]
    points[-1] = goal[:2]
    result: NDArray[np.float64] = _pull_taut(points, obstacles, inflation)
    return result


def path_length(path: NDArray[np.float64]) -> float:
    """Length of a polyline (P, 2) [m]."""
    return float(np.sum(np.hypot(*np.diff(path, axis=0).T)))
