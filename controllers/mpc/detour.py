"""Detour waypoints of the distributed NMPC: when the straight line from a robot to its goal runs
through an obstacle, a point beside that obstacle on the side the line passes. A
distance-tracking cost has a local minimum behind an obstacle straight ahead, and the horizon is
too short to see around it; a waypoint on the tangent leads the robot around instead."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "DETOUR_CLEARANCE",
    "DETOUR_LEAD",
    "DETOUR_PERIODS",
    "RESTART_ITERATIONS",
    "STALL_DISTANCE",
    "STALL_PERIODS",
    "YIELD_CLEARANCE",
    "DeadlockResolver",
    "StallMonitor",
    "detour_waypoint",
    "pursuit_rollout",
    "tangent_waypoint",
]

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


#: a robot that moved less than STALL_DISTANCE [m] in STALL_PERIODS periods while away from its
#: target (more than twice the goal tolerance) has stalled (ours)
STALL_PERIODS = 10
STALL_DISTANCE = 0.02
#: periods a stalled robot follows its detour before it tracks its target again (ours: 3 s, the
#: time to drive 1.5 m, past the robot or obstacle that blocked it)
DETOUR_PERIODS = 30
#: SQP steps of the real-time iteration in the period a stall restarts it from a pursuit rollout
RESTART_ITERATIONS = 10
#: how far [m], beyond both radii and the pair's margin, a yielding robot steps aside from the
#: straight path of the robot it gives way to (ours)
YIELD_CLEARANCE = 0.3


class StallMonitor:
    """Which robots have stalled: moved less than :data:`STALL_DISTANCE` in
    :data:`STALL_PERIODS` periods while farther than twice the goal tolerance from their target.

    A robot's history restarts when it is named stalled, so that whatever resolves the stall has
    :data:`STALL_PERIODS` periods before it is judged again.
    """

    def __init__(self, n_robots: int) -> None:
        self._history: list[list[NDArray[np.float64]]] = [[] for _ in range(n_robots)]

    def stalled(
        self, i: int, position: NDArray[np.float64], target: NDArray[np.float64], tolerance: float
    ) -> bool:
        """Record robot ``i``'s ``position`` (2,) this period; whether it has stalled."""
        history = self._history[i]
        history.append(np.array(position[:2], dtype=np.float64))
        if len(history) <= STALL_PERIODS:
            return False
        history.pop(0)
        away = np.hypot(*(position[:2] - target[:2])) > 2 * tolerance
        if away and np.hypot(*(history[-1] - history[0])) < STALL_DISTANCE:
            history.clear()
            return True
        return False


def _blocks(position: NDArray, goal: NDArray, other: NDArray, reach: float) -> bool:
    """Whether a disc of radius ``reach`` at ``other`` lies on the straight path ``position`` ->
    ``goal`` (ahead of the robot, not beyond its goal)."""
    line = goal - position
    length = float(np.hypot(*line))
    if length < 1e-9:
        return False
    t = float(np.dot(other - position, line / length))
    return 0.0 < t < length + reach and float(np.hypot(*(position + t * line / length - other))) < reach


