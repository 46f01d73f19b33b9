"""Collision checks between disc robots, circular obstacles, movers and the workspace box, and
whose fault a collision is (:class:`CollisionFault`), batched and compiled."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from koopman_envs.checks import check_choice
from koopman_envs.sim.geometry import TeamGeometry, clearance

__all__ = ["CollisionFault", "CollisionKind", "check_collisions", "collision_flags", "mover_collisions"]


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


class CollisionFault:
    """Whose fault a robot's collision is: one code per robot in ``info["collision_fault"]``.

    The rule (docs/movers.md, "Who is at fault"): a contact with a static obstacle, a team-mate
    (both robots) or the workspace's edge is always the robot's; a contact with a mover is the
    mover's when, over the period of the contact, the robot was stopped (speed below
    :data:`~koopman_envs.params.FAULT_STOPPED_SPEED`) or moving away from the mover (its velocity
    has a non-positive component along the direction from its centre to the mover's), and the
    robot's otherwise. A robot with several contacts in a period is at fault if any one is its.
    """

    NONE = 0
    #: the robot ran into something
    ROBOT = 1
    #: a mover ran into the robot (every contact of the robot this period)
    MOVER = 2

    NAMES = {NONE: "", ROBOT: "robot", MOVER: "mover"}

    @classmethod
    def describe(cls, code: int) -> str:
        """``"robot"``, ``"mover"`` or ``""`` (no collision) for a code of ``info["collision_fault"]``."""
        check_choice("collision fault code", code, sorted(cls.NAMES), sep=" ")
        return cls.NAMES[int(code)]


_ROBOT, _OBSTACLE, _WORKSPACE = CollisionKind.ROBOT, CollisionKind.OBSTACLE, CollisionKind.WORKSPACE
_NO_FAULT, _ROBOT_FAULT, _MOVER_FAULT = CollisionFault.NONE, CollisionFault.ROBOT, CollisionFault.MOVER


@njit(cache=True)
def collision_flags(
    state: NDArray[np.float64],
    obstacles: NDArray[np.float64],
    radius_sum: NDArray[np.float64],
    workspace: NDArray[np.float64],
    out: NDArray[np.int64],
) -> None:  # pragma: no cover - compiled
    """Collision flags of K teams (compiled).

    Parameters
    ----------
    state : ndarray, shape (K, 3, N)
        Rows x [m], y [m], theta [rad].
    obstacles : ndarray, shape (K, 3, M)
        Obstacle sets, rows x, y, radius [m] (the radius sums below hold the radii).
    radius_sum : ndarray, shape (K, N, N + M)
        Radius sums, robots first (see :class:`~koopman_envs.sim.geometry.TeamGeometry`).
    workspace : ndarray, shape (4,)
        (x_min, x_max, y_min, y_max) [m]; a centre outside it is a workspace exit, as in the
        paper's state constraint.
    out : ndarray of int, shape (K,)
        Bitwise OR of :class:`CollisionKind` flags per environment (0 = no collision).
    """
    n_envs, _, n_robots = state.shape
    n_obstacles = obstacles.shape[2]
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
                if (
                    clearance(x, y, obstacles[k, 0, m], obstacles[k, 1, m], radius_sum[k, i, n_robots + m])
                    < 0.0
                ):
                    flags |= _OBSTACLE
        out[k] = flags


@njit(cache=True)
def mover_collisions(
    motion: tuple[NDArray[np.float64], NDArray[np.float64]],
    robot_radius: NDArray[np.float64],
    position: NDArray[np.float64],
    mover_radius: NDArray[np.float64],
    rows: NDArray[np.int64],
    stepping: NDArray[np.bool_],
    flag: int,
    stopped_step: float,
    marks: tuple[NDArray[np.int64], NDArray[np.bool_], NDArray[np.int64]],
) -> None:  # pragma: no cover - compiled
    """OR ``flag`` into ``collision[k]`` for every environment of ``rows`` where a robot overlaps a
    mover, mark that robot in ``robot_hit`` (K, N), and in the ``stepping`` environments write
    whose fault its contacts are into ``fault`` (K, N) (``marks`` is the tuple ``collision``,
    ``robot_hit``, ``fault``), by the rule of
    :class:`~koopman_envs.sim.collision.CollisionFault`: the robot's when it moved at least
    ``stopped_step`` [m] over the period (``FAULT_STOPPED_SPEED`` x dt) with a positive
    component towards the mover's centre, else the mover's. ``motion`` is the tuple ``before``,
    ``state``: the robots' poses (K, 3, N) at the start and the end of the period; the contact is
    judged at its end, where it is seen."""
    before, state = motion
    collision, robot_hit, fault = marks
    for k in rows:
        judged = stepping[k]
        for i in range(state.shape[2]):
            x, y = state[k, 0, i], state[k, 1, i]
            # the displacement over the period is the robot's mean velocity times dt: the rule
            # needs only its length and the sign of its component towards a mover
            mx, my = x - before[k, 0, i], y - before[k, 1, i]
            moving = mx * mx + my * my >= stopped_step * stopped_step
            if judged:
                fault[k, i] = _NO_FAULT
            for c in range(position.shape[1]):
                dx, dy = position[k, c, 0] - x, position[k, c, 1] - y
                reach = robot_radius[i] + mover_radius[c]
                if dx * dx + dy * dy < reach * reach:
                    collision[k] |= flag
                    robot_hit[k, i] = True
                    if not judged:
                        continue
                    if moving and mx * dx + my * dy > 0.0:
                        fault[k, i] = _ROBOT_FAULT
                    elif fault[k, i] == _NO_FAULT:
                        fault[k, i] = _MOVER_FAULT


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
    collision_flags(state, geo.obstacles, geo.radius_sum, bounds, out)
    return int(out[0])
