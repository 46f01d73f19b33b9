"""Control-barrier-function (CBF) safety filter for unicycle teams, usable around any controller.

``SafetyFilter(inner, gamma=..., margin=...)`` is itself a controller: each period it asks the
inner controller for a joint command and replaces it by the nearest command (weighted least
squares on (v, omega)) that keeps every robot away from the obstacles, the other robots and the
workspace boundary. By name: ``controllers.make("safe:consensus-free")``; in the evaluator's
syntax inner options are given as usual and filter options with a ``safety_`` prefix,
``safe:nominal-nmpc:horizon=10,safety_gamma=1,safety_margin=0.1`` (see :func:`wrap`).

The barrier functions
---------------------
Each robot i is represented by its look-ahead point ``p_i = (x + l cos theta, y + l sin theta)``,
whose velocity ``dp_i/dt = v e(theta) + l omega e_perp(theta)`` is affine in (v, omega) (and
invertible for l > 0, so both inputs steer it). A disc of radius ``r_i + l`` around p_i covers the
robot, so the barriers are, per robot i:

* obstacle k (centre c_k, radius R_k): ``h = |p_i - c_k| - (R_k + r_i + l + margin)``;
* robot j: ``h = |p_i - p_j| - (r_i + r_j + 2 l + margin)``;
* workspace wall, e.g. the left one: ``h = x(p_i) - (x_min + l + margin)``, which keeps the
  robot's centre inside the box as the env requires (its body may overhang, as in the env).

The filter keeps ``dh/dt >= -gamma h`` for each of them (gamma: the class-K gain). Robot pairs are
split decentrally: each robot of a pair takes half, ``n_ij . dp_i/dt >= -gamma h_ij / 2``, which
adds up to the pair's condition. We chose the split over one joint QP for the team because (1)
each robot's problem then has two variables and is solved exactly in closed form
(:mod:`controllers.solvers.two_variable_qp`, compiled), in microseconds per robot (a joint QP
through CasADi's ``conic`` costs ~0.3 ms per call even for 2 variables and 1.3-6 ms for 32
variables with daqp / qpOASES); (2) each robot's problem stays feasible on its own (see below),
so one robot in trouble does not make the whole team's problem infeasible; (3) it is what robots
running the filter on board, knowing only positions, could do. Its price is conservatism: a robot
never yields more than half a pair's barrier, even when its partner could not yield at all.

From continuous to sampled time (why the guarantee is exact for the nominal robots)
------------------------------------------------------------------------------------
The command is held for a period ``dt``. Every barrier is convex in the look-ahead points (a norm
minus a constant, or affine), so ``h(t + dt) >= h(t) + n . delta_p`` with n its gradient at t.
Holding (v, omega), ``f(t) = n . dp/dt`` drifts from its initial value as the heading turns:
``|f'| <= |omega| (|v| k_s + l |omega| k_c)`` with ``k_s = min(1, |n . e_perp| + omega_max dt)``,
``k_c = min(1, |n . e| + omega_max dt)``, so ``n . delta_p >= dt f(0) - dt^2/2 sup |f'|``. With
``|v||omega| <= lam omega_max |v| + (1 - lam) v_max |omega|`` (true for every lam in [0, 1]; lam is
taken from the inner command, for which it is tightest) and ``omega^2 <= omega_max |omega|``,
each barrier becomes four linear rows (one per sign of v and of omega) of::

    n . dp/dt - c_v |v| - c_omega |omega| >= -gamma h,
    c_v = dt/2 k_s lam omega_max,   c_omega = dt/2 (k_s (1 - lam) v_max + l omega_max k_c),

which gives ``h(t + dt) >= (1 - gamma dt) h(t)``: with ``0 < gamma dt <= 1`` the safe set
``h >= 0`` is invariant for the nominal (slip-free) kinematics, not only in the limit dt -> 0.
The command (0, 0) satisfies every row whenever every h >= 0, so each robot's QP is feasible
until a barrier is already negative.

Only barriers that can bind are built: the rows can be violated inside the command box only if
``gamma h < (|a_v| + c_v) v_max + (|a_omega| + c_omega) omega_max`` (``dh/dt = a_v v + a_omega omega``;
the "sensing radius": with the defaults at most 0.34 m of clearance to obstacles and walls and
0.69 m between robots), so each QP grows with the number of nearby objects only; the distance
check itself visits every obstacle and pair, a few floating-point operations each.

Deadlocks
---------
A filter only removes the unsafe part of a command; it does not plan. A controller that drives
straight at an obstacle (``consensus-free``) is stopped in front of it, and one that plans with
smaller clearances than the filter keeps (the NMPCs' 0.015 m against the filter's
``l + margin``) can push two robots into a corner of the safe set where the only safe motion is
backwards, which the QP, staying near the command, does not choose. For a controller that takes
margins, widening them to the filter's (``nominal-nmpc:obstacle_offset=0.08,robot_offset=0.13``) is
the better cure (``bench/safety_filter.py``); the filter is for controllers that cannot.
``omega_weight`` is small by default so that the filter steers away from a barrier rather than
brakes in front of it.

Slip and infeasibility
----------------------
The filter sees the nominal kinematics only (the scenario carries no slip), so under slip it is a
filter, not a guarantee: ``margin`` [m] is extra clearance for the unmodelled drift; since slip
scales with the commanded speed, which the filter lowers near obstacles, a few centimetres go a
long way. When slip has already pushed a robot inside a barrier (h < 0) its rows ask for a
positive rate of recovery, which may be out of reach within the limits. Then the fallback is the
least-violating command: the recovery rates asked by the violated rows are scaled by the largest
factor s in [0, 1] that is feasible (bisection; s = 0, which (0, 0) satisfies, means no violated
barrier may shrink), and the QP is solved at that s. Such periods are counted
(``SafetyStats.infeasible``).
"""

