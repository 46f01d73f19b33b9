"""The barriers of the safety filter and the filter itself: one exact two-variable QP per robot,
compiled (the maths: :mod:`controllers.safety`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from controllers.safety.options import SafetyOptions
from controllers.solvers.two_variable_qp import qp2_kernel
from koopman_envs.scenario import Scenario

__all__ = ["BarrierFilter", "FilterStep"]

#: a robot's command counts as changed by the filter beyond this difference [m/s or rad/s]
_CHANGED = 1e-6
#: bisection steps of the least-violating fallback (resolution 2^-12 of the asked recovery rate)
_BISECTION_STEPS = 12


@dataclass
class FilterStep:
    """What the filter did in one period.

    Attributes
    ----------
    command : ndarray, shape (N, 2)
        Filtered (v, omega) per robot, within the limits.
    changed : ndarray of bool, shape (N,)
        Robots whose (clipped) command the filter changed.
    infeasible : ndarray of bool, shape (N,)
        Robots whose QP was infeasible (the least-violating fallback was used).
    relaxation : ndarray, shape (N,)
        Fraction of the asked recovery rate the fallback could grant (1 where feasible).
    barrier_min : float
        Smallest barrier value of the team before the step [m] (negative: inside a margin).
    constraints : int
        Barriers built (those that can bind), over the team.
    """

    command: NDArray[np.float64]
    changed: NDArray[np.bool_]
    infeasible: NDArray[np.bool_]
    relaxation: NDArray[np.float64]
    barrier_min: float
    constraints: int


@njit(cache=True)
def _add_barrier(
    A, b, row, h, nx, ny, share, hx, hy, lookahead, gamma, v_max, omega_max, dt, lam, approach=0.0
):  # pragma: no cover
    """Append the four rows of one barrier (unit gradient n, value h) of a robot with heading
    (hx, hy) when some command within the limits could violate them; return the new row count.

    ``approach``: n . v of a moving obstacle (its velocity along the gradient, positive when it
    comes toward the robot): dh/dt = n . dp/dt - n . v, so the robot must recede that much more."""
    a_v = nx * hx + ny * hy  # n . e
    cross = -nx * hy + ny * hx  # n . e_perp
    a_w = lookahead * cross
    # bound on the drift of n . dp/dt over a held period (module docstring), per |v| and per |omega|
    k_s = min(1.0, abs(cross) + omega_max * dt)
    k_c = min(1.0, abs(a_v) + omega_max * dt)
    c_v = 0.5 * dt * k_s * lam * omega_max
    c_w = 0.5 * dt * (k_s * (1.0 - lam) * v_max + lookahead * omega_max * k_c)
    rhs = -gamma * share * h + approach
    if -rhs >= (abs(a_v) + c_v) * v_max + (abs(a_w) + c_w) * omega_max:
        return row  # no command within the limits can violate it: leave it out (exact pruning)
    for s_v in (-1.0, 1.0):  # a_v v + a_w omega - c_v |v| - c_w |omega| >= rhs, one row per sign pair
        for s_w in (-1.0, 1.0):
            A[row, 0], A[row, 1], b[row] = a_v - s_v * c_v, a_w - s_w * c_w, rhs
            row += 1
    return row


@njit(cache=True)
def _filter_team(
    poses,
    wanted,
    centres,
    obstacle_reach,
    robot_reach,
    walls,
    mover_xy,
    mover_velocity,
    mover_reach,
    lookahead,
    gamma,
    v_max,
    omega_max,
    dt,
    omega_weight,
    out,
    infeasible,
    relaxation,
):  # pragma: no cover - compiled
    """Filter every robot's command (see the module docstring); returns (barrier minimum, barriers built).

    ``mover_xy`` and ``mover_velocity`` (C, 2): the movers' observed centres and the velocities
    their barriers assume; ``mover_reach`` (N,): the distance each robot's look-ahead point keeps."""
    n, n_obs = poses.shape[0], centres.shape[0]
    px, py = np.empty(n), np.empty(n)
    for i in range(n):
        px[i] = poses[i, 0] + lookahead * math.cos(poses[i, 2])
        py[i] = poses[i, 1] + lookahead * math.sin(poses[i, 2])
    size = 4 * (n_obs + n - 1 + mover_xy.shape[0] + 4) + 4
    A, b, relaxed = np.empty((size, 2)), np.empty(size), np.empty(size)
    h_min, built = math.inf, 0
    for i in range(n):
        hx, hy = math.cos(poses[i, 2]), math.sin(poses[i, 2])
        # split of |v||omega| <= lam omega_max |v| + (1 - lam) v_max |omega| (valid for any lam in
        # [0, 1]); taken from the inner command, for which it is tightest
        r_v, r_w = abs(wanted[i, 0]) / v_max, abs(wanted[i, 1]) / omega_max
        lam = r_w / (r_v + r_w) if r_v + r_w > 0.0 else 0.5
        row = 0
        for k in range(n_obs + n):
            if k == n_obs + i:
                continue  # not itself
            if k < n_obs:
                dx, dy, reach, share = px[i] - centres[k, 0], py[i] - centres[k, 1], obstacle_reach[i, k], 1.0
            else:
                j = k - n_obs
                dx, dy, reach, share = (
                    px[i] - px[j],
                    py[i] - py[j],
                    robot_reach[i, j],
                    0.5,
                )  # half of the pair's
            dist = math.hypot(dx, dy)
            h = dist - reach
            h_min = min(h_min, h)
            if dist > 1e-12:
                nx, ny = dx / dist, dy / dist
            else:  # coincident points (deep in collision) have no direction: push straight back
                nx, ny = -hx, -hy
            row = _add_barrier(
                A, b, row, h, nx, ny, share, hx, hy, lookahead, gamma, v_max, omega_max, dt, lam
            )
        for m in range(mover_xy.shape[0]):  # moving discs: their velocity along the gradient
            dx, dy = px[i] - mover_xy[m, 0], py[i] - mover_xy[m, 1]
            dist = math.hypot(dx, dy)
            h = dist - mover_reach[i]
            h_min = min(h_min, h)
            if dist > 1e-12:
                nx, ny = dx / dist, dy / dist
            else:
                nx, ny = -hx, -hy
            approach = nx * mover_velocity[m, 0] + ny * mover_velocity[m, 1]
            row = _add_barrier(
                A, b, row, h, nx, ny, 1.0, hx, hy, lookahead, gamma, v_max, omega_max, dt, lam, approach
            )
        for w in range(4):  # left, right, bottom, top
            h = (px[i] - walls[0], walls[1] - px[i], py[i] - walls[2], walls[3] - py[i])[w]
            nx, ny = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))[w]
            h_min = min(h_min, h)
            row = _add_barrier(A, b, row, h, nx, ny, 1.0, hx, hy, lookahead, gamma, v_max, omega_max, dt, lam)
        built += row // 4
        for sign in range(4):  # the command box
            A[row, 0], A[row, 1] = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))[sign]
            b[row] = -v_max if sign < 2 else -omega_max
            row += 1
        relaxation[i] = 1.0
        infeasible[i] = not qp2_kernel(wanted[i, 0], wanted[i, 1], 1.0, omega_weight, A, b, row, 1e-9, out[i])
        if infeasible[i]:
            # least-violating fallback: the largest fraction s of the asked recovery rates (rows
            # with b > 0) that is feasible; s = 0 admits the stop whenever the box does
            low, high = 0.0, 1.0
            for _ in range(_BISECTION_STEPS):
                mid = 0.5 * (low + high)
                for r in range(row):
                    relaxed[r] = mid * b[r] if b[r] > 0.0 else b[r]
                if qp2_kernel(wanted[i, 0], wanted[i, 1], 1.0, omega_weight, A, relaxed, row, 1e-9, out[i]):
                    low = mid
                else:
                    high = mid
            for r in range(row):
                relaxed[r] = low * b[r] if b[r] > 0.0 else b[r]
            if not qp2_kernel(wanted[i, 0], wanted[i, 1], 1.0, omega_weight, A, relaxed, row, 1e-9, out[i]):
                out[i, 0], out[i, 1] = (
                    0.0,
                    0.0,
                )  # unreachable in exact arithmetic; a stop, never the raw command
            relaxation[i] = low
    return h_min, built


