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

__all__ = ["FILTER_GAINS", "BarrierFilter", "FilterStep"]

#: a robot's command counts as changed by the filter beyond this difference [m/s or rad/s]
_CHANGED = 1e-6
#: bisection steps of the least-violating fallback (resolution 2^-12 of the asked recovery rate)
_BISECTION_STEPS = 12

#: the filter's fixed terms, one record per filter (:attr:`BarrierFilter.gains`): numba reads a
#: record's fields by name and types a record argument about as fast as a plain array (a named
#: tuple it types field by field in Python, microseconds a call)
FILTER_GAINS = np.dtype(
    [
        ("lookahead", np.float64),  # the look-ahead point's distance ahead of the centre [m]
        ("gamma", np.float64),  # the barriers' recovery rate [1/s]
        ("v_max", np.float64),  # [m/s]
        ("omega_max", np.float64),  # [rad/s]
        ("dt", np.float64),  # the control period [s]
        ("omega_weight", np.float64),  # the QP's cost weight of a turn-rate change
        ("margin", np.float64),  # the extra clearance every barrier keeps [m]
        ("mover_radius", np.float64),  # a mover's radius in the scenario [m]
        # the limits x_min, x_max, y_min, y_max within which the look-ahead points stay [m]
        ("walls", np.float64, (4,)),
    ]
)


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
def _add_barrier(system, row, h, normal, share, heading, g, lam, approach=0.0):  # pragma: no cover
    """Append the four rows of one barrier (unit gradient ``normal`` (nx, ny), value h) of a robot
    with ``heading`` (hx, hy) to the rows ``system`` = (A, b) when some command within the limits
    could violate them; return the new row count. ``g``: the filter's gains (a record of
    :data:`FILTER_GAINS`).

    ``approach``: n . v of a moving obstacle (its velocity along the gradient, positive when it
    comes toward the robot): dh/dt = n . dp/dt - n . v, so the robot must recede that much more."""
    A, b = system
    (nx, ny), (hx, hy) = normal, heading
    lookahead, gamma, v_max, omega_max, dt = g.lookahead, g.gamma, g.v_max, g.omega_max, g.dt
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
    poses, wanted, obstacles, radius, widen, movers, mover_extra, gains, outputs
):  # pragma: no cover - compiled
    """Filter every robot's command (see the module docstring); returns (barrier minimum, barriers built).

    ``poses`` (N, 3) and ``wanted`` (N, 2): the team's poses and the commands asked for;
    ``obstacles`` (M, 3): the static obstacle set, x, y, radius [m] each (the scenario's);
    ``radius`` (N,): the robots' radii and ``widen`` (N,) their extra clearance this period [m];
    ``movers`` (C, 4): the movers' observed centres and the velocities their barriers assume
    (x, y, vx, vy), each mover ``mover_extra`` [m] larger than the scenario's; ``gains`` (1,) of
    :data:`FILTER_GAINS`. ``outputs`` is the tuple ``out``, ``infeasible``, ``relaxation``: the
    filtered commands (N, 2), and per robot whether its QP was infeasible and the fraction of
    the recovery rate granted.

    The distances the look-ahead points keep are summed here in the order the filter has
    always summed them (a term of zero leaves a sum as it is): from an obstacle ((r + r_i) + l)
    + margin + w_i, from robot j ((r_i + r_j) + 2 l) + margin + sqrt(w_i^2 + w_j^2), from a mover
    ((r_i + r_mover) + l) + margin + extra + w_i, and the walls moved in by max(w).
    """
    out, infeasible, relaxation = outputs
    g = gains[0]
    lookahead, v_max, omega_max = g.lookahead, g.v_max, g.omega_max
    omega_weight, margin, walls = g.omega_weight, g.margin, g.walls
    n, n_obs = poses.shape[0], obstacles.shape[0]
    wider = 0.0
    for i in range(n):
        wider = max(wider, widen[i])
    limits = (walls[0] + wider, walls[1] - wider, walls[2] + wider, walls[3] - wider)
    px, py = np.empty(n), np.empty(n)
    for i in range(n):
        px[i] = poses[i, 0] + lookahead * math.cos(poses[i, 2])
        py[i] = poses[i, 1] + lookahead * math.sin(poses[i, 2])
    size = 4 * (n_obs + n - 1 + movers.shape[0] + 4) + 4
    A, b, relaxed = np.empty((size, 2)), np.empty(size), np.empty(size)
    system = (A, b)  # the rows _add_barrier appends to
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
                dx, dy, share = px[i] - obstacles[k, 0], py[i] - obstacles[k, 1], 1.0
                reach = obstacles[k, 2] + radius[i] + lookahead + margin + widen[i]
            else:
                j = k - n_obs
                dx, dy, share = px[i] - px[j], py[i] - py[j], 0.5  # half of the pair's
                reach = radius[i] + radius[j] + 2.0 * lookahead + margin
                reach += math.sqrt(widen[i] * widen[i] + widen[j] * widen[j])
            dist = math.hypot(dx, dy)
            h = dist - reach
            h_min = min(h_min, h)
            if dist > 1e-12:
                nx, ny = dx / dist, dy / dist
            else:  # coincident points (deep in collision) have no direction: push straight back
                nx, ny = -hx, -hy
            row = _add_barrier(system, row, h, (nx, ny), share, (hx, hy), g, lam)
        for m in range(movers.shape[0]):  # moving discs: their velocity along the gradient
            dx, dy = px[i] - movers[m, 0], py[i] - movers[m, 1]
            dist = math.hypot(dx, dy)
            h = dist - (radius[i] + g.mover_radius + lookahead + margin + mover_extra + widen[i])
            h_min = min(h_min, h)
            if dist > 1e-12:
                nx, ny = dx / dist, dy / dist
            else:
                nx, ny = -hx, -hy
            approach = nx * movers[m, 2] + ny * movers[m, 3]
            row = _add_barrier(system, row, h, (nx, ny), 1.0, (hx, hy), g, lam, approach)
        for w in range(4):  # left, right, bottom, top
            h = (px[i] - limits[0], limits[1] - px[i], py[i] - limits[2], limits[3] - py[i])[w]
            nx, ny = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))[w]
            h_min = min(h_min, h)
            row = _add_barrier(system, row, h, (nx, ny), 1.0, (hx, hy), g, lam)
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
        #: the static obstacle set (M, 3): x, y, radius [m] each
        self.obstacles = np.ascontiguousarray(np.asarray(scenario.obstacles, dtype=np.float64).reshape(-1, 3))
        self._radius = np.ascontiguousarray(radius)
        x0, x1, y0, y1 = scenario.workspace
        walls = np.array([x0, x1, y0, y1], dtype=np.float64) + np.array([1, -1, 1, -1]) * (l + margin)
        self.v_max, self.omega_max = float(scenario.v_max), float(scenario.omega_max)
        self.dt = float(scenario.dt)
        self._limits = np.array([self.v_max, self.omega_max])
        self._no_movers, self._no_widening = np.zeros((0, 4)), np.zeros(self.n)
        #: the fixed terms, one record of :data:`FILTER_GAINS`
        self.gains = np.array(
            [
                (
                    l,
                    options.gamma,
                    self.v_max,
                    self.omega_max,
                    self.dt,
                    options.omega_weight,
                    margin,
                    scenario.mover_radius,
                    walls,
                )
            ],
            dtype=FILTER_GAINS,
        )
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
        if movers is None:
            movers = self._no_movers
        else:  # a copy whose velocities are the ones the barriers assume: times the option's weight
            movers = np.array(movers, dtype=np.float64).reshape(-1, 4)
            movers[:, 2:] *= opt.mover_velocity
        # a mover perceived larger than a person: every mover barrier keeps the largest's distance
        extra = 0.0
        if mover_radius is not None and mover_radius > self.scenario.mover_radius:
            extra = mover_radius - self.scenario.mover_radius
        w = self._no_widening if widen is None else np.ascontiguousarray(widen, dtype=np.float64).reshape(n)
        h_min, built = _filter_team(
            poses,
            wanted,
            self.obstacles,
            self._radius,
            w,
            movers,
            extra,
            self.gains,
            (out, infeasible, relaxation),
        )
        return FilterStep(
            command=out,
            changed=np.abs(out - wanted).max(axis=1) > _CHANGED,
            infeasible=infeasible,
            relaxation=relaxation,
            barrier_min=float(h_min),
            constraints=int(built),
        )
