"""Relative geometry of robot teams: the clearance formula and the per-environment layout data.

:func:`clearance` is the one definition of surface-to-surface distance; the collision checks
(:mod:`koopman_envs.sim.collision`) and the observation features
(:mod:`koopman_envs.tasks.observation`) both call it from their compiled kernels, so a robot
that "touches" an obstacle in the collision check reads a negative clearance in its features.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["TeamGeometry", "clearance"]


@njit(cache=True)
def clearance(x: float, y: float, other_x: float, other_y: float, radius_sum: float) -> float:
    """Surface-to-surface distance of two discs [m] (negative on overlap).

    ``sqrt`` of squares rather than ``hypot``: the values are metres, and hypot is much slower.
    """
    dx = other_x - x
    dy = other_y - y
    return math.sqrt(dx * dx + dy * dy) - radius_sum


@njit(cache=True)
def _clearances(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    entity_x: NDArray[np.float64],
    entity_y: NDArray[np.float64],
    radius_sum: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:  # pragma: no cover - compiled
    n_envs, n_robots = x.shape
    for k in range(n_envs):
        for i in range(n_robots):
            for e in range(entity_x.shape[1]):
                out[k, i, e] = clearance(
                    x[k, i], y[k, i], entity_x[k, e], entity_y[k, e], radius_sum[k, i, e]
                )


class TeamGeometry:
    """Obstacle layouts and radius sums of K environments (the inputs of the compiled kernels).

    Parameters
    ----------
    num_envs : int
        Batch size K.
    robot_radius : ndarray, shape (N,)
        Robot radii [m].
    n_obstacles : int
        Obstacles per environment M.

    Attributes
    ----------
    obstacles : ndarray, shape (K, 3, M)
        Every environment's obstacle set, channel-first as the engine's state: rows x, y of the
        centres and the radii [m] (the count is the array's, M; a map lists them as (M, 3)). A
        kernel's loop over the obstacles then reads consecutive memory, which the compiler
        vectorizes.
    radius_sum : ndarray, shape (K, N, N + M)
        Robot i's radius plus entity e's (robots first, then obstacles); -inf from a robot to
        itself, which makes its clearance to itself +inf without a mask.
    """

    def __init__(self, num_envs: int, robot_radius: NDArray[np.float64], n_obstacles: int) -> None:
        n = robot_radius.shape[0]
        self.n_robots = n
        self.n_obstacles = int(n_obstacles)
        self.robot_radius = np.asarray(robot_radius, dtype=np.float64)
        self.obstacles = np.zeros((num_envs, 3, self.n_obstacles))
        self.radius_sum = np.zeros((num_envs, n, n + self.n_obstacles))
        pair = self.robot_radius[:, None] + self.robot_radius[None, :]
        pair[np.arange(n), np.arange(n)] = -np.inf
        self.radius_sum[:, :, :n] = pair

    def set_obstacles(self, index: int, obstacles: NDArray[np.float64]) -> None:
        """Install the (M, 3) obstacles (x, y, radius) of environment ``index``."""
        self.obstacles[index] = obstacles.T
        self.radius_sum[index, :, self.n_robots :] = obstacles[None, :, 2] + self.robot_radius[:, None]

    def clearances(
        self, x: NDArray[np.float64], y: NDArray[np.float64], rows: NDArray[np.intp] | None = None
    ) -> NDArray[np.float64]:
        """Clearance of every robot to every entity, shape (K, N, N + M) [m], for centres ``x``, ``y``
        of shape (K, N) [m]; +inf from a robot to itself, negative on overlap. With ``rows`` (indices
        of environments), ``x`` and ``y`` hold only those environments and so does the result."""
        x = np.ascontiguousarray(x, dtype=np.float64)
        y = np.ascontiguousarray(y, dtype=np.float64)
        obstacles, radius_sum = self.obstacles, self.radius_sum
        if rows is not None:
            obstacles, radius_sum = obstacles[rows], radius_sum[rows]
        entity_x = np.concatenate([x, obstacles[:, 0]], axis=1)
        entity_y = np.concatenate([y, obstacles[:, 1]], axis=1)
        out = np.empty(radius_sum.shape)
        _clearances(x, y, entity_x, entity_y, np.ascontiguousarray(radius_sum), out)
        return out
