"""The NMPC's nonlinear program (SPEC section 3), built once per problem structure.

Multiple shooting over the horizon: the decision vector is ordered stage by stage,
``[x_0, u_0, s_0, x_1, u_1, s_1, ..., x_T]`` (s: the slacks), and the constraints likewise
(stage k: the dynamics gap x_k+1 - f(x_k, u_k), then the path constraints of stage k;
x_0 = measured state at stage 0). That is the layout the structure detection of the fatrop solver
and the stage-wise QP of the real-time iteration need; IPOPT solves it the same way. The
parameters are the named blocks of :mod:`controllers.mpc.layout`.

The pieces are separate functions: :func:`tracking_cost` (the stage cost on the goals),
:func:`clearances` (obstacles, robot pairs, pair slots and moving neighbour discs), written as
distance rows by :func:`collision_rows` or, with ``cbf_gamma`` set, as discrete-time control
barrier rows by :func:`barrier_rows`, and :func:`formation_rows` (the bound on how fast a follower's offset to the leader may change).
:class:`Problem` stacks them stage by stage and keeps the index maps, the bounds, the solvers
built on it and the shifted warm start.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from controllers.mpc.config import WARM_START_OPTIONS, NMPCConfig
from controllers.mpc.layout import nmpc_layout
from controllers.mpc.models import PredictionModel, coding_size, decode_state, model_step
from controllers.mpc.rti import RealTimeIteration, bind_buffer
from controllers.solvers.compiled import nlpsol
from koopman_envs.params import PARAMS
from koopman_envs.scenario import Scenario

__all__ = ["Problem", "barrier_rows", "clearances", "collision_rows", "formation_rows", "tracking_cost"]


class Rows:
    """The constraint rows g(w) with their bounds, in the order they are added."""

    def __init__(self) -> None:
        self.g: list[Any] = []
        self.lbg: list[NDArray] = []
        self.ubg: list[NDArray] = []
        self.equality: list[bool] = []

    def add(self, expr: Any, low: Any, high: Any) -> None:
        """Rows ``low <= expr <= high`` (bounds broadcast over the rows)."""
        expr = ca.vertcat(expr)
        count = expr.shape[0]
        self.g.append(expr)
        self.lbg.append(np.broadcast_to(low, count))
        self.ubg.append(np.broadcast_to(high, count))
        self.equality.extend([bool(np.all(np.asarray(low) == np.asarray(high)))] * count)

    def __len__(self) -> int:
        return len(self.equality)


@dataclass(frozen=True)
class Geometry:
    """What the rows and the cost of one problem structure need: sizes, radii, weights, symbols."""

    n: int
    size: int  # NLP state entries per robot (the model's coding)
    coding: str
    radius: NDArray[np.float64]
    weights: list[tuple[float, ...]]  # per robot (qx, qy, qc, qs)
    symbols: dict[str, Any]  # the parameter blocks' symbols (controllers.mpc.layout)
    obstacle_count: int  # obstacles in the problem (every one, or slots per robot)
    obstacle_slots: int
    neighbour_slots: int
    pair_slots: int
    pairs: list[tuple[int, int]]
    leader: int
    formation: bool


def tracking_cost(x: Any, geo: Geometry, residuals: list) -> Any:
    """Stage cost of state ``x`` on the goals; appends its least-squares residuals to ``residuals``."""
    goal_xy, goal_cs, size = geo.symbols["goal_xy"], geo.symbols["goal_cs"], geo.size
    total = 0
    for i in range(geo.n):
        px, py = x[size * i], x[size * i + 1]
        if geo.coding == "pose":
            cos_th, sin_th = ca.cos(x[size * i + 2]), ca.sin(x[size * i + 2])
        else:
            cos_th, sin_th = x[size * i + 2], x[size * i + 3]
        qx, qy, qc, qs = geo.weights[i]
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


def clearances(x: Any, stage: int, geo: Geometry) -> list[Any]:
    """The clearance functions h(x) of state ``x`` at ``stage`` (>= 1), one per collision row, in
    row order: per robot, its neighbour discs (at their stage-``stage`` positions), its obstacles
    and the robots after it (or, with pair slots, one per slot). Each is a squared centre distance
    minus the squared reach (radii plus margin): >= 0 is clear."""
    sym, size, radius = geo.symbols, geo.size, geo.radius
    out = []
    for i in range(geo.n):
        px, py = x[size * i], x[size * i + 1]
        for j in range(geo.neighbour_slots):
            at = 2 * (geo.neighbour_slots * (stage - 1) + j)
            reach = radius[i] + sym["neighbour_reach"][j]
            out.append(
                (px - sym["neighbour_xy"][at]) ** 2 + (py - sym["neighbour_xy"][at + 1]) ** 2 - reach**2
            )
        for k in range(geo.obstacle_count):
            at = 3 * (i * geo.obstacle_slots + k) if geo.obstacle_slots else 3 * k
            ox, oy, orad = sym["obstacles"][at], sym["obstacles"][at + 1], sym["obstacles"][at + 2]
            out.append((px - ox) ** 2 + (py - oy) ** 2 - (radius[i] + orad + sym["obstacle_margin"][i]) ** 2)
        if geo.pair_slots:
            continue
        for j in range(i + 1, geo.n):
            margin = sym["pair_margin"][geo.pairs.index((i, j))]
            out.append(
                (px - x[size * j]) ** 2 + (py - x[size * j + 1]) ** 2 - (radius[i] + radius[j] + margin) ** 2
            )
    robot_x = ca.vertcat(*[x[size * m] for m in range(geo.n)])
    robot_y = ca.vertcat(*[x[size * m + 1] for m in range(geo.n)])
    for p in range(geo.pair_slots):
        select = sym["pair_select"][geo.n * p : geo.n * (p + 1)]
        dx = ca.dot(select, robot_x) + sym["pair_offset"][2 * p]
        dy = ca.dot(select, robot_y) + sym["pair_offset"][2 * p + 1]
        out.append(dx**2 + dy**2 - sym["pair_reach"][p] ** 2)
    return out


def collision_rows(rows: Rows, x: Any, slack: Any, stage: int, geo: Geometry) -> None:
    """Clearance rows ``h(x) + slack >= 0`` of state ``x`` at ``stage`` (>= 1), one per
    :func:`clearances` entry, each softened by ``slack``."""
    for clear in clearances(x, stage, geo):
        rows.add(clear + slack, 0.0, np.inf)


def barrier_rows(
    rows: Rows, x: Any, x_next: Any, slack: Any, stage: int, gamma: float, geo: Geometry
) -> None:
    """Discrete-time control barrier rows of stage ``stage`` (Zeng, Zhang and Sreenath 2021):
    ``h(x_next) - (1 - gamma) h(x) + slack >= 0`` for every :func:`clearances` entry, with
    ``x_next = f(x, u)`` (so the row is a function of the stage's own variables, as the
    structured QP needs). The clearance may shrink by at most the fraction ``gamma`` per period:
    the robot slows down before an obstacle rather than at it, and a state already inside a
    margin (noise, slip) is asked to recover at that rate rather than at once. ``gamma = 1`` is
    the distance constraint at the next state. A neighbour disc's (mover's) position now is not
    a parameter: at stage 0 its first predicted position stands in."""
    now = clearances(x, max(stage, 1), geo)
    after = clearances(x_next, stage + 1, geo)
    for h_now, h_next in zip(now, after):
        rows.add(h_next - (1.0 - gamma) * h_now + slack, 0.0, np.inf)


def formation_rows(rows: Rows, x: Any, x_next: Any, slack: Any, bound: float, geo: Geometry) -> None:
    """``-bound <= (x_f,k+1 - x_f,k) - (x_l,k+1 - x_l,k) <= bound`` per follower and axis, written
    with ``x_next = f(x_k, u_k)`` and softened by ``slack``."""
    lead = geo.size * geo.leader
    for i in range(geo.n):
        if i == geo.leader:
            continue
        for axis in range(2):
            a, b = geo.size * i + axis, lead + axis
            deviation = (x_next[a] - x[a]) - (x_next[b] - x[b])
            rows.add(deviation + slack, -bound, np.inf)
            rows.add(deviation - slack, -np.inf, bound)


@dataclass
class _Stages:
    """The decision vector and the cost as the stage loop writes them."""

    w: list
    lbw: list
    ubw: list
    stage_rows: list
    residuals: list
    cost: Any = 0
    linear_cost: Any = 0
    terminal_rows: NDArray = field(default_factory=lambda: np.zeros(0, dtype=int))


class Problem:
    """One built NLP: its solvers, index maps, bounds and warm-start shift.

    ``terminal_slack=True`` (the real-time iteration's problem) writes the terminal state's
    collision rows on the last stage, on ``f(x_T-1, u_T-1)``, with a third slack per stage that
    only the last stage may use: the structured QP solvers take no variables at the terminal
    stage, and every row of the QP then has a slack. The NLP is the same problem (its optimum is
    unchanged whenever the hard one is feasible), written differently; IPOPT's closed loop on it
    is not bit-identical to the paper formulation's (see docs/results.md).

    Attributes
    ----------
    nlp : dict
        ``{"x", "f", "g", "p"}`` for ``nlpsol``.
    layout : ParameterLayout
        The named blocks of ``p``.
    lbw, ubw, lbg, ubg : ndarray
        Bounds of the decision vector and the rows.
    u_index, x_index : ndarray
        Where the commands (stages 0..T-1) and the predicted states (1..T) sit in ``w``.
    stage_rows, stage_cons, terminal_rows, least_squares
        The stage structure the real-time iteration and the warm start read.
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
        coding = model.coding
        size = coding_size(coding)  # refuses an unknown coding by name
        nx, nu = size * n, 2 * n
        # slacks per stage: collision rows, formation rows and (terminal_slack) the terminal
        # state's collision rows, which only the last stage uses
        ns = (3 if terminal_slack else 2) if config.soft_constraints else 0
        step_function, theta_values, _ = model_step(model) if step is None else step
        theta = ca.SX.sym("model", theta_values.size)
        n_obstacle_slots = config.obstacle_slots
        self.layout = nmpc_layout(
            nx,
            n,
            3 * (n * n_obstacle_slots if n_obstacle_slots else m_obs),
            horizon,
            neighbour_slots,
            config.pair_slots,
            theta_values.size,
        )
        symbols = self.layout.symbols({"model": theta})
        formation = scenario.is_formation
        geo = Geometry(
            n=n,
            size=size,
            coding=coding,
            radius=scenario.robot_radius,
            weights=[
                config.q_follower if formation and i != scenario.leader else config.q_leader for i in range(n)
            ],
            symbols=symbols,
            obstacle_count=n_obstacle_slots or m_obs,
            obstacle_slots=n_obstacle_slots,
            neighbour_slots=neighbour_slots,
            pair_slots=config.pair_slots,
            pairs=[(i, j) for i in range(n) for j in range(i + 1, n)],
            leader=scenario.leader,
            formation=formation,
        )
        self.nx, self.nu, self.ns, self.horizon, self.coding = nx, nu, ns, horizon, coding
        self.n_robots = n
        self.neighbour_slots = neighbour_slots
        self.pair_slots, self.obstacle_slots = config.pair_slots, n_obstacle_slots
        self.step = step_function  # (s, u, theta) -> s_next, for the shifted warm start
        self._symbols = symbols
        rows = Rows()
        stages = self._stages(geo, scenario, config, rows, theta, terminal_slack)
        self._finish(stages, rows, config)

    def _stages(
        self,
        geo: Geometry,
        scenario: Scenario,
        config: NMPCConfig,
        rows: Rows,
        theta: Any,
        terminal_slack: bool,
    ) -> _Stages:
        """Stack the stages: variables and bounds, dynamics gaps, cost, collision and formation rows."""
        nx, nu, ns, horizon, size = self.nx, self.nu, self.ns, self.horizon, geo.size
        soft, n, barrier = config.soft_constraints, geo.n, config.cbf_gamma
        x_meas = geo.symbols["x_meas"]
        r_weights = np.tile(np.asarray(config.r_input, dtype=float), n)
        x0_w, x1_w, y0_w, y1_w = scenario.workspace
        u_high = np.tile([scenario.v_max, scenario.omega_max], n)
        x_low = np.tile([x0_w, y0_w] + [-np.inf] * (size - 2), n)
        x_high = np.tile([x1_w, y1_w] + [np.inf] * (size - 2), n)
        xs = [ca.SX.sym(f"x{k}", nx) for k in range(horizon + 1)]
        us = [ca.SX.sym(f"u{k}", nu) for k in range(horizon)]
        ss = [ca.SX.sym(f"s{k}", ns) for k in range(horizon)]
        out = _Stages([], [], [], [], [])
        slack: ca.SX | int  # a stage's slack variables, or 0 without soft constraints
        formation_slack: ca.SX | int
        for k in range(horizon + 1):
            x = xs[k]
            first = len(rows)
            out.w.append(x)
            out.lbw.append(np.full(nx, -np.inf) if k == 0 else x_low)
            out.ubw.append(np.full(nx, np.inf) if k == 0 else x_high)
            if k < horizon:
                u, slack_vars = us[k], ss[k]
                out.w += [u, slack_vars]
                out.lbw += [-u_high, np.zeros(ns)]
                slack_high = np.full(ns, np.inf)
                if terminal_slack and soft and k < horizon - 1:
                    slack_high[2] = 0.0  # the terminal rows' slack exists on the last stage only
                out.ubw += [u_high, slack_high]
                out.cost += ca.dot(r_weights, u * u)
                out.residuals.append(np.sqrt(r_weights) * u)
                if soft:
                    out.cost += config.slack_penalty * (ca.sum1(slack_vars) + ca.sumsqr(slack_vars))
                    out.residuals.append(np.sqrt(config.slack_penalty) * slack_vars)
                    out.linear_cost += config.slack_penalty * ca.sum1(slack_vars)
                    slack, formation_slack = slack_vars[0], slack_vars[1]
                else:
                    slack = formation_slack = 0
                x_next = self.step(x, u, theta)
                rows.add(xs[k + 1] - x_next, 0.0, 0.0)
            else:
                slack = 0  # the terminal stage has no slack (below: terminal_slack)
            if k == 0:
                rows.add(x - x_meas, 0.0, 0.0)
            else:
                out.cost += tracking_cost(x, geo, out.residuals)
                if barrier is None and not (terminal_slack and k == horizon):
                    collision_rows(rows, x, slack, k, geo)
            if barrier is not None:
                # the barrier rows of stage k bound h(x_k+1) by h(x_k): stages 0..T-1 cover the
                # states 1..T, and the terminal state needs no rows of its own
                if k < horizon:
                    barrier_rows(rows, x, x_next, slack, k, barrier, geo)
            elif terminal_slack and k == horizon - 1:
                # the terminal state's collision rows, written on the last stage's f(x, u) with
                # a slack of their own: the structured QP solvers take no variables at the
                # terminal stage, and every row of the real-time iteration's QP stays soft. A
                # slack shared with the stage's own rows changed the closed loop (the Map 2
                # crossing deadlocked, with IPOPT as well)
                terminal_first = len(rows)
                collision_rows(rows, x_next, slack_vars[2] if soft else 0, horizon, geo)
                out.terminal_rows = np.arange(terminal_first, len(rows))
            if geo.formation and k < horizon:
                formation_rows(rows, x, x_next, formation_slack, config.formation_bound, geo)
            out.stage_rows.append(np.arange(first, len(rows)))
        return out

    def _finish(self, stages: _Stages, rows: Rows, config: NMPCConfig) -> None:
        """The NLP, its bounds and index maps from the stacked stages."""
        nx, nu, horizon = self.nx, self.nu, self.horizon
        self.nlp = {
            "x": ca.vertcat(*stages.w),
            "f": stages.cost,
            "g": ca.vertcat(*rows.g),
            "p": self.layout.vector(self._symbols),
        }
        #: the cost as ``sumsqr(residuals) + linear_cost`` (same value as ``f``)
        self.least_squares = (ca.vertcat(*stages.residuals), stages.linear_cost)
        #: constraint rows per stage, stage 0 first (for the structured QP solvers)
        self.stage_rows = [int(c.size) for c in stages.stage_rows]
        self.stage_cons = stages.stage_rows
        self.terminal_rows = stages.terminal_rows
        self._equality = rows.equality
        self._config = config
        self._solvers: dict[tuple[str, bool], ca.Function] = {}
        self._rti: RealTimeIteration | None = None
        self.lbw, self.ubw = (
            np.concatenate(stages.lbw).astype(float),
            np.concatenate(stages.ubw).astype(float),
        )
        self.lbg = np.concatenate(rows.lbg).astype(float)
        self.ubg = np.concatenate(rows.ubg).astype(float)
        self.n_vars, self.n_cons = self.lbw.size, self.lbg.size
        # the bounds never change: convert them to CasADi once, not at every solver call (~0.2 ms)
        self.bounds = {
            name: ca.DM(v)
            for name, v in (("lbx", self.lbw), ("ubx", self.ubw), ("lbg", self.lbg), ("ubg", self.ubg))
        }
        self.stage_size = nx + nu + self.ns
        stage = self.stage_size
        self.u_index = np.concatenate(
            [np.arange(t * stage + nx, t * stage + nx + nu) for t in range(horizon)]
        )
        self.x_index = np.concatenate([np.arange(t * stage, t * stage + nx) for t in range(1, horizon + 1)])
        self._step_call: tuple[Any, Any, list[NDArray], NDArray] | None = None

    # ------------------------------------------------------------------ solvers
    def solver_for(self, name: str, cold: bool = False) -> ca.Function:
        """The ``nlpsol`` of this problem for a solver plugin, built on first use.

        ``cold=True``: the variant for a start without a previous solution (no warm-start
        options, see :data:`~controllers.mpc.config.WARM_START_OPTIONS`).
        """
        if (name, cold) not in self._solvers:
            options = self.solver_options(name, cold)
            label = f"nmpc_{name}_cold" if cold else f"nmpc_{name}"
            self._solvers[(name, cold)] = nlpsol(label, name, self.nlp, options)
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

    # ------------------------------------------------------------------ plans
    def plan(self, w: NDArray) -> tuple[NDArray, NDArray]:
        """Split a decision vector into commands (T, N, 2) and predicted poses (T, N, 3)."""
        states = w[self.x_index].reshape(self.horizon, -1)
        return w[self.u_index].reshape(self.horizon, -1, 2), decode_state(states, self.coding)

    def predict(self, state: NDArray, command: NDArray, theta: NDArray) -> NDArray:
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
        x[-nx:] = self.predict(w[-nx:], x[last + nx : last + nx + nu], theta)

        lam = lam_g.copy()
        for k in range(1, self.horizon - 1):
            source = self.stage_cons[k + 1]
            if k + 1 == self.horizon - 1 and self.terminal_rows.size:
                # the last stage also holds the terminal state's rows (kept where they are)
                source = source[~np.isin(source, self.terminal_rows)]
            lam[self.stage_cons[k]] = lam_g[source]
        return {"x": x, "lam_x": shift_primal(lam_x), "lam_g": lam}
