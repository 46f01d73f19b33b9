"""Nonlinear MPC of the robot team in CasADi (SPEC section 3), with a pluggable prediction model.

The problem is posed once per problem structure (team size, obstacle count, task, model) by
multiple shooting over the horizon and handed to ``nlpsol``; the measured state, the targets
and the obstacles are parameters, so a new episode or a new step only changes numbers. Every
step is warm-started from the previous solution shifted by one period. When the solver fails
(infeasible, iteration limit, NaN) the controller falls back to the rest of its last plan, then
to a safe stop, counts the failure, and the episode goes on.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, replace
from typing import Any, Protocol

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from controllers.base import BaseController
from controllers.rti import RealTimeIteration, bind_buffer, check_rti_options
from controllers.solver_cache import jit_options, nlpsol
from koopman_envs.checks import check_int
from koopman_envs.params import PARAMS
from koopman_envs.scenario import Scenario

__all__ = [
    "SOLVERS",
    "FATROP_OPTIONS",
    "IPOPT_OPTIONS",
    "NMPCConfig",
    "NMPCController",
    "PredictionModel",
    "ROBUST_UNCERTAINTY_MARGIN",
    "decode_state",
    "encode_state",
]

#: ``uncertainty_margin`` of the ``*-robust`` NMPC variants (ours): margins of 3 RMS one-step
#: residuals, i.e. a prediction error that large is three standard deviations out for Gaussian errors.
ROBUST_UNCERTAINTY_MARGIN = 3.0

#: IPOPT settings (ours): quiet, warm-startable, bounded effort per control period.
IPOPT_OPTIONS: dict[str, Any] = {
    "ipopt.print_level": 0,
    "ipopt.sb": "yes",
    "print_time": False,
    "ipopt.max_iter": 100,
    "ipopt.tol": 1e-6,
    "ipopt.acceptable_tol": 1e-4,
    "ipopt.acceptable_iter": 5,
    "ipopt.warm_start_init_point": "yes",
    "ipopt.warm_start_bound_push": 1e-6,
    "ipopt.warm_start_mult_bound_push": 1e-6,
    "ipopt.mu_init": 1e-3,
    "ipopt.linear_solver": "mumps",
}

#: fatrop settings (ours): the structure-exploiting interior-point solver shipped with CasADi.
#: ``bound_push`` 1e-6 (fatrop's default 1e-2) keeps the shifted warm start where it is, as
#: IPOPT's ``warm_start_bound_push`` does, and a small initial barrier (``mu_init`` 1e-5) suits
#: a start that is already near the optimum: on the Map 1 benchmark episode the median went from
#: 13 to 8 iterations with the same closed loop (and the same outcomes on Map 4 and Map 2, high
#: slip, 3 seeds each, Koopman-NMPC).
FATROP_OPTIONS: dict[str, Any] = {
    "print_time": False,
    "fatrop.print_level": 0,
    "fatrop.mu_init": 1e-5,
    "fatrop.bound_push": 1e-6,
    "fatrop.max_iter": 100,
}

#: environment variable that turns compiled ``nlpsol`` solvers on (``KOOPNAV_NMPC_JIT=1``)
JIT_ENV = "KOOPNAV_NMPC_JIT"

#: where an unused obstacle or neighbour slot waits [m]: far outside every workspace, so its
#: collision row never binds (and its squared distance stays well inside double precision)
PARKED = 1.0e3

DEFAULT_SOLVER_OPTIONS: dict[str, dict[str, Any]] = {"ipopt": IPOPT_OPTIONS, "fatrop": FATROP_OPTIONS}

#: NMPC solvers: the real-time iteration and the ``nlpsol`` plugins solved to convergence
SOLVERS = ("rti", "ipopt", "fatrop")

#: Options that tune a solver for a warm start near the optimum; a cold start (first step of an
#: episode, or after a failure, with zero multipliers) drops them and uses the solver's own
#: initialization. With them, IPOPT starts from multipliers pushed to 1e-6 and a barrier of 1e-3:
#: a badly centred point from which feasible problems ran into the 100-iteration limit
#: (Koopman-NMPC, Map 1, high slip, hard constraints) that the default start solves in ~45.
WARM_START_OPTIONS: dict[str, tuple[str, ...]] = {
    "ipopt": (
        "ipopt.warm_start_init_point",
        "ipopt.warm_start_bound_push",
        "ipopt.warm_start_mult_bound_push",
        "ipopt.mu_init",
    ),
    "fatrop": ("fatrop.mu_init", "fatrop.bound_push"),
}


class PredictionModel(Protocol):
    """What the NMPC needs of a model: team size, period, and a CasADi step function.

    ``coding`` names the per-robot NLP state: ``"pose"`` = (x, y, theta) or ``"cs"`` =
    (x, y, cos theta, sin theta); ``casadi_nlp_step()`` maps (state, u) to the next state in it.
    """

    # read-only members: a frozen dataclass (UnicycleModel) satisfies them, the NMPC only reads them
    @property
    def n_robots(self) -> int: ...

    @property
    def dt(self) -> float: ...

    @property
    def coding(self) -> str: ...

    def casadi_nlp_step(self) -> ca.Function: ...


def model_step(model: PredictionModel) -> tuple[ca.Function, NDArray[np.float64], Any]:
    """(step function (s, u, theta) -> s_next, theta's values, structure key) of a model.

    A model may offer its coefficients as NLP parameters (``casadi_nlp_step_parametric``,
    ``nlp_parameters``, ``nlp_structure``): the NMPC's problem then depends on its structure
    only, and models of the same structure share one built (and compiled) problem. Otherwise
    the coefficients are constants and the model itself is the key.
    """
    if (
        hasattr(model, "casadi_nlp_step_parametric")
        and hasattr(model, "nlp_parameters")
        and hasattr(model, "nlp_structure")
    ):
        return (
            model.casadi_nlp_step_parametric(),
            np.asarray(model.nlp_parameters(), dtype=float),
            model.nlp_structure(),
        )
    fixed = model.casadi_nlp_step()
    s = ca.SX.sym("s", fixed.size1_in(0))
    u = ca.SX.sym("u", fixed.size1_in(1))
    theta = ca.SX.sym("theta", 0)
    step = ca.Function("step", [s, u, theta], [fixed(s, u)], ["s", "u", "theta"], ["s_next"])
    # the model itself, not id(model): Python reuses the id of a collected object, and a new
    # model at an old address would silently inherit the old model's NLP
    return step, np.zeros(0), model


_CODING_SIZE = {"pose": 3, "cs": 4}


def encode_state(poses: NDArray, coding: str) -> NDArray[np.float64]:
    """Stacked NLP state of poses (N, 3) in a model's coding."""
    poses = np.asarray(poses, dtype=np.float64)
    if coding == "pose":
        return poses.reshape(-1)
    return np.column_stack([poses[:, :2], np.cos(poses[:, 2]), np.sin(poses[:, 2])]).reshape(-1)


def decode_state(states: NDArray, coding: str) -> NDArray[np.float64]:
    """Poses (..., N, 3) from NLP states (..., N * size) in a coding."""
    size = _CODING_SIZE[coding]
    s = np.asarray(states).reshape(states.shape[:-1] + (-1, size))
    if coding == "pose":
        return s.copy()
    return np.concatenate([s[..., :2], np.arctan2(s[..., 3], s[..., 2])[..., None]], axis=-1)


@dataclass(frozen=True)
class NMPCConfig:
    """NMPC options; the paper's values come from :mod:`koopman_envs.params`.

    Attributes
    ----------
    horizon : int
        Prediction horizon T in periods (paper: 20).
    q_leader, q_follower : tuple of float
        Stage weights on (x, y, cos theta, sin theta) errors. Target reaching uses
        ``q_leader`` for every robot (paper: diag(4, 4, 0.1, 0.1)); formation uses
        ``q_follower`` (paper: diag(1, 1, 0.1, 0.1)) for the followers.
    r_input : tuple of float
        Weights on (v, omega) (paper: diag(0.1, 0.1)).
    obstacle_offset : float
        Safety distance added to robot + obstacle radii [m] (paper: 0.015).
    robot_offset : float
        (ours) Safety distance added to the sum of two robots' radii [m]. The paper adds its
        0.015 m margin to obstacles only; the reason it gives (prediction error near a
        constraint) holds as much between robots, whose paths cross on Map 2.
    uncertainty_margin : float
        (ours) k >= 0: widen the margins to k times each robot's RMS one-step position residual
        of the controller's own prediction model, measured on its calibration data (see
        :meth:`NMPCController.calibrate`), never below ``obstacle_offset`` / ``robot_offset``
        (pairs: k (r_i + r_j)). 0 keeps the paper's margins; the ``*-robust`` variants use
        :data:`ROBUST_UNCERTAINTY_MARGIN`. The same option means the same thing for every NMPC.
    formation_bound : float
        ``|lb| = |ub|`` of the formation constraint, per period and axis [m] (ours: the paper gives
        no number; 0.03 m is half a period's travel at full speed, enough to skirt obstacles).
    soft_constraints : bool
        (ours) Give the collision constraints (obstacles, robots) and the formation constraints
        of each stage a slack s_t >= 0 each, with the exact penalty
        ``slack_penalty * (s_t + s_t^2)``. Whenever the hard
        problem is feasible its solution is unchanged; when model error or slip has already
        pushed a robot inside a safety margin, the problem stays solvable and the controller
        steers back out instead of failing. ``False`` gives the paper's hard constraints.
    slack_penalty : float
        Weight of the slack penalty.
    solver : str
        ``"rti"``: the real-time iteration (:mod:`controllers.rti`): one structured QP per
        control period from the previous plan shifted by one step (``rti_iterations`` QPs), no
        compiler. Or a CasADi ``nlpsol`` plugin solved to convergence at every period:
        ``"ipopt"`` (the paper's) or ``"fatrop"`` (the structure-exploiting interior-point
        solver shipped with CasADi: faster per step, but not the same closed loop:
        Koopman-NMPC deadlocks on Map 2 at nominal slip with fatrop in every trial and succeeds
        with IPOPT; see ``bench/nmpc_solve.py``). See :data:`SOLVERS`.
    solver_options : dict, optional
        Options passed to ``nlpsol`` for ``solver`` (default: :data:`IPOPT_OPTIONS` or
        :data:`FATROP_OPTIONS`). Unless they set ``ipopt.mu_strategy``, IPOPT updates its barrier
        the paper's way (``monotone``) for up to 3 robots and ``adaptive`` beyond, where the
        monotone update hits the iteration limit on most steps.
    fallback_solver : str or None
        ``nlpsol`` plugin tried on the same problem when ``solver`` fails (for ``"rti"``: a
        failed QP, or a plan whose largest slack exceeds ``slack_tolerance``), before the plan
        fallback (ignored when it equals ``solver``).
    qp_solver : str
        QP solver of the real-time iteration, one of :data:`controllers.rti.QP_SOLVERS`
        (``"hpipm"``: structure-exploiting interior point).
    rti_iterations : int
        QPs per control period of the real-time iteration (>= 1).
    hessian : str
        QP Hessian of the real-time iteration: ``"exact"`` (the Lagrangian's, made convex
        stage by stage) or ``"gauss-newton"`` (see :data:`controllers.rti.HESSIANS`).
    slack_tolerance : float
        Largest slack of a real-time-iteration plan accepted without the fallback solver
        (slacks are in the constraints' units: squared metres for collision rows).
    pair_slots : int
        (ours) 0 (default, the paper's problem): a collision row for every pair of robots at
        every stage. P >= 1: P pair slots instead, filled before every solve with the pairs that
        can meet within the horizon (centre distance below ``2 v_max T dt`` plus both radii and
        the pair's margin), nearest first; a pair keeps its slot while it stays within reach,
        and unused slots are parked far away (:data:`PARKED`). More pairs within reach than
        slots: the farthest go unconstrained for that step, counted as ``pairs_dropped``.
    obstacle_slots : int
        (ours) 0 (default): every robot has a row for every obstacle. K >= 1: each robot's K
        nearest obstacles (by surface clearance, refreshed before every solve); one built
        problem then serves maps with any number of obstacles.
    jit : bool or None
        Compile the NLP's functions to C (several times faster derivative evaluations). The
        compiled objects are cached on disk (:mod:`controllers.solver_cache`), so a problem
        structure is compiled once per machine, not per process; without a C compiler the solver
        runs uncompiled, with one warning. None (default): compiled only when the environment
        variable ``KOOPNAV_NMPC_JIT`` is ``1``: a compiler running beside the workers of an
        evaluation slowed every first run on a machine, and the real-time iteration never
        compiles. Only ``nlpsol`` solvers (``"ipopt"``, ``"fatrop"``) are compiled.
    """

    horizon: int = PARAMS.horizon
    q_leader: tuple[float, ...] = PARAMS.q_leader
    q_follower: tuple[float, ...] = PARAMS.q_follower
    r_input: tuple[float, ...] = PARAMS.r_input
    obstacle_offset: float = PARAMS.obstacle_offset
    robot_offset: float = PARAMS.obstacle_offset
    uncertainty_margin: float = 0.0
    formation_bound: float = 0.03
    soft_constraints: bool = True
    slack_penalty: float = 1e4
    solver: str = "ipopt"
    solver_options: dict[str, Any] | None = None
    fallback_solver: str | None = "ipopt"
    qp_solver: str = "hpipm"
    rti_iterations: int = 1
    hessian: str = "exact"
    slack_tolerance: float = 1e-2
    pair_slots: int = 0
    obstacle_slots: int = 0
    jit: bool | None = None

    @property
    def compiled(self) -> bool:
        """Whether the ``nlpsol`` solvers are compiled: ``jit``, or when None, if ``$KOOPNAV_NMPC_JIT`` is 1."""
        if self.jit is not None:
            return bool(self.jit)
        return os.environ.get(JIT_ENV, "0").strip().lower() in ("1", "true", "yes", "on")

    def options_for(self, solver: str) -> dict[str, Any]:
        """nlpsol options of ``solver``: ``solver_options`` for the main solver, else defaults."""
        if solver == self.solver and self.solver_options is not None:
            options = dict(self.solver_options)
        else:
            options = dict(DEFAULT_SOLVER_OPTIONS.get(solver, {}))
        if self.compiled and solver == self.solver:
            # compiled once per machine (controllers.solver_cache); {} without a C compiler. The
            # fallback solver runs rarely: compiling it (minutes for a large NLP) would stall the
            # first episode that needs it
            for key, value in jit_options(background=True).items():
                options.setdefault(key, value)
        return options

    def with_options(self, **changes: Any) -> NMPCConfig:
        """A copy with some fields changed; unknown names raise ``TypeError``."""
        return replace(self, **changes)


class _Problem:
    """One built NLP: the solver and the index maps of its decision vector.

    Variables are ordered stage by stage, ``[x_0, u_0, s_0, x_1, u_1, s_1, ..., x_T]`` (s: the
    slacks), and constraints likewise (stage k: dynamics gap x_k+1 - f(x_k, u_k), then the path
    constraints of stage k; x_0 = measured state at stage 0). That is the layout the structure
    detection of the fatrop solver needs, and IPOPT solves it the same way.

    ``terminal_slack=True`` (the real-time iteration's problem) writes the terminal state's
    collision rows on the last stage, on ``f(x_T-1, u_T-1)``, with a third slack per stage that
    only the last stage may use: the structured QP solvers take no variables at the terminal
    stage, and every row of the QP then has a slack. The NLP is the same problem (its optimum is
    unchanged whenever the hard one is feasible), written differently; IPOPT's closed loop on it
    is not bit-identical to the paper formulation's (see docs/results.md).
    """

    def __init__(
        self,
        model: PredictionModel,
        scenario: Scenario,
        config: NMPCConfig,
        step: tuple[ca.Function, NDArray, Any] | None = None,
        *,
        terminal_slack: bool = False,
        neighbour_slots: int = 0,
    ) -> None:
        n, m_obs, horizon = scenario.n_robots, scenario.obstacles.shape[0], config.horizon
        n_slots = neighbour_slots
        n_pair_slots, n_obstacle_slots = config.pair_slots, config.obstacle_slots
        coding = model.coding
        if coding not in _CODING_SIZE:
            raise ValueError(f"model coding={coding!r} is not one of {sorted(_CODING_SIZE)}")
        size = _CODING_SIZE[coding]
        nx, nu = size * n, 2 * n
        soft = config.soft_constraints
        # slacks per stage: collision rows, formation rows and (terminal_slack) the terminal
        # state's collision rows, which only the last stage uses
        ns = (3 if terminal_slack else 2) if soft else 0
        step_function, theta_values, _ = model_step(model) if step is None else step
        theta = ca.SX.sym("model", theta_values.size)

        def f(x, u):
            return step_function(x, u, theta)

        x_meas = ca.SX.sym("x_meas", nx)
        goal_xy = ca.SX.sym("goal_xy", 2 * n)
        goal_cs = ca.SX.sym("goal_cs", 2 * n)
        # every obstacle (x, y, r), or with obstacle slots K nearest per robot (robot-major)
        obstacles = ca.SX.sym("obstacles", 3 * (n * n_obstacle_slots if n_obstacle_slots else m_obs))
        # safety margins are parameters: per robot toward obstacles, per pair between robots
        pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
        obstacle_margin = ca.SX.sym("obstacle_margin", n)
        pair_margin = ca.SX.sym("pair_margin", len(pairs))
        # moving discs (the distributed NMPC's neighbours): a position per slot and stage 1..T, and
        # per slot the radius plus margin to keep (no slots: the central problem, unchanged)
        neighbour_xy = ca.SX.sym("neighbour_xy", 2 * n_slots * horizon)
        neighbour_reach = ca.SX.sym("neighbour_reach", n_slots)
        # pair slots (config.pair_slots): slot p constrains the distance between
        # sum_m select[p, m] p_m + offset_p and 0, i.e. p_i - p_j (select: +1 at i, -1 at j) or,
        # parked, a point far away; reach: both radii plus the pair's margin
        pair_select = ca.SX.sym("pair_select", n * n_pair_slots)
        pair_offset = ca.SX.sym("pair_offset", 2 * n_pair_slots)
        pair_reach = ca.SX.sym("pair_reach", n_pair_slots)
        params = ca.vertcat(
            x_meas,
            goal_xy,
            goal_cs,
            obstacles,
            obstacle_margin,
            pair_margin,
            neighbour_xy,
            neighbour_reach,
            pair_select,
            pair_offset,
            pair_reach,
            theta,
        )

        formation = scenario.is_formation
        weights = [
            config.q_follower if formation and i != scenario.leader else config.q_leader for i in range(n)
        ]
        r_weights = np.tile(np.asarray(config.r_input, dtype=float), n)
        x0_w, x1_w, y0_w, y1_w = scenario.workspace
        radius = scenario.robot_radius
        u_high = np.tile([scenario.v_max, scenario.omega_max], n)
        x_low = np.tile([x0_w, y0_w] + [-np.inf] * (size - 2), n)
        x_high = np.tile([x1_w, y1_w] + [np.inf] * (size - 2), n)

        xs = [ca.SX.sym(f"x{k}", nx) for k in range(horizon + 1)]
        us = [ca.SX.sym(f"u{k}", nu) for k in range(horizon)]
        ss = [ca.SX.sym(f"s{k}", ns) for k in range(horizon)]
        w, lbw, ubw = [], [], []
        g, lbg, ubg, equality = [], [], [], []
        stage_cons: list[NDArray] = []
        terminal_rows = np.zeros(0, dtype=int)  # rows of the terminal state written on the last stage
        cost: ca.SX | int = 0

        def constrain(expr, low, high) -> None:
            expr = ca.vertcat(expr)
            count = expr.shape[0]
            g.append(expr)
            lbg.append(np.broadcast_to(low, count))
            ubg.append(np.broadcast_to(high, count))
            equality.extend([bool(np.all(np.asarray(low) == np.asarray(high)))] * count)

        def collision_constraints(x, slack, stage) -> None:
            for i in range(n):
                px, py = x[size * i], x[size * i + 1]
                for j in range(n_slots):
                    at = 2 * (n_slots * (stage - 1) + j)
                    reach = radius[i] + neighbour_reach[j]
                    clear = (px - neighbour_xy[at]) ** 2 + (py - neighbour_xy[at + 1]) ** 2 - reach**2
                    constrain(clear + slack, 0.0, np.inf)
                for k in range(n_obstacle_slots or m_obs):
                    at = 3 * (i * n_obstacle_slots + k) if n_obstacle_slots else 3 * k
                    ox, oy, orad = obstacles[at], obstacles[at + 1], obstacles[at + 2]
                    clear = (px - ox) ** 2 + (py - oy) ** 2 - (radius[i] + orad + obstacle_margin[i]) ** 2
                    constrain(clear + slack, 0.0, np.inf)
                if n_pair_slots:
                    continue
                for j in range(i + 1, n):
                    margin = pair_margin[pairs.index((i, j))]
                    clear = (
                        (px - x[size * j]) ** 2
                        + (py - x[size * j + 1]) ** 2
                        - (radius[i] + radius[j] + margin) ** 2
                    )
                    constrain(clear + slack, 0.0, np.inf)
            robot_x = ca.vertcat(*[x[size * m] for m in range(n)])
            robot_y = ca.vertcat(*[x[size * m + 1] for m in range(n)])
            for p in range(n_pair_slots):
                select = pair_select[n * p : n * (p + 1)]
                dx = ca.dot(select, robot_x) + pair_offset[2 * p]
                dy = ca.dot(select, robot_y) + pair_offset[2 * p + 1]
                constrain(dx**2 + dy**2 - pair_reach[p] ** 2 + slack, 0.0, np.inf)

        # least-squares form of the cost, for the real-time iteration's Gauss-Newton Hessian:
        # cost = sum of squared residuals + linear_cost (the slacks' exact-penalty term)
        residuals: list = []
        linear_cost: ca.SX | int = 0

        def tracking_cost(x):
            total = 0
            for i in range(n):
                px, py = x[size * i], x[size * i + 1]
                if coding == "pose":
                    cos_th, sin_th = ca.cos(x[size * i + 2]), ca.sin(x[size * i + 2])
                else:
                    cos_th, sin_th = x[size * i + 2], x[size * i + 3]
                qx, qy, qc, qs = weights[i]
                residuals.extend(
                    [
                        np.sqrt(qx) * (px - goal_xy[2 * i]),
                        np.sqrt(qy) * (py - goal_xy[2 * i + 1]),
                        np.sqrt(qc) * (cos_th - goal_cs[2 * i]),
                        np.sqrt(qs) * (sin_th - goal_cs[2 * i + 1]),
                    ]
                )
                total += (
                    qx * (px - goal_xy[2 * i]) ** 2
                    + qy * (py - goal_xy[2 * i + 1]) ** 2
                    + qc * (cos_th - goal_cs[2 * i]) ** 2
                    + qs * (sin_th - goal_cs[2 * i + 1]) ** 2
                )
            return total

        slack: ca.SX | int  # a stage's slack variables, or 0 without soft constraints
        formation_slack: ca.SX | int
        for k in range(horizon + 1):
            x = xs[k]
            first = len(equality)
            w.append(x)
            lbw.append(np.full(nx, -np.inf) if k == 0 else x_low)
            ubw.append(np.full(nx, np.inf) if k == 0 else x_high)
            if k < horizon:
                u, slack_vars = us[k], ss[k]
                w += [u, slack_vars]
                lbw += [-u_high, np.zeros(ns)]
                slack_high = np.full(ns, np.inf)
                if terminal_slack and soft and k < horizon - 1:
                    slack_high[2] = 0.0  # the terminal rows' slack exists on the last stage only
                ubw += [u_high, slack_high]
                cost += ca.dot(r_weights, u * u)
                residuals.append(np.sqrt(r_weights) * u)
                if soft:
                    cost += config.slack_penalty * (ca.sum1(slack_vars) + ca.sumsqr(slack_vars))
                    residuals.append(np.sqrt(config.slack_penalty) * slack_vars)
                    linear_cost += config.slack_penalty * ca.sum1(slack_vars)
                    slack, formation_slack = slack_vars[0], slack_vars[1]
                else:
                    slack = formation_slack = 0
                x_next = f(x, u)
                constrain(xs[k + 1] - x_next, 0.0, 0.0)
            else:
                slack = 0  # the terminal stage has no slack (below: terminal_slack)
            if k == 0:
                constrain(x - x_meas, 0.0, 0.0)
            else:
                cost += tracking_cost(x)
                if not (terminal_slack and k == horizon):
                    collision_constraints(x, slack, k)
            if terminal_slack and k == horizon - 1:
                # the terminal state's collision rows, written on the last stage's f(x, u) with
                # a slack of their own: the structured QP solvers take no variables at the
                # terminal stage, and every row of the real-time iteration's QP stays soft. A
                # slack shared with the stage's own rows changed the closed loop (the Map 2
                # crossing deadlocked, with IPOPT as well)
                terminal_first = len(equality)
                collision_constraints(x_next, slack_vars[2] if soft else 0, horizon)
                terminal_rows = np.arange(terminal_first, len(equality))
            if formation and k < horizon:
                # lb <= (x_f,k+1 - x_f,k) - (x_l,k+1 - x_l,k) <= ub, written with f(x_k, u_k)
                lead = size * scenario.leader
                for i in range(n):
                    if i == scenario.leader:
                        continue
                    for axis in range(2):
                        a, b = size * i + axis, lead + axis
                        deviation = (x_next[a] - x[a]) - (x_next[b] - x[b])
                        constrain(deviation + formation_slack, -config.formation_bound, np.inf)
                        constrain(deviation - formation_slack, -np.inf, config.formation_bound)
            stage_cons.append(np.arange(first, len(equality)))
        self.n_robots = n
        self.neighbour_slots = n_slots
        self.pair_slots, self.obstacle_slots = n_pair_slots, n_obstacle_slots
        self._nlp = {"x": ca.vertcat(*w), "f": cost, "g": ca.vertcat(*g), "p": params}
        #: the cost as ``sumsqr(residuals) + linear_cost`` (same value as ``f``)
        self.least_squares = (ca.vertcat(*residuals), linear_cost)
        #: constraint rows per stage, stage 0 first (for the structured QP solvers)
        self.stage_rows = [int(c.size) for c in stage_cons]
        self.terminal_rows = terminal_rows
        self._equality = equality
        self._config = config
        self._solvers: dict[tuple[str, bool], ca.Function] = {}
        self._rti: RealTimeIteration | None = None
        self.lbw, self.ubw = np.concatenate(lbw).astype(float), np.concatenate(ubw).astype(float)
        self.lbg = np.concatenate(lbg).astype(float)
        self.ubg = np.concatenate(ubg).astype(float)
        self.n_vars, self.n_cons = self.lbw.size, self.lbg.size
        # the bounds never change: convert them to CasADi once, not at every solver call (~0.2 ms)
        self.bounds = {
            name: ca.DM(v)
            for name, v in (("lbx", self.lbw), ("ubx", self.ubw), ("lbg", self.lbg), ("ubg", self.ubg))
        }
        self.nx, self.nu, self.ns, self.horizon, self.coding = nx, nu, ns, horizon, coding
        self.stage_size = nx + nu + ns
        stage = self.stage_size
        self.u_index = np.concatenate(
            [np.arange(t * stage + nx, t * stage + nx + nu) for t in range(horizon)]
        )
        self.x_index = np.concatenate([np.arange(t * stage, t * stage + nx) for t in range(1, horizon + 1)])
        self.stage_cons = stage_cons
        self.step = step_function  # (s, u, theta) -> s_next, for the shifted warm start
        self._step_call: tuple[Any, Any, list[NDArray], NDArray] | None = None

    def solver_for(self, name: str, cold: bool = False) -> ca.Function:
        """The ``nlpsol`` of this problem for a solver plugin, built on first use.

        ``cold=True``: the variant for a start without a previous solution (no warm-start
        options, see :data:`WARM_START_OPTIONS`).
        """
        if (name, cold) not in self._solvers:
            options = self.solver_options(name, cold)
            label = f"nmpc_{name}_cold" if cold else f"nmpc_{name}"
            self._solvers[(name, cold)] = nlpsol(label, name, self._nlp, options)
        return self._solvers[(name, cold)]

    def solver_options(self, name: str, cold: bool = False) -> dict[str, Any]:
        """The ``nlpsol`` options :meth:`solver_for` builds ``name``'s solver with."""
        options = self._config.options_for(name)
        if cold:
            for key in WARM_START_OPTIONS.get(name, ()):
                options.pop(key, None)
        options.setdefault("expand", True)
        if name == "ipopt":
            # the paper's (monotone) barrier update up to its 3 robots; beyond, the adaptive one:
            # with monotone, 8 robots on a random map hit the 100-iteration limit at every step
            # (3 s per step), adaptive converges in ~10 iterations (bench/scaling.py)
            options.setdefault(
                "ipopt.mu_strategy", "monotone" if self.n_robots <= PARAMS.n_robots else "adaptive"
            )
        if name == "fatrop":
            options.setdefault("structure_detection", "auto")
            options.setdefault("equality", self._equality)
        return options

    def real_time_iteration(self) -> RealTimeIteration:
        """The real-time iteration of this problem (its QP solver built on first use)."""
        if self._rti is None:
            config = self._config
            self._rti = RealTimeIteration(self, config.qp_solver, config.rti_iterations, config.hessian)
        return self._rti

    def plan(self, w: NDArray) -> tuple[NDArray, NDArray]:
        """Split a decision vector into commands (T, N, 2) and predicted poses (T, N, 3)."""
        states = w[self.x_index].reshape(self.horizon, -1)
        return w[self.u_index].reshape(self.horizon, -1, 2), decode_state(states, self.coding)

    def _predict(self, state: NDArray, command: NDArray, theta: NDArray) -> NDArray:
        """The model's next NLP state, through a CasADi buffer on preallocated arrays (a plain
        call converts the model's coefficients element by element: 0.3 ms for a Koopman model)."""
        if self._step_call is None:
            step = self.step
            inputs = [np.zeros(step.nnz_in(i)) for i in range(step.n_in())]
            output = np.zeros(step.nnz_out(0))
            buffer, evaluate = bind_buffer(step, inputs, [output])
            self._step_call = (buffer, evaluate, inputs, output)
        _, evaluate, inputs, output = self._step_call
        for array, value in zip(inputs, (state, command, theta)):
            array[:] = value
        evaluate()
        return output.copy()

    def shift(self, w: NDArray, lam_x: NDArray, lam_g: NDArray, theta: NDArray) -> dict[str, NDArray]:
        """Primal-dual guess for the next period: every stage moves one step earlier.

        ``theta``: the model's coefficients (its NLP parameters; empty for constants).

        The last stage's command repeats from the old terminal state, and the new terminal state
        is its prediction, so the guess has no dynamics gap; stage 0's constraint multipliers
        (its shape differs) are kept.
        """
        stage, nx, nu = self.stage_size, self.nx, self.nu

        def shift_primal(v: NDArray) -> NDArray:
            out = v.copy()
            out[: -stage - nx] = v[stage:-nx]
            return out

        x = shift_primal(w)
        last = (self.horizon - 1) * stage  # the new last stage: (x_T-1, u_T-1, s_T-1), then x_T
        x[last : last + nx] = w[-nx:]
        x[-nx:] = self._predict(w[-nx:], x[last + nx : last + nx + nu], theta)

        lam = lam_g.copy()
        for k in range(1, self.horizon - 1):
            source = self.stage_cons[k + 1]
            if k + 1 == self.horizon - 1 and self.terminal_rows.size:
                # the last stage also holds the terminal state's rows (kept where they are)
                source = source[~np.isin(source, self.terminal_rows)]
            lam[self.stage_cons[k]] = lam_g[source]
        return {"x": x, "lam_x": shift_primal(lam_x), "lam_g": lam}


def check_solver_options(config: NMPCConfig) -> None:
    """Raise ``ValueError`` naming a bad solver option of ``config`` and what is allowed."""
    if config.solver not in SOLVERS:
        raise ValueError(f"solver={config.solver!r} is not one of {list(SOLVERS)}")
    if config.fallback_solver is not None and config.fallback_solver not in SOLVERS[1:]:
        raise ValueError(
            f"fallback_solver={config.fallback_solver!r} is not one of {list(SOLVERS[1:])} or None"
        )
    check_rti_options(config.qp_solver, config.rti_iterations, config.hessian)
    tol = config.slack_tolerance
    if isinstance(tol, bool) or not isinstance(tol, (int, float)) or not tol > 0:
        raise ValueError(f"slack_tolerance={tol!r} must be a number > 0")


@dataclass
class _SolveOutcome:
    """One attempt at the period's problem: (success, status, plan, multipliers, iterations)."""

    success: bool
    status: str
    w: NDArray | None = None
    lam_x: NDArray | None = None
    lam_g: NDArray | None = None
    iterations: int = 0


class NMPCController(BaseController):
    """NMPC with a given prediction model (see :mod:`controllers.koopman_nmpc`,
    :mod:`controllers.nominal_nmpc`).

    Parameters
    ----------
    model : PredictionModel, optional
        Prediction model; subclasses may provide it at reset instead.
    config : NMPCConfig, optional
        Options (paper defaults).
    **options
        Shorthand for fields of :class:`NMPCConfig` (``horizon=10``, ``solver="fatrop"``...).
    """

    name = "nmpc"
    #: moving-disc slots of the built problem (the distributed NMPC's robots: their neighbours)
    neighbour_slots = 0

    def __init__(
        self, model: PredictionModel | None = None, config: NMPCConfig | None = None, **options: Any
    ):
        super().__init__()
        base = config or NMPCConfig()
        try:
            self.config = base.with_options(**options) if options else base
        except TypeError as exc:
            raise ValueError(f"{type(self).__name__}: unknown option in {sorted(options)} ({exc})") from None
        check_int("horizon", self.config.horizon, 1)
        check_int("pair_slots", self.config.pair_slots, 0)
        check_int("obstacle_slots", self.config.obstacle_slots, 0)
        k = self.config.uncertainty_margin
        if isinstance(k, bool) or not isinstance(k, (int, float)) or not np.isfinite(k) or k < 0:
            raise ValueError(f"uncertainty_margin={k!r} must be a finite number >= 0")
        check_solver_options(self.config)
        self.model = model
        #: RMS one-step position residual of the prediction model per robot [m], from calibration
        self.position_residual: NDArray[np.float64] | None = None
        self._problem: _Problem | None = None
        self._key: tuple | None = None
        self._model_step: tuple[Any, tuple[ca.Function, NDArray, Any]] | None = None
        self._warm: dict[str, NDArray] | None = None
        self._fallback: NDArray | None = None
        self._fallback_used = 0
        self.last_plan: tuple[NDArray, NDArray] | None = None

    # ------------------------------------------------------------------ setup
    def _model_for(self, scenario: Scenario) -> PredictionModel:
        if self.model is None:
            raise ValueError(f"{self.name}: no prediction model was given")
        return self.model

    def _reset(self, scenario: Scenario, seed: int | None) -> None:
        model = self._model_for(scenario)
        if model.n_robots != scenario.n_robots:
            raise ValueError(
                f"{self.name}: the prediction model has {model.n_robots} robots, the scenario {scenario.n_robots}"
            )
        if self._model_step is None or self._model_step[0] is not model:
            self._model_step = (model, model_step(model))  # built once per model, not per episode
        step = self._model_step[1]
        _, theta_values, structure = step
        key = (
            structure,
            scenario.n_robots,
            # with obstacle slots one problem serves any obstacle count
            0 if self.config.obstacle_slots else scenario.obstacles.shape[0],
            scenario.task,
            tuple(scenario.robot_radius),
            scenario.workspace,
            scenario.v_max,
            scenario.omega_max,
            self.neighbour_slots,
        )
        if key != self._key:
            self._problem = _Problem(
                model,
                scenario,
                self.config,
                step,
                terminal_slack=self.config.solver == "rti",
                neighbour_slots=self.neighbour_slots,
            )
            self._key = key
        obstacle_margin, pair_margin = self.safety_margins(scenario)
        self._scenario_obstacles = np.asarray(scenario.obstacles, dtype=float).reshape(-1, 3)
        self._radius = np.asarray(scenario.robot_radius, dtype=float)
        self._pair_reach = 2 * scenario.v_max * self.config.horizon * scenario.dt
        obstacles = (
            self._nearest_obstacles(scenario.starts[:, :2])
            if self.config.obstacle_slots
            else scenario.obstacles.reshape(-1)
        )
        fixed = np.concatenate(
            [
                scenario.targets[:, :2].reshape(-1),
                np.column_stack([np.cos(scenario.targets[:, 2]), np.sin(scenario.targets[:, 2])]).reshape(-1),
                obstacles,
            ]
        )
        # the parameters after the measured state; margins and model coefficients may change
        # during an episode (see set_margins, set_model_parameters)
        assert self._problem is not None  # built above
        slots, horizon = self._problem.neighbour_slots, self._problem.horizon
        # neighbour slots start parked (see set_neighbours), pair slots too (see _assign_pairs)
        neighbours = np.concatenate([np.full(2 * slots * horizon, PARKED), np.zeros(slots)])
        n, p_slots = scenario.n_robots, self.config.pair_slots
        pair_block = np.concatenate([np.zeros(n * p_slots), np.full(2 * p_slots, PARKED), np.zeros(p_slots)])
        self._pairs_in_slots: list[tuple[int, int] | None] = [None] * p_slots
        self._params_tail = np.concatenate(
            [fixed, obstacle_margin, pair_margin, neighbours, pair_block, theta_values]
        )
        start = fixed.size
        self._margin_slices = (
            slice(start, start + obstacle_margin.size),
            slice(start + obstacle_margin.size, start + obstacle_margin.size + pair_margin.size),
        )
        after_margins = start + obstacle_margin.size + pair_margin.size
        self._neighbour_slice = slice(after_margins, after_margins + neighbours.size)
        self._pair_slice = slice(self._neighbour_slice.stop, self._neighbour_slice.stop + pair_block.size)
        self._obstacle_slice = slice(fixed.size - obstacles.size, fixed.size)
        self._theta_slice = slice(self._params_tail.size - theta_values.size, self._params_tail.size)
        self._warm = None
        self._fallback = None
        self._fallback_used = 0
        self.last_plan = None
        self._stats.solver = self.solver_label

    @property
    def solver_label(self) -> str:
        """The optimizer as reports name it: ``"rti/<qp solver>"`` or the ``nlpsol`` plugin."""
        config = self.config
        return f"rti/{config.qp_solver}" if config.solver == "rti" else config.solver

    def set_margins(self, obstacle: NDArray, pair: NDArray) -> None:
        """Use these safety margins from the next solve on (shapes as :meth:`safety_margins`)."""
        self._params_tail[self._margin_slices[0]] = obstacle
        self._params_tail[self._margin_slices[1]] = pair

    def set_neighbours(self, positions: NDArray, reach: NDArray) -> None:
        """Use these moving discs from the next solve on (a problem built with neighbour slots).

        ``positions`` (T, K, 2): each slot's predicted position at stages 1..T; ``reach`` (K,):
        the slot's radius plus the margin to keep. An unused slot is parked (:data:`PARKED`).
        """
        self._params_tail[self._neighbour_slice] = np.concatenate([np.ravel(positions), np.ravel(reach)])

    def set_goal(self, index: int, xy: NDArray) -> None:
        """Track ``xy`` instead of robot ``index``'s target position from the next solve on."""
        self._params_tail[2 * index : 2 * index + 2] = xy

    def set_obstacles(self, obstacles: NDArray) -> None:
        """Use these obstacles (M, 3) from the next solve on (M as the problem was built for)."""
        self._params_tail[self._obstacle_slice] = np.ravel(obstacles)

    def _nearest_obstacles(self, positions: NDArray) -> NDArray:
        """Obstacle slot values: each robot's ``obstacle_slots`` nearest obstacles, robot-major, flat."""
        k = self.config.obstacle_slots
        n = positions.shape[0]
        slots = np.tile([PARKED, PARKED, 0.0], (n, k, 1))
        obstacles = self._scenario_obstacles
        if obstacles.size:
            gap = (
                np.hypot(*(positions[:, None, :] - obstacles[None, :, :2]).transpose(2, 0, 1))
                - obstacles[:, 2]
            )
            nearest = np.argsort(gap, axis=1, kind="stable")[:, :k]
            count = nearest.shape[1]
            slots[:, :count] = obstacles[nearest]
        return slots.reshape(-1)

    def _fill_slots(self, positions: NDArray) -> None:
        """Refresh the obstacle slots and the pair slots from the robots' current positions."""
        if self.config.obstacle_slots:
            self._params_tail[self._obstacle_slice] = self._nearest_obstacles(positions)
        p_slots = self.config.pair_slots
        if not p_slots:
            return
        n = positions.shape[0]
        pair_margin = self._params_tail[self._margin_slices[1]]
        i_index, j_index = np.triu_indices(n, 1)  # the order of pair_margin
        distance = np.hypot(*(positions[i_index] - positions[j_index]).T)
        keep = self._radius[i_index] + self._radius[j_index] + pair_margin
        within = distance < self._pair_reach + keep
        candidates = [
            (int(i_index[q]), int(j_index[q])) for q in np.flatnonzero(within)[np.argsort(distance[within])]
        ]
        active = set(candidates)
        # a pair keeps its slot while it stays within reach (its multipliers stay meaningful)
        slots = [pair if pair in active else None for pair in self._pairs_in_slots]
        placed = {pair for pair in slots if pair is not None}
        free = [s for s, pair in enumerate(slots) if pair is None]
        waiting = [pair for pair in candidates if pair not in placed]
        for slot, waiting_pair in zip(free, waiting, strict=False):
            slots[slot] = waiting_pair
        dropped = len(waiting) - min(len(waiting), len(free))
        if dropped:
            self._stats.counts["pairs_dropped"] += dropped
        select = np.zeros((p_slots, n))
        offset = np.full((p_slots, 2), PARKED)
        reach = np.zeros(p_slots)
        for slot, held in enumerate(slots):
            if held is None:
                continue
            i, j = held
            select[slot, i], select[slot, j] = 1.0, -1.0
            offset[slot] = 0.0
            # position of pair (i, j), i < j, in the row-major upper triangle (pair_margin's order)
            reach[slot] = keep[i * n - i * (i + 1) // 2 + (j - i - 1)]
        self._pairs_in_slots = slots
        self._params_tail[self._pair_slice] = np.concatenate([select.ravel(), offset.ravel(), reach])

    def set_model_parameters(self, theta: NDArray) -> None:
        """Use these model coefficients (the model's ``nlp_parameters`` layout) from the next solve on."""
        self._params_tail[self._theta_slice] = theta

    def safety_margins(self, scenario: Scenario) -> tuple[NDArray, NDArray]:
        """Margins added to the radii: per robot toward obstacles (N,), per robot pair (i < j).

        ``obstacle_offset`` and ``robot_offset``, widened to ``uncertainty_margin`` times the
        prediction model's calibrated residual when that is larger.
        """
        n = scenario.n_robots
        k = self.config.uncertainty_margin
        if k > 0 and (self.position_residual is None or len(self.position_residual) != n):
            raise ValueError(
                f"{self.name}: uncertainty_margin={k} needs the prediction model's residual for "
                f"{n} robots; call calibrate(plant) first (the evaluator does)"
            )
        return self.margins_for(n, self.position_residual)

    def margins_for(self, n_robots: int, residual: NDArray | None) -> tuple[NDArray, NDArray]:
        """:meth:`safety_margins` for a given per-robot RMS position residual [m] (None: offsets only)."""
        n = n_robots
        pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
        obstacle = np.full(n, self.config.obstacle_offset)
        pair = np.full(len(pairs), self.config.robot_offset)
        k = self.config.uncertainty_margin
        if k > 0 and residual is not None:
            spread = k * np.asarray(residual, dtype=float)
            obstacle = np.maximum(obstacle, spread)
            pair = np.maximum(pair, np.array([spread[i] + spread[j] for i, j in pairs]))
        return obstacle, pair

    # -------------------------------------------------------------------- act
    def _initial_guess(self, state: NDArray) -> NDArray:
        """Hold the current state with zero commands (the first step of an episode)."""
        prob = self._problem
        assert prob is not None  # built by _reset, which act() requires
        w = np.zeros(prob.n_vars)
        w[prob.x_index] = np.tile(state, prob.horizon)
        w[: prob.nx] = state
        return w

    def _act(self, observation: NDArray, info: dict[str, Any]) -> NDArray[np.float64]:
        prob = self._problem
        assert prob is not None  # built by _reset, which act() requires
        state = encode_state(info["poses"], prob.coding)
        if self.config.obstacle_slots or self.config.pair_slots:
            self._fill_slots(np.asarray(info["poses"], dtype=float)[:, :2])
        params = np.concatenate([state, self._params_tail])
        cold = self._warm is None
        if self._warm is None:  # cold
            guess = {
                "x0": self._initial_guess(state),
                "lam_x0": np.zeros(prob.n_vars),
                "lam_g0": np.zeros(prob.n_cons),
            }
        else:
            guess = {"x0": self._warm["x"], "lam_x0": self._warm["lam_x"], "lam_g0": self._warm["lam_g"]}
        start = time.perf_counter()
        main = self.config.solver
        if main == "rti":
            outcome = self._solve_rti(params, guess)
        else:
            outcome = self._solve_nlp(main, params, guess, cold)
        fallback = self.config.fallback_solver
        if not outcome.success and fallback and fallback != main:
            first = outcome
            outcome = self._solve_nlp(fallback, params, guess, cold)
            outcome.iterations += first.iterations
            outcome.status = f"{main}:{first.status} -> {fallback}:{outcome.status}"
            self._stats.counts[f"fallback_{fallback}"] += 1
        self._stats.solve_times.append(time.perf_counter() - start)
        self._stats.iterations.append(outcome.iterations)  # QPs, plus IPOPT's iterations on a fallback
        self._stats.statuses[outcome.status] += 1
        if outcome.success:
            # a successful outcome carries its plan and multipliers (_solve_rti, _solve_nlp)
            assert outcome.w is not None and outcome.lam_x is not None and outcome.lam_g is not None
            commands, poses = prob.plan(outcome.w)
            self.last_plan = (commands, poses)
            self._warm = prob.shift(
                outcome.w, outcome.lam_x, outcome.lam_g, self._params_tail[self._theta_slice]
            )
            self._fallback = commands
            self._fallback_used = 0
            return commands[0].reshape(-1).copy()
        self._stats.failures += 1
        self._warm = None  # a failed iterate is a poor starting point: restart cold next step
        return self._fallback_command()

    def _solve_rti(self, params: NDArray, guess: dict[str, NDArray]) -> _SolveOutcome:
        """The real-time iteration's QP(s); a failed QP or a plan with a large slack fails."""
        assert self._problem is not None  # built by _reset, which act() requires
        step = self._problem.real_time_iteration().solve(
            guess["x0"], guess["lam_x0"], guess["lam_g0"], params
        )
        if not step.success:
            return _SolveOutcome(False, f"qp_failed({step.status})", iterations=step.iterations)
        if step.max_slack > self.config.slack_tolerance:
            return _SolveOutcome(False, "large_slack", iterations=step.iterations)
        return _SolveOutcome(True, "rti", step.w, step.lam_x, step.lam_g, step.iterations)

    def _solve_nlp(self, name: str, params: NDArray, guess: dict[str, NDArray], cold: bool) -> _SolveOutcome:
        """One ``nlpsol`` call of plugin ``name`` to convergence."""
        prob = self._problem
        assert prob is not None  # built by _reset, which act() requires
        solver = prob.solver_for(name, cold)
        try:
            sol = solver(p=params, **prob.bounds, **guess)
        except RuntimeError as exc:  # CasADi raises on evaluation errors (e.g. NaN in a function)
            return _SolveOutcome(False, f"error: {exc}".splitlines()[0][:80])
        stats = solver.stats()
        status = str(stats.get("return_status", "unknown"))
        w = np.asarray(sol["x"]).reshape(-1)
        success = bool(stats.get("success", False)) and bool(np.all(np.isfinite(w)))
        if not np.all(np.isfinite(w)):
            status = "non_finite_solution"
        return _SolveOutcome(
            success,
            status,
            w,
            np.asarray(sol["lam_x"]).reshape(-1),
            np.asarray(sol["lam_g"]).reshape(-1),
            int(stats.get("iter_count", 0)),
        )

    def _fallback_command(self) -> NDArray[np.float64]:
        """Next command of the last successful plan, or a stop when that plan is used up."""
        assert self.scenario is not None  # act() checked it
        n = self.scenario.n_robots
        self._fallback_used += 1
        if self._fallback is not None and self._fallback_used < self._fallback.shape[0]:
            return self._fallback[self._fallback_used].reshape(-1).copy()
        return np.zeros(2 * n)
