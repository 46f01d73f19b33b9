"""Relative geometry of a batch of teams: one pass serves collisions and observations.

For every robot i the offsets, distances and surface clearances to every "entity" (all robots,
then all obstacles) are computed once per step. Collision checks and observation features both
read this result, so the step does the pairwise work a single time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["Geometry", "TeamGeometry"]


@dataclass
class Geometry:
    """Pairwise geometry of K environments of N robots and M obstacles (E = N + M entities).

    Attributes
    ----------
    dx, dy : ndarray, shape (K, N, E)
        World-frame offset from robot i to entity e [m].
    clearance : ndarray, shape (K, N, E)
        Surface-to-surface distance [m]; +inf from a robot to itself, negative on overlap.
    """

    dx: NDArray[np.float64]
    dy: NDArray[np.float64]
    clearance: NDArray[np.float64]


class TeamGeometry:
    """Holds obstacle layouts and radius sums of K environments and computes :class:`Geometry`.

    Parameters
    ----------
    num_envs : int
        Batch size K.
    robot_radius : ndarray, shape (N,)
        Robot radii [m].
    n_obstacles : int
        Obstacles per environment M.
    """

    def __init__(self, num_envs: int, robot_radius: NDArray, n_obstacles: int) -> None:
        n = robot_radius.shape[0]
        self.n_robots = n
        self.n_obstacles = int(n_obstacles)
        self.robot_radius = np.asarray(robot_radius, dtype=np.float64)
        self._ex = np.zeros((num_envs, n + self.n_obstacles))
        self._ey = np.zeros((num_envs, n + self.n_obstacles))
        self._radius_sum = np.zeros((num_envs, n, n + self.n_obstacles))
        pair = self.robot_radius[:, None] + self.robot_radius[None, :]
        # -inf on the diagonal turns a robot's clearance to itself into +inf without a mask
        pair[np.arange(n), np.arange(n)] = -np.inf
        self._radius_sum[:, :, :n] = pair

    def set_obstacles(self, index: int, obstacles: NDArray) -> None:
        """Install the (M, 3) obstacles (x, y, radius) of environment ``index``."""
        n = self.n_robots
        self._ex[index, n:] = obstacles[:, 0]
        self._ey[index, n:] = obstacles[:, 1]
        self._radius_sum[index, :, n:] = obstacles[None, :, 2] + self.robot_radius[:, None]

    def compute(self, x: NDArray, y: NDArray) -> Geometry:
        """Geometry for robot centres ``x``, ``y`` of shape (K, N) [m]."""
        n = self.n_robots
        self._ex[:, :n] = x
        self._ey[:, :n] = y
        dx = self._ex[:, None, :] - x[:, :, None]
        dy = self._ey[:, None, :] - y[:, :, None]
        # sqrt of squares rather than hypot: the values are metres, and hypot is ~10x slower
        clearance = dx * dx
        clearance += dy * dy
        np.sqrt(clearance, out=clearance)
        clearance -= self._radius_sum
        return Geometry(dx, dy, clearance)