from __future__ import annotations

import difflib
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar

import numpy as np
from numba import njit
from numpy.typing import NDArray

from controllers.base import BaseController, Controller, ControllerStats
from controllers.solvers.two_variable_qp import qp2_kernel
from koopman_envs.params import PARAMS
from koopman_envs.scenario import Scenario

__all__ = [
    "FILTER_OPTION_PREFIX",
    "BarrierFilter",
    "FilterStep",
    "SafetyFilter",
    "SafetyOptions",
    "SafetyStats",
    "wrap",
]

#: in ``safe:<name>`` configurations, options with this prefix go to the filter, the others to ``<name>``
FILTER_OPTION_PREFIX = "safety_"

#: a robot's command counts as changed by the filter beyond this difference [m/s or rad/s]
_CHANGED = 1e-6
#: bisection steps of the least-violating fallback (resolution 2^-12 of the asked recovery rate)
_BISECTION_STEPS = 12


@dataclass(frozen=True)
class SafetyOptions:
    """Options of the CBF safety filter (all ours; ranges checked on construction).

    The defaults keep the narrowest passage of the paper maps open (0.56 m between two obstacles
    of Map 1 and Map 3; a robot needs ``2 (r + lookahead + margin)`` = 0.54 m), so that the
    filter does not close a way the inner controller may take.

    Attributes
    ----------
    gamma : float
        Class-K gain [1/s], ``0 < gamma <= 1 / dt`` (10 for the paper's dt): each barrier may
        shrink by at most the fraction ``gamma dt`` per period. Small: brake early and gently;
        large: late and hard.
    margin : float
        Extra clearance [m] beyond the robot and obstacle radii (and between robots), in
        ``[0, 1]``: room for the slip the filter does not model.
    lookahead : float
        Distance of the controlled point ahead of the axle [m], in ``(0, 0.5]``. Larger lets a
        turn move the point more (more steering authority) but inflates every radius by as much.
    omega_weight : float
        Weight of a change of omega relative to a change of v in the cost [m^2/rad^2], in
        ``(0, 100]``: small prefers turning away, large prefers braking.
    """

    gamma: float = 2.0
    margin: float = 0.02
    lookahead: float = 0.05
    omega_weight: float = 0.01

    #: allowed range per option: (low, high, low included, description)
    RANGES: ClassVar[dict[str, tuple[float, float, bool, str]]] = {
        "gamma": (0.0, 1.0 / PARAMS.dt, False, f"(0, {1.0 / PARAMS.dt:g}] 1/s (gamma * dt <= 1)"),
        "margin": (0.0, 1.0, True, "[0, 1] m"),
        "lookahead": (0.0, 0.5, False, "(0, 0.5] m"),
        "omega_weight": (0.0, 100.0, False, "(0, 100] m^2/rad^2"),
    }

    def __post_init__(self) -> None:
        for name in self.RANGES:
            self.check(name, getattr(self, name))

    @classmethod
    def check(cls, name: str, value: Any, prefix: str = "") -> None:
        """Raise ``ValueError`` naming option ``prefix + name``, its value and its allowed range."""
        low, high, closed, text = cls.RANGES[name]
        number = not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
        if not number or value > high or value < low or (value == low and not closed):
            raise ValueError(
                f"safety filter option {prefix}{name}={value!r} is out of range; allowed: {text}"
            )

    @classmethod
    def from_options(cls, prefix: str = "", **options: Any) -> SafetyOptions:
        """Build from keyword options; errors name the option as given (with ``prefix``), its value
        and what is allowed."""
        allowed = [f.name for f in fields(cls)]
        for key, value in options.items():
            if key not in allowed:
                close = difflib.get_close_matches(key, allowed, n=1)
                hint = f" (did you mean {prefix + close[0]!r}?)" if close else ""
                raise ValueError(
                    f"unknown safety filter option {prefix + key!r}{hint}; "
                    f"allowed: {[prefix + a for a in allowed]}"
                )
            cls.check(key, value, prefix)
        return cls(**options)


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
    A, b, row, h, nx, ny, share, hx, hy, lookahead, gamma, v_max, omega_max, dt, lam
):  # pragma: no cover
    """Append the four rows of one barrier (unit gradient n, value h) of a robot with heading
    (hx, hy) when some command within the limits could violate them; return the new row count."""
    a_v = nx * hx + ny * hy  # n . e
    cross = -nx * hy + ny * hx  # n . e_perp
    a_w = lookahead * cross
    # bound on the drift of n . dp/dt over a held period (module docstring), per |v| and per |omega|
    k_s = min(1.0, abs(cross) + omega_max * dt)
    k_c = min(1.0, abs(a_v) + omega_max * dt)
    c_v = 0.5 * dt * k_s * lam * omega_max
    c_w = 0.5 * dt * (k_s * (1.0 - lam) * v_max + lookahead * omega_max * k_c)
    rhs = -gamma * share * h
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
    """Filter every robot's command (see the module docstring); returns (barrier minimum, barriers built)."""
    n, n_obs = poses.shape[0], centres.shape[0]
    px, py = np.empty(n), np.empty(n)
    for i in range(n):
        px[i] = poses[i, 0] + lookahead * math.cos(poses[i, 2])
        py[i] = poses[i, 1] + lookahead * math.sin(poses[i, 2])
    size = 4 * (n_obs + n - 1 + 4) + 4
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

    def filter(self, poses: NDArray, command: NDArray) -> FilterStep:
        """The safe command nearest to ``command``.

        Parameters
        ----------
        poses : ndarray, shape (N, 3)
            Current poses: x [m], y [m], theta [rad] per robot.
        command : ndarray, shape (N, 2) or (2N,)
            The inner controller's (v, omega) per robot; clipped to the limits first, non-finite
            entries replaced by 0 (a stop).

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
        h_min, built = _filter_team(
            poses,
            wanted,
            self._centres,
            self._obstacle_reach,
            self._robot_reach,
            self._walls,
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


@dataclass
class SafetyStats(ControllerStats):
    """Statistics of a filtered controller: the inner controller's, plus the filter's.

    ``solve_times`` is the wall time of each whole decision (inner controller plus filter), so the
    evaluator's solve-time columns rank the filtered controller as it runs; ``iterations``,
    ``failures`` and ``statuses`` are the inner controller's.

    Attributes
    ----------
    filter_times : list of float
        Wall time of the filter alone per decision [s].
    changed : int
        Decisions where the filter changed at least one robot's command.
    changed_robots : int
        Robot-decisions changed (at most N per decision).
    infeasible : int
        Decisions where at least one robot's QP was infeasible (least-violating fallback used).
    barrier_min : float
        Smallest barrier value seen in the episode [m] (negative: a robot was inside a margin).
    inner : ControllerStats or None
        The inner controller's own statistics (its solve times exclude the filter).
    """

    filter_times: list[float] = field(default_factory=list)
    changed: int = 0
    changed_robots: int = 0
    infeasible: int = 0
    barrier_min: float = float("inf")
    inner: ControllerStats | None = None

    def summary(self) -> dict[str, Any]:
        """The base summary plus ``filter_ms_median/p95/max``, ``filter_changed``,
        ``filter_changed_robots``, ``filter_infeasible``, ``filter_barrier_min`` and
        ``inner_ms_median``."""
        times = np.asarray(self.filter_times)
        inner = self.inner.summary() if self.inner is not None else {}
        return {
            **super().summary(),
            "filter_ms_median": 1e3 * float(np.median(times)) if times.size else float("nan"),
            "filter_ms_p95": 1e3 * float(np.percentile(times, 95)) if times.size else float("nan"),
            "filter_ms_max": 1e3 * float(times.max()) if times.size else float("nan"),
            "filter_changed": self.changed,
            "filter_changed_robots": self.changed_robots,
            "filter_infeasible": self.infeasible,
            "filter_barrier_min": self.barrier_min,
            "inner_ms_median": inner.get("solve_ms_median", float("nan")),
            **({"solver": inner["solver"]} if "solver" in inner else {}),
        }


class SafetyFilter(BaseController):
    """Any controller behind a CBF safety filter (see the module docstring).

    Parameters
    ----------
    inner : Controller
        The controller whose commands are filtered (``.inner``). The evaluator calibrates it
        as it would alone (:func:`controllers.base.calibratable` looks down ``.inner``).
    **options
        Fields of :class:`SafetyOptions`: ``gamma``, ``margin``, ``lookahead``, ``omega_weight``.

    Raises
    ------
    ValueError
        An unknown option or a value out of its range (the message names both).
    TypeError
        ``inner`` has no ``act`` / ``reset``.

    Examples
    --------
    >>> ctrl = SafetyFilter(controllers.make("consensus-free"), gamma=2.0, margin=0.05)
    >>> ctrl = controllers.make("safe:consensus-free", safety_margin=0.1)   # the same by name
    """

    _stats: SafetyStats  # set in __init__, and by _reset over the plain one reset() starts with

    def __init__(self, inner: Controller, **options: Any) -> None:
        super().__init__()
        for method in ("reset", "act"):
            if not callable(getattr(inner, method, None)):
                raise TypeError(
                    f"SafetyFilter needs a controller with {method}(); got {type(inner).__name__}"
                )
        self.inner = inner
        self.options = SafetyOptions.from_options(**options)
        self.name = f"safe:{getattr(inner, 'name', type(inner).__name__)}"
        self._filter: BarrierFilter | None = None
        self._stats = SafetyStats()

    def _reset(self, scenario: Scenario, seed: int | None) -> None:
        self.inner.reset(scenario, seed=seed)
        self._filter = BarrierFilter(scenario, self.options)
        self._stats = SafetyStats()

    @property
    def sensing_radius(self) -> tuple[float, float]:
        """Clearances beyond which obstacles / walls and other robots cannot constrain a robot [m]
        (after ``reset``)."""
        if self._filter is None:
            raise RuntimeError(f"{self.name}: call reset(scenario) first")
        return self._filter.sensing_radius

    def _act(self, observation: NDArray, info: dict[str, Any]) -> NDArray[np.float64]:
        start = time.perf_counter()
        command = self.inner.act(observation, info)
        middle = time.perf_counter()
        assert self._filter is not None  # built by _reset, which act() requires
        step = self._filter.filter(np.asarray(info["poses"], dtype=np.float64), command)
        end = time.perf_counter()
        stats = self._stats
        stats.solve_times.append(end - start)
        stats.filter_times.append(end - middle)
        stats.changed += bool(step.changed.any())
        stats.changed_robots += int(step.changed.sum())
        stats.infeasible += bool(step.infeasible.any())
        stats.barrier_min = min(stats.barrier_min, step.barrier_min)
        return step.command.reshape(-1)

    def stats(self) -> SafetyStats:
        """This episode's statistics, with the inner controller's iterations, failures and statuses."""
        inner_stats = self.inner.stats()
        self._stats.inner = inner_stats
        self._stats.iterations = list(inner_stats.iterations)
        self._stats.failures = inner_stats.failures
        self._stats.statuses = inner_stats.statuses.copy()
        return self._stats


def wrap(inner_factory: Callable[..., Controller], **options: Any) -> SafetyFilter:
    """Registry wrapper of the ``safe:`` prefix: options named ``safety_<field>`` go to the filter
    (prefix removed), the others to ``inner_factory``.

    >>> wrap(factory("nominal-nmpc"), horizon=10, safety_gamma=1.0)   # = make("safe:nominal-nmpc", ...)
    """
    mine = {
        k[len(FILTER_OPTION_PREFIX) :]: v for k, v in options.items() if k.startswith(FILTER_OPTION_PREFIX)
    }
    theirs = {k: v for k, v in options.items() if not k.startswith(FILTER_OPTION_PREFIX)}
    SafetyOptions.from_options(FILTER_OPTION_PREFIX, **mine)  # errors name the prefixed option the user wrote
    return SafetyFilter(inner_factory(**theirs), **mine)
