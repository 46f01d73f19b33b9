"""Collision checks between disc robots, circular obstacles and the workspace box, batched and compiled."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from koopman_envs.sim.geometry import TeamGeometry, clearance

__all__ = ["CollisionKind", "check_collisions", "collision_flags"]


class CollisionKind:
    """Bit flags of the collision kinds a step can report (they can combine)."""

    NONE = 0
    OBSTACLE = 1
    ROBOT = 2
    WORKSPACE = 4
    #: a moving obstacle (``movers`` keyword)
    MOVER = 8

    NAMES = {OBSTACLE: "obstacle", ROBOT: "robot", WORKSPACE: "workspace", MOVER: "mover"}

    @classmethod
    def describe(cls, flags: int) -> str:
        """Human-readable name of a flag combination, e.g. ``"obstacle+robot"`` or ``"none"``."""
        names = [name for bit, name in cls.NAMES.items() if int(flags) & bit]
        return "+".join(names) if names else "none"


_ROBOT, _OBSTACLE, _WORKSPACE = CollisionKind.ROBOT, CollisionKind.OBSTACLE, CollisionKind.WORKSPACE


@njit(cache=True)
def collision_flags(
    state: NDArray[np.float64],
    obstacle_x: NDArray[np.float64],
    obstacle_y: NDArray[np.float64],
    radius_sum: NDArray[np.float64],
    workspace: NDArray[np.float64],
    out: NDArray[np.int64],
) -> None:  # pragma: no cover - compiled
    """Collision flags of K teams (compiled).

    Parameters
    ----------
    state : ndarray, shape (K, 3, N)
        Rows x [m], y [m], theta [rad].
    obstacle_x, obstacle_y : ndarray, shape (K, M)
        Obstacle centres [m].
    radius_sum : ndarray, shape (K, N, N + M)
        Radius sums, robots first (see :class:`~koopman_envs.sim.geometry.TeamGeometry`).
    workspace : ndarray, shape (4,)
        (x_min, x_max, y_min, y_max) [m]; a centre outside it is a workspace exit, as in the
        paper's state constraint.
    out : ndarray of int, shape (K,)
        Bitwise OR of :class:`CollisionKind` flags per environment (0 = no collision).
    """
    n_envs, _, n_robots = state.shape
    n_obstacles = obstacle_x.shape[1]
    for k in range(n_envs):
        flags = 0
        for i in range(n_robots):
            x, y = state[k, 0, i], state[k, 1, i]
            if x < workspace[0] or x > workspace[1] or y < workspace[2] or y > workspace[3]:
                flags |= _WORKSPACE
            for j in range(i + 1, n_robots):
                if clearance(x, y, state[k, 0, j], state[k, 1, j], radius_sum[k, i, j]) < 0.0:
                    flags |= _ROBOT
            for m in range(n_obstacles):
                if clearance(x, y, obstacle_x[k, m], obstacle_y[k, m], radius_sum[k, i, n_robots + m]) < 0.0:
                    flags |= _OBSTACLE
        out[k] = flags


def check_collisions(
    positions: NDArray[np.float64],
    obstacles: NDArray[np.float64],
    robot_radius: NDArray[np.float64],
    workspace: tuple[float, float, float, float],
) -> int:
    """Collision flags of one team: a convenience wrapper of :func:`collision_flags`.

    Parameters
    ----------
    positions : ndarray, shape (N, 2)
        Robot centres [m].
    obstacles : ndarray, shape (M, 3)
        Obstacles (x, y, radius) [m].
    robot_radius : ndarray, shape (N,)
        Robot radii [m].
    workspace : tuple of float
        (x_min, x_max, y_min, y_max) [m].

    Returns
    -------
    int
        Bitwise OR of :class:`CollisionKind` flags.
    """
    positions = np.asarray(positions, dtype=np.float64)
    state = np.zeros((1, 3, positions.shape[0]))
    state[0, :2] = positions.T
    obstacles = np.asarray(obstacles, dtype=np.float64).reshape(-1, 3)
    geo = TeamGeometry(1, np.asarray(robot_radius, dtype=np.float64), obstacles.shape[0])
    geo.set_obstacles(0, obstacles)
    out = np.zeros(1, dtype=np.int64)
    bounds = np.asarray(workspace, dtype=np.float64)
    collision_flags(state, geo.obstacle_x, geo.obstacle_y, geo.radius_sum, bounds, out)
    return int(out[0])
