"""Detour waypoints of the distributed NMPC: when the straight line from a robot to its goal runs
through an obstacle, a point beside that obstacle on the side the line passes. A
distance-tracking cost has a local minimum behind an obstacle straight ahead, and the horizon is
too short to see around it; a waypoint on the tangent leads the robot around instead."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["DETOUR_CLEARANCE", "DETOUR_LEAD", "detour_waypoint", "tangent_waypoint"]

#: extra distance [m] a detour waypoint keeps from an obstacle's inflated disc (ours)
DETOUR_CLEARANCE = 0.3
#: how far [m] beyond the tangent point a detour waypoint lies (ours)
DETOUR_LEAD = 1.0


def tangent_waypoint(
    position: NDArray[np.float64], centre: NDArray[np.float64], radius: float, side: NDArray[np.float64]
) -> NDArray[np.float64]:
    """A point on the tangent from ``position`` to the circle (``centre``, ``radius``) that
    touches it on ``side`` (a unit vector from the centre), ``DETOUR_LEAD`` beyond the tangent
    point: the straight path to it clears the circle."""
    to_robot = position - centre
    distance = float(np.hypot(*to_robot))
    # a robot already within the clearance ring (pressed against the obstacle) takes the tangent
    # of a ring just inside its own distance: the waypoint then leads around the obstacle
    radius = min(radius, 0.95 * distance)
    # the tangent point seen from the centre: angle acos(r / d) from the robot's direction,
    # turned toward ``side``
    base = np.arctan2(to_robot[1], to_robot[0])
    turn = np.arccos(radius / distance)
    candidates = [base + turn, base - turn]
    touch = max(
        (centre + radius * np.array([np.cos(a), np.sin(a)]) for a in candidates),
        key=lambda point: float(np.dot(point - centre, side)),
    )
    direction = (touch - position) / np.hypot(*(touch - position))
    return touch + DETOUR_LEAD * direction


def detour_waypoint(
    position: NDArray[np.float64], target: NDArray[np.float64], obstacles: NDArray[np.float64], inflate: float
) -> NDArray[np.float64]:
    """``target``, or a waypoint around the first obstacle the straight line to it runs through.

    Parameters
    ----------
    position, target : ndarray, shape (2,)
        The robot's position and its goal [m].
    obstacles : ndarray, shape (M, 3)
        Obstacle discs (x, y, radius) [m].
    inflate : float
        What each obstacle's radius grows by: the robot's radius, its margin and
        :data:`DETOUR_CLEARANCE` [m].
    """
    line = target - position
    length = float(np.hypot(*line))
    if length < 1e-9:
        return target
    along = line / length
    best: tuple[float, NDArray[np.float64]] | None = None
    for x, y, r in obstacles:
        centre = np.array([x, y])
        reach = r + inflate
        t = float(np.clip(np.dot(centre - position, along), 0.0, length))
        closest = position + t * along
        offset = closest - centre
        gap = float(np.hypot(*offset))
        if gap >= reach or t <= 0.0 or np.hypot(*(target - centre)) <= reach:
            continue  # clear of the line, behind the robot, or the target is beside it
        if best is None or t < best[0]:
            side = offset / gap if gap > 1e-9 else np.array([-along[1], along[0]])
            best = (t, tangent_waypoint(position, centre, reach, side))
    return target if best is None else best[1]