class DeadlockResolver:
    """The central NMPC's way out of a stall (ours; on by default, ``unstall``): a distance-tracking
    cost has local minima where a robot faces an obstacle on its straight path, or where two
    robots' paths cross and each blocks the other (Map 2's crossing), and the real-time
    iteration, one QP per period from the last plan, stays in them.

    A robot named stalled by :class:`StallMonitor` gets, for :data:`DETOUR_PERIODS` periods:

    - when it blocks a team-mate's straight path, or a team-mate blocks its own, and it has the
      lower priority (the higher index: a fixed order, so two robots never both yield), a point
      :data:`YIELD_CLEARANCE` beyond both radii to the side of the other robot's straight path
      on which it stands: it steps out of the way;
    - else, when an obstacle lies on its straight path, the detour waypoint beside it
      (:func:`detour_waypoint`, as the distributed NMPC's);
    - else its target (a restart from the last plan is all it needs).

    Without a stall every goal is the robot's target: the controller is unchanged, bit for bit.

    Parameters
    ----------
    radii : ndarray, shape (N,)
        The robots' radii [m].
    obstacles : ndarray, shape (M, 3)
        The map's obstacles.
    margin : float
        The pair and obstacle margin the NMPC keeps [m].
    """

    def __init__(self, radii: NDArray[np.float64], obstacles: NDArray[np.float64], margin: float) -> None:
        self.radii = np.asarray(radii, dtype=np.float64)
        self.obstacles = np.asarray(obstacles, dtype=np.float64).reshape(-1, 3)
        self.margin = float(margin)
        n = self.radii.size
        self.monitor = StallMonitor(n)
        self._detour: list[tuple[NDArray[np.float64], int] | None] = [None] * n

    @classmethod
    def for_scenario(cls, scenario: Any, margin: float) -> DeadlockResolver:
        """The resolver of an episode on ``scenario`` (its robots' radii, its obstacles)."""
        return cls(scenario.robot_radius, scenario.obstacles, margin)

    def goals(
        self, positions: NDArray[np.float64], targets: NDArray[np.float64], tolerance: float
    ) -> tuple[NDArray[np.float64], list[str]]:
        """This period's goal of every robot (N, 2), and the rule each newly stalled robot got
        (``"yield"``, ``"obstacle"`` or ``"restart"``; its solver should restart).
        ``positions`` (N, >=2) as the controller plans from them."""
        positions = np.asarray(positions, dtype=np.float64)[:, :2]
        goals = np.array(targets, dtype=np.float64)[:, :2]
        started = []
        for i in range(goals.shape[0]):
            if self.monitor.stalled(i, positions[i], goals[i], tolerance):
                kind, point = self._waypoint(i, positions, goals)
                self._detour[i] = (point, DETOUR_PERIODS)
                started.append(kind)
        for i, detour in enumerate(self._detour):
            if detour is None:
                continue
            point, left = detour
            goals[i] = point
            self._detour[i] = (point, left - 1) if left > 1 else None
        return goals, started

    def _waypoint(self, i: int, positions: NDArray, goals: NDArray) -> tuple[str, NDArray[np.float64]]:
        for j in range(i):  # only a higher-priority (lower-index) team-mate makes robot i yield
            reach = self.radii[i] + self.radii[j] + self.margin + YIELD_CLEARANCE
            if _blocks(positions[j], goals[j], positions[i], reach) or _blocks(
                positions[i], goals[i], positions[j], reach
            ):
                return "yield", _aside(positions[i], positions[j], goals[j], reach)
        inflate = self.radii[i] + self.margin + DETOUR_CLEARANCE
        waypoint = detour_waypoint(positions[i], goals[i], self.obstacles, inflate)
        return ("restart" if np.array_equal(waypoint, goals[i]) else "obstacle"), waypoint


def _aside(position: NDArray, other: NDArray, other_goal: NDArray, reach: float) -> NDArray[np.float64]:
    """A point ``reach`` from the straight path ``other`` -> ``other_goal``, on the side where
    ``position`` stands, level with ``position`` along that path."""
    line = other_goal - other
    length = float(np.hypot(*line))
    along = line / length if length > 1e-9 else np.array([1.0, 0.0])
    normal = np.array([-along[1], along[0]])
    offset = float(np.dot(position - other, normal))
    side = 1.0 if offset >= 0 else -1.0
    foot = other + float(np.dot(position - other, along)) * along
    return foot + side * reach * normal


def pursuit_rollout(
    poses: NDArray[np.float64], goals: NDArray[np.float64], horizon: int, scenario: Any
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Every robot turning toward its goal and driving, over ``horizon`` periods of the unicycle
    (explicit Euler, within ``scenario``'s speed limits): commands (T, N, 2) and poses (T, N, 3).
    The NMPCs' cold start after a stall."""
    pose = np.array(poses, dtype=np.float64).reshape(-1, 3)
    goals = np.asarray(goals, dtype=np.float64).reshape(-1, 2)
    dt = scenario.dt
    commands, states = [], []
    for _ in range(horizon):
        delta = goals - pose[:, :2]
        error = (np.arctan2(delta[:, 1], delta[:, 0]) - pose[:, 2] + np.pi) % (2 * np.pi) - np.pi
        omega = np.clip(2.0 * error, -scenario.omega_max, scenario.omega_max)
        v = (
            scenario.v_max
            * np.maximum(np.cos(error), 0.0)
            * np.minimum(1.0, np.hypot(delta[:, 0], delta[:, 1]))
        )
        pose[:, 2] += omega * dt
        pose[:, 0] += v * np.cos(pose[:, 2]) * dt
        pose[:, 1] += v * np.sin(pose[:, 2]) * dt
        commands.append(np.column_stack([v, omega]))
        states.append(pose.copy())
    return np.array(commands), np.array(states)
