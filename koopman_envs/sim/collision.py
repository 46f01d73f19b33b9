"""Collision checks between disc robots, circular obstacles and the workspace box, batched."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from koopman_envs.sim.geometry import Geometry, TeamGeometry

__all__ = ["CollisionKind", "check_collisions", "collision_flags"]


class CollisionKind:
    """Bit flags of the collision kinds a step can report (they can combine)."""

    NONE = 0
    OBSTACLE = 1
    ROBOT = 2
    WORKSPACE = 4

    NAMES = {OBSTACLE: "obstacle", ROBOT: "robot", WORKSPACE: "workspace"}

    @classmethod
    def describe(cls, flags: int) -> str:
        """Human-readable name of a flag combination, e.g. ``"obstacle+robot"`` or ``"none"``."""
        names = [name for bit, name in cls.NAMES.items() if int(flags) & bit]
        return "+".join(names) if names else "none"


def collision_flags(
    geometry: Geometry, x: NDArray, y: NDArray, workspace: tuple[float, float, float, float]
) -> NDArray[np.int64]:
    """Collision flags from precomputed geometry.

    Parameters
    ----------
    geometry : Geometry
        Pairwise geometry of the same positions.
    x, y : ndarray, shape (K, N)
        Robot centres [m].
    workspace : tuple of float
        (x_min, x_max, y_min, y_max) [m]; a centre outside it is a workspace exit, as in the
        paper's state constraint.

    Returns
    -------
    ndarray of int, shape (K,)
        Bitwise OR of :class:`CollisionKind` flags per environment (0 = no collision).
    """
    k, n = x.shape
    n_entities = geometry.clearance.shape[2]
    # one column per entity (any robot overlapping it) plus one for "some robot is outside"
    touched = np.empty((k, n_entities + 1), dtype=bool)
    np.logical_or.reduce(geometry.clearance < 0.0, axis=1, out=touched[:, :n_entities])
    outside = x < workspace[0]
    outside |= x > workspace[1]
    outside |= y < workspace[2]
    outside |= y > workspace[3]
    np.logical_or.reduce(outside, axis=1, out=touched[:, n_entities])
    # segments: robots [0, n), obstacles [n, E), workspace [E]
    if n_entities > n:
        kinds = np.logical_or.reduceat(touched, [0, n, n_entities], axis=1)
        return kinds.dot(_CODES_WITH_OBSTACLES)
    kinds = np.logical_or.reduceat(touched, [0, n_entities], axis=1)
    return kinds.dot(_CODES_WITHOUT_OBSTACLES)


_CODES_WITH_OBSTACLES = np.array([CollisionKind.ROBOT, CollisionKind.OBSTACLE, CollisionKind.WORKSPACE])
_CODES_WITHOUT_OBSTACLES = np.array([CollisionKind.ROBOT, CollisionKind.WORKSPACE])


def check_collisions(
    positions: NDArray,
    obstacles: NDArray,
    robot_radius: NDArray,
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
    x, y = positions[None, :, 0].copy(), positions[None, :, 1].copy()
    obstacles = np.asarray(obstacles, dtype=np.float64).reshape(-1, 3)
    geo = TeamGeometry(1, np.asarray(robot_radius, dtype=np.float64), obstacles.shape[0])
    geo.set_obstacles(0, obstacles)
    return int(collision_flags(geo.compute(x, y), x, y, workspace)[0])
