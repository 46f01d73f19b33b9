"""The per-episode metrics: :class:`EpisodeResult` (what one episode did) and
:class:`EpisodeRecorder`, the one place they are computed, fed one step at a time by
:func:`koopman_envs.episodes.single.run_episode` and by any runner that steps episodes another way
(:mod:`koopman_envs.episodes.batch`). Its readers of records (:func:`path_ratio`,
:func:`smallest_clearance`) take a result's fields or a record's lists alike, so that a report
computes a metric the way the episode did.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from koopman_envs.params import PATH_RATIO_MIN_DISTANCE, STRICT_CLEARANCE_MARGIN
from koopman_envs.sim.collision import CollisionKind
from koopman_envs.sim.nearest import obstacle_clearances, smallest_clearances

__all__ = ["EpisodeRecorder", "EpisodeResult", "path_ratio", "smallest_clearance"]


@dataclass
class EpisodeResult:
    """What one episode did (metres, seconds; arrays per robot).

    Attributes
    ----------
    success : bool
        Every robot settled within tolerance without collision.
    collision : str or None
        Kind of the collision that ended the episode.
    collision_at_fault : bool
        The episode ended on a collision that was a robot's fault (``info["robots_at_fault"]``
        of its last step: an obstacle, a team-mate, the workspace's edge, or a mover the robot
        ran into; the rule: :class:`~koopman_envs.sim.collision.CollisionFault`). False
        without a collision, and for one where movers ran into robots that were stopped or
        moving away.
    success_excusing_unavoidable : bool
        Success, or an episode ended by a collision that was no robot's fault with every robot
        within ``goal_tolerance`` of its target at that period. A collision of any fault ends
        the episode (the env's rule), so a team hit on its way can never be shown to have
        arrived: only one hit after it had arrived is excused.
    truncated : bool
        Ended by the time limit.
    steps : int
        Control periods taken.
    total_reward : float
        Sum of the env's rewards.
    time_to_goal : float or None
        Start of the final settled stretch [s] (the team's last entry into tolerance, not its
        first visit), for successful episodes; None for the others (a team that did not arrive
        has no arrival time, and a stand-in such as the time limit would mix the outcome into the
        metric: the reports compare times on the episodes both controllers won).
    final_poses, targets : ndarray, shape (N, 3)
    final_distance, path_length, control_effort : ndarray, shape (N,)
        Distance to target at the end [m]; distance driven [m]; sum of v^2 + omega^2 over the
        saturated commands times dt.
    formation_rms : float or None
        RMS follower formation error over the episode [m] (formation task).
    straight_distance : ndarray, shape (N,)
        Distance from each robot's start to its target [m]: ``path_length / straight_distance``
        is the path-length ratio robotics papers report.
    min_clearance : dict of str to float or None
        Smallest surface clearance over the episode [m] (negative: overlapping) of any robot to
        ``"obstacle"``, ``"robot"`` (a team-mate) and ``"mover"``; None where there is none (a
        single robot, a map without obstacles, no movers). Measured on the true poses at every
        period, the start included.
    decisions : int
        Times the controller decided (every period, except under a :class:`ComputeCharge`,
        where a slow controller decides once per the periods it takes).
    deadline_misses : int
        Decisions that took longer than the control period (compute-aware episodes; else 0).
    late_periods : float
        Mean periods between a decision's measurement and its command acting (0 without a
        compute charge).
    accel_rms, angular_accel_rms : ndarray, shape (N,)
        Smoothness: root mean square of the change of the saturated command per period, divided
        by the period: linear [m/s^2] and angular [rad/s^2] (0 for a constant command; the first
        command is measured against standing still).
    jerk_rms : ndarray, shape (N,), or None
        Root mean square of the second difference of the saturated linear speed command over the
        episode's periods, divided by the period squared [m/s^3]: ``(v[t] - 2 v[t-1] + v[t-2]) /
        dt**2`` for t = 2 .. T - 1 (0 at a constant speed or a constant acceleration). The
        commanded speed, not the realised one: it is what the controller decides, exact to the
        bit, where a speed differenced out of the poses carries the slip and the integration.
        Only differences within the episode count (the start from standing still is the first
        command's, measured by ``accel_rms``). None for an episode of fewer than 3 periods.
    near_obstacle_share : ndarray, shape (N,)
        Share of the episode's periods at whose end the robot's surface clearance to an obstacle
        was at most ``params.STRICT_CLEARANCE_MARGIN`` (5 cm; a contact counts): 0 for a robot
        that never came that close (and on a map without obstacles).
    trajectory : ndarray, shape (T + 1, N, 3)
        Poses from the start.
    mover_trajectory : ndarray, shape (T + 1, C, 2), or None
        The movers' true positions from the start (None without movers).
    obstacles : ndarray, shape (M, 3), or None
        The episode's obstacles (x, y, r; its map's, random layouts included).
    frames : list of ndarray
        ``rgb_array`` frames when ``render=True``.
    """

    success: bool
    collision: str | None
    collision_at_fault: bool
    success_excusing_unavoidable: bool
    truncated: bool
    steps: int
    total_reward: float
    time_to_goal: float | None
    final_poses: NDArray[np.float64]
    targets: NDArray[np.float64]
    final_distance: NDArray[np.float64]
    path_length: NDArray[np.float64]
    control_effort: NDArray[np.float64]
    formation_rms: float | None
    straight_distance: NDArray[np.float64]
    min_clearance: dict[str, float | None]
    accel_rms: NDArray[np.float64]
    angular_accel_rms: NDArray[np.float64]
    jerk_rms: NDArray[np.float64] | None
    near_obstacle_share: NDArray[np.float64]
    trajectory: NDArray[np.float64]
    decisions: int = 0
    deadline_misses: int = 0
    late_periods: float = 0.0
    mover_trajectory: NDArray[np.float64] | None = None
    obstacles: NDArray[np.float64] | None = None
    frames: list[NDArray[np.uint8]] = field(default_factory=list)

    @property
    def outcome(self) -> str:
        """``"success"``, the collision kind, or ``"time limit"``."""
        return "success" if self.success else (self.collision or "time limit")

    @property
    def clearance_min_m(self) -> float | None:
        """The smallest clearance over the episode [m] of any robot to anything it must not
        touch: :func:`smallest_clearance` of :attr:`min_clearance`."""
        return smallest_clearance(self.min_clearance)

    @property
    def strict_success(self) -> bool:
        """A success that kept more than ``params.STRICT_CLEARANCE_MARGIN`` (5 cm) from every
        obstacle, team-mate and mover all episode (a success with nothing to keep clear of is
        strict)."""
        low = self.clearance_min_m
        return self.success and (low is None or low > STRICT_CLEARANCE_MARGIN)

    @property
    def path_ratio(self) -> float | None:
        """The team's path-length ratio: :func:`path_ratio` of the robots' paths and straight-line
        distances."""
        return path_ratio(self.path_length, self.straight_distance)


def path_ratio(path_length: Any, straight_distance: Any) -> float | None:
    """The path-length ratio of a team: per robot, the distance it drove over the straight-line
    distance from its start to its target, then the mean over the robots (every robot weighs the
    same, in a formation as in target reaching: a formation robot's target is its slot at the
    goal).

    Parameters
    ----------
    path_length, straight_distance : array-like, shape (N,)
        Per robot [m] (an :class:`EpisodeResult`'s fields, or an episode record's lists).

    Returns
    -------
    float or None
        At least 1 for a robot that reached its target; robots that start within
        ``params.PATH_RATIO_MIN_DISTANCE`` (10 cm) of their target are left out (nothing to
        divide by); None when every robot is, or when a record lacks the fields.
    """
    if path_length is None or straight_distance is None:
        return None
    straight = np.asarray(straight_distance, dtype=np.float64)
    moved = straight > PATH_RATIO_MIN_DISTANCE
    if not moved.any():
        return None
    return float(np.mean(np.asarray(path_length, dtype=np.float64)[moved] / straight[moved]))


def smallest_clearance(min_clearance: Mapping[str, float | None] | None) -> float | None:
    """The smallest of an episode's per-kind minimum clearances [m] (``min_clearance`` of an
    :class:`EpisodeResult` or an episode record: obstacle, team-mate, mover), None when it has
    none (a lone robot on an empty map without movers, or a record without the field)."""
    values = [value for value in (min_clearance or {}).values() if value is not None]
    return min(values) if values else None


class EpisodeRecorder:
    """The per-episode metrics of :class:`EpisodeResult`, fed one step at a time: the one place
    they are computed, by :func:`run_episode` and by any runner that steps episodes another way
    (a batch of them in a vector env: each environment's info row is a lone env's info).

    Parameters
    ----------
    scenario : Scenario
        The episode's scenario.
    info : dict
        The info of the episode's reset (true poses, and movers when there are any).
    """

    def __init__(self, scenario: Any, info: dict[str, Any]) -> None:
        self.scenario = scenario
        n = scenario.n_robots
        self._low = np.array([-scenario.v_max, -scenario.omega_max])
        self._high = np.array([scenario.v_max, scenario.omega_max])
        self._poses = [np.array(info["poses"], dtype=np.float64)]
        self._clearance = _Clearance(scenario)
        self._clearance.observe(info)
        self._effort = np.zeros(n)
        self._previous = np.zeros((n, 2))
        self._rate_sq = np.zeros((n, 2))
        # the linear command two periods back, and the squared second differences of it
        self._earlier = np.zeros(n)
        self._jerk_sq = np.zeros(n)
        self._formation_sq: list[NDArray[np.float64]] = []
        # the movers' true positions (info["movers"]) at the start and after every period
        self._movers = [np.asarray(info["movers"])[:, :2].copy()] if "movers" in info else None
        self.steps, self.total_reward = 0, 0.0
        # first step of the current stretch with every robot within tolerance
        self._stretch_start: int | None = None

    def record(self, action: NDArray[np.float64], reward: float, info: dict[str, Any]) -> None:
        """One period: the command the robots were given (N, 2), the env's reward and the info
        after the step."""
        scenario = self.scenario
        self.steps += 1
        self.total_reward += reward
        within = _record_commands(
            np.asarray(action, dtype=np.float64),
            self._low,
            self._high,
            float(scenario.dt),
            (self._effort, self._rate_sq, self._jerk_sq),
            (self._previous, self._earlier),
            np.asarray(info["distances"], dtype=np.float64),
            float(scenario.goal_tolerance),
            self.steps,
        )
        self._poses.append(np.array(info["poses"], dtype=np.float64))
        self._clearance.observe(info, period_end=True)
        if self._movers is not None:
            self._movers.append(np.asarray(info["movers"])[:, :2].copy())
        if "formation_error" in info:
            self._formation_sq.append(np.asarray(info["formation_error"])[1:] ** 2)
        if within:
            self._stretch_start = self.steps if self._stretch_start is None else self._stretch_start
        else:
            self._stretch_start = None

    def result(self, info: dict[str, Any], truncated: bool) -> EpisodeResult:
        """The episode's result from the info of its last step; ``truncated``: ended by the
        time limit (and not terminated)."""
        scenario, steps = self.scenario, self.steps
        trajectory = np.asarray(self._poses)
        success = bool(info["is_success"])
        stretch = self._stretch_start
        # the fault of the last step's contacts, and whether the team had arrived (every robot
        # within tolerance at the last period: the stretch the recorder follows is open)
        collided = bool(info["collision"])
        at_fault = collided and int(info["robots_at_fault"]) > 0
        excused = collided and not at_fault and stretch is not None
        return EpisodeResult(
            success=success,
            collision=CollisionKind.describe(info["collision_code"]) if collided else None,
            collision_at_fault=at_fault,
            success_excusing_unavoidable=success or excused,
            truncated=truncated,
            steps=steps,
            total_reward=self.total_reward,
            time_to_goal=stretch * scenario.dt if success and stretch is not None else None,
            final_poses=np.array(info["poses"], dtype=np.float64),
            targets=np.array(info["targets"], dtype=np.float64),
            final_distance=np.array(info["distances"], dtype=np.float64),
            path_length=np.linalg.norm(np.diff(trajectory[:, :, :2], axis=0), axis=2).sum(axis=0),
            control_effort=self._effort,
            formation_rms=float(np.sqrt(np.mean(self._formation_sq))) if self._formation_sq else None,
            straight_distance=np.hypot(*(trajectory[0, :, :2] - np.asarray(info["targets"])[:, :2]).T),
            min_clearance=self._clearance.smallest(),
            accel_rms=np.sqrt(self._rate_sq[:, 0] / steps),
            angular_accel_rms=np.sqrt(self._rate_sq[:, 1] / steps),
            jerk_rms=np.sqrt(self._jerk_sq / (steps - 2)) if steps >= 3 else None,
            near_obstacle_share=self._clearance.near / steps,
            trajectory=trajectory,
            mover_trajectory=np.asarray(self._movers) if self._movers else None,
            obstacles=np.asarray(scenario.obstacles, dtype=np.float64).reshape(-1, 3).copy(),
        )


@numba.njit(cache=True, nogil=True)
def _record_commands(
    action: NDArray[np.float64],
    low: NDArray[np.float64],
    high: NDArray[np.float64],
    dt: float,
    sums: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]],
    memory: tuple[NDArray[np.float64], NDArray[np.float64]],
    distances: NDArray[np.float64],
    tolerance: float,
    step: int,
) -> bool:
    """One period of the recorder's command metrics, in place: the command saturated to
    [low, high] (NaN stays NaN, as ``np.clip``), its effort ``(v^2 + omega^2) dt`` added per robot,
    the squared rate of change added, the previous command replaced; returns whether every
    robot is within ``tolerance`` of its target. Each value is computed in the order of the numpy
    expressions it replaces (``(applied**2).sum(axis=1) * dt``, ``((applied - previous) / dt) ** 2``),
    so the metrics are the same to the bit; one call instead of six numpy ones per period.

    From the episode's third period on (``step`` counts from 1) the squared second difference of
    the linear command over ``dt**2`` is added to ``jerk_sq``; ``earlier`` holds the linear
    command two periods back. ``sums`` is the tuple ``effort`` (N,), ``rate_sq`` (N, 2),
    ``jerk_sq`` (N,) and ``memory`` the tuple ``previous`` (N, 2), ``earlier`` (N,)."""
    effort, rate_sq, jerk_sq = sums
    previous, earlier = memory
    for i in range(action.shape[0]):
        total = 0.0
        for j in range(2):
            a = action[i, j]
            if a < low[j]:
                a = low[j]
            elif a > high[j]:
                a = high[j]
            total += a * a
            d = (a - previous[i, j]) / dt
            rate_sq[i, j] += d * d
            if j == 0:
                if step >= 3:
                    jerk = (a - 2.0 * previous[i, 0] + earlier[i]) / (dt * dt)
                    jerk_sq[i] += jerk * jerk
                earlier[i] = previous[i, 0]
            previous[i, j] = a
        effort[i] += total * dt
    within = True
    for i in range(distances.shape[0]):
        if not distances[i] <= tolerance:
            within = False
    return within


class _Clearance:
    """The smallest surface clearance so far of any robot to obstacles, team-mates and movers."""

    def __init__(self, scenario: Any) -> None:
        self.radius = np.ascontiguousarray(scenario.robot_radius, dtype=np.float64)
        self.obstacles = np.ascontiguousarray(scenario.obstacles, dtype=np.float64).reshape(-1, 3)
        self.mover_radius = float(getattr(scenario, "mover_radius", 0.0))
        self.low = [np.inf, np.inf, np.inf]  # obstacle, robot, mover
        # per robot: periods that ended within the margin of an obstacle
        self.near = np.zeros(self.radius.shape[0])

    def observe(self, info: dict[str, Any], period_end: bool = False) -> None:
        """The poses (and movers) of ``info``; ``period_end``: at the end of a period (not the
        reset), counted in :attr:`near`."""
        xy = np.ascontiguousarray(np.asarray(info["poses"], dtype=np.float64)[:, :2])
        if period_end and self.obstacles.shape[0]:
            self.near += obstacle_clearances(xy, self.radius, self.obstacles) <= STRICT_CLEARANCE_MARGIN
        movers = np.ascontiguousarray(
            np.asarray(info.get("movers", _NO_MOVERS), dtype=np.float64).reshape(-1, 4)
        )
        now = smallest_clearances(xy, self.radius, self.obstacles, movers, self.mover_radius)
        self.low = [min(before, value) for before, value in zip(self.low, now, strict=True)]

    def smallest(self) -> dict[str, float | None]:
        """Per kind, the smallest clearance so far, None where there is nothing of the kind."""
        return {
            kind: float(value) if math.isfinite(value) else None
            for kind, value in zip(("obstacle", "robot", "mover"), self.low, strict=True)
        }


_NO_MOVERS = np.zeros((0, 4))