class BarrierFilter:
    """The CBF quadratic programs of one scenario (see the module docstring for the maths).

    Parameters
    ----------
    scenario : Scenario
        Geometry (obstacles, radii, workspace), limits and dt of the episode.
    options : SafetyOptions
        Gain, margin, look-ahead distance and cost weight.

    Raises
    ------
    ValueError
        ``gamma * dt > 1`` for the scenario's dt.
    """

    def __init__(self, scenario: Scenario, options: SafetyOptions) -> None:
        if options.gamma * scenario.dt > 1.0 + 1e-12:
            raise ValueError(
                f"safety filter option gamma={options.gamma!r} is out of range for dt={scenario.dt}; "
                f"allowed: (0, {1.0 / scenario.dt:g}] 1/s"
            )
        self.scenario, self.options = scenario, options
        self.n = scenario.n_robots
        l, margin = options.lookahead, options.margin
        radius = np.asarray(scenario.robot_radius, dtype=np.float64)
        obstacles = np.asarray(scenario.obstacles, dtype=np.float64).reshape(-1, 3)
        self._centres = np.ascontiguousarray(obstacles[:, :2])
        # distances the look-ahead points must keep: obstacles (N, M), robots (N, N), walls (4,)
        self._obstacle_reach = np.ascontiguousarray(obstacles[None, :, 2] + radius[:, None] + l + margin)
        self._robot_reach = radius[:, None] + radius[None, :] + 2 * l + margin
        self._mover_reach = radius + scenario.mover_radius + l + margin
        x0, x1, y0, y1 = scenario.workspace
        self._walls = np.array([x0, x1, y0, y1], dtype=np.float64) + np.array([1, -1, 1, -1]) * (l + margin)
        self.v_max, self.omega_max = float(scenario.v_max), float(scenario.omega_max)
        self.dt = float(scenario.dt)
        self._limits = np.array([self.v_max, self.omega_max])
        # compile (or load the compiled kernel) here, not inside the first timed step
        self.filter(np.asarray(scenario.starts, dtype=np.float64), np.zeros((self.n, 2)))

    @property
    def sensing_radius(self) -> tuple[float, float]:
        """Clearance beyond which no obstacle or wall, and no other robot, can constrain a robot [m]."""
        l, dt = self.options.lookahead, self.dt
        # the largest |a_v| + c_v and |a_omega| + c_omega a row can have (see _add_barrier)
        speed = (
            self.v_max * (1 + dt * self.omega_max / 2)
            + (l + dt * (self.v_max + l * self.omega_max) / 2) * self.omega_max
        )
        reach = speed / self.options.gamma
        return reach, 2 * reach

    def filter(
        self,
        poses: NDArray,
        command: NDArray,
        movers: NDArray | None = None,
        widen: NDArray | None = None,
        mover_radius: float | None = None,
    ) -> FilterStep:
        """The safe command nearest to ``command``.

        Parameters
        ----------
        poses : ndarray, shape (N, 3)
            Current poses: x [m], y [m], theta [rad] per robot.
        command : ndarray, shape (N, 2) or (2N,)
            The inner controller's (v, omega) per robot; clipped to the limits first, non-finite
            entries replaced by 0 (a stop).
        movers : ndarray, shape (C, 4), optional
            Observed movers (x, y, vx, vy): each a moving barrier whose velocity counts with the
            weight ``mover_velocity`` (0: a disc standing where it is seen).
        widen : ndarray, shape (N,), optional
            Extra clearance per robot for this period [m] (the pose estimate's uncertainty,
            :func:`controllers.mpc.margins.chance_tightening`): toward obstacles, walls and movers
            by robot i's own, between robots i and j by sqrt(w_i^2 + w_j^2).
        mover_radius : float, optional
            The largest observed mover's radius [m] when it exceeds the scenario's (perceived
            movers, ``mover_radii``): every mover barrier keeps that distance.

        Returns
        -------
        FilterStep
        """
        n = self.n
        poses = np.ascontiguousarray(poses, dtype=np.float64).reshape(n, 3)
        wanted = np.asarray(command, dtype=np.float64).reshape(n, 2)
        wanted = np.clip(np.where(np.isfinite(wanted), wanted, 0.0), -self._limits, self._limits)
        out = np.empty((n, 2))
        infeasible = np.empty(n, dtype=np.bool_)
        relaxation = np.empty(n)
        opt = self.options
        movers = np.zeros((0, 4)) if movers is None else np.asarray(movers, dtype=np.float64).reshape(-1, 4)
        obstacle_reach, robot_reach, walls, mover_reach = (
            self._obstacle_reach,
            self._robot_reach,
            self._walls,
            self._mover_reach,
        )
        if mover_radius is not None and mover_radius > self.scenario.mover_radius:
            # perceived movers may be larger than a person: every mover barrier takes the largest
            mover_reach = np.ascontiguousarray(mover_reach + (mover_radius - self.scenario.mover_radius))
        if widen is not None:
            w = np.asarray(widen, dtype=np.float64).reshape(n)
            obstacle_reach = np.ascontiguousarray(obstacle_reach + w[:, None])
            robot_reach = np.ascontiguousarray(robot_reach + np.sqrt(w[:, None] ** 2 + w[None, :] ** 2))
            walls = walls + np.array([1, -1, 1, -1]) * float(w.max(initial=0.0))
            mover_reach = np.ascontiguousarray(mover_reach + w)
        h_min, built = _filter_team(
            poses,
            wanted,
            self._centres,
            obstacle_reach,
            robot_reach,
            walls,
            np.ascontiguousarray(movers[:, :2]),
            np.ascontiguousarray(opt.mover_velocity * movers[:, 2:4]),
            mover_reach,
            opt.lookahead,
            opt.gamma,
            self.v_max,
            self.omega_max,
            self.dt,
            opt.omega_weight,
            out,
            infeasible,
            relaxation,
        )
        return FilterStep(
            command=out,
            changed=np.abs(out - wanted).max(axis=1) > _CHANGED,
            infeasible=infeasible,
            relaxation=relaxation,
            barrier_min=float(h_min),
            constraints=int(built),
        )
