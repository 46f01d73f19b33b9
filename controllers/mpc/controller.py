"""The NMPC controller: build (or reuse) the problem at reset, solve it every period, fall back.

The problem is posed once per problem structure (team size, obstacle count, task, model) by
multiple shooting (:mod:`controllers.mpc.problem`); the measured state, the targets and the
obstacles are parameters (:mod:`controllers.mpc.layout`), so a new episode or a new step only
changes numbers. Every step is warm-started from the previous solution shifted by one period.
When the solver fails (infeasible, iteration limit, NaN) the controller falls back to the rest
of its last plan, then to a safe stop, counts the failure, and the episode goes on.

The distributed NMPC (:mod:`controllers.mpc.distributed`) drives one of these per robot through
its public hooks: :meth:`NMPCController.share_problem`, the ``set_*`` methods, :meth:`restart`,
:attr:`last_plan` and :meth:`solve_failed`.
"""

from __future__ import annotations

import time
from typing import Any, ClassVar

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from controllers.base import BaseController
from controllers.estimation import front_end_for
from controllers.koopman.dictionary import shift_memory
from controllers.movers import observed_mover_radii, observed_movers
from controllers.mpc.config import NMPC_TUNABLE, PARKED, PERCEIVED_OBSTACLE_SLOTS, NMPCConfig
from controllers.mpc.detour import RESTART_ITERATIONS, DeadlockResolver, pursuit_rollout
from controllers.mpc.hooks import ParameterHooks
from controllers.mpc.margins import chance_tightening, margin_spread, offset_margins
from controllers.mpc.models import (
    PredictionModel,
    coding_memory,
    coding_velocity,
    decode_state,
    encode_state,
    model_step,
)
from controllers.mpc.problem import Problem
from controllers.mpc.slots import PairSlots, closing_distance, mover_slots, nearest_obstacle_slots
from controllers.mpc.solve import SolveOutcome, solve_nlp, solve_rti
from controllers.tuning.search_space import Search
from koopman_envs import Observed
from koopman_envs.scenario import Scenario

# the margins (controllers.mpc.margins) stay importable from here, where they were first
__all__ = ["SETTLE_RELEASE", "NMPCController", "SolveOutcome", "chance_tightening", "margin_spread"]

#: a settled robot (``settle_fraction``) moves again when its estimate is farther from its target
#: than this fraction of the goal tolerance
SETTLE_RELEASE = 0.75


class NMPCController(ParameterHooks, BaseController):
    """NMPC with a given prediction model (see :mod:`controllers.mpc.variants`).

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
    #: what the tuner searches (:data:`~controllers.mpc.config.NMPC_TUNABLE`, why these there)
    TUNABLE: ClassVar[dict[str, Search]] = NMPC_TUNABLE
    #: moving-disc slots of the built problem (the distributed NMPC's robots: their neighbours)
    neighbour_slots = 0
    #: the central NMPC runs on the leader's computer and hears the team over its radio
    radio_station: int | None = 0
    #: whether the ``unstall`` option applies (a robot of the distributed NMPC has its goals set
    #: by the team's own stall handling)
    resolves_stalls = True
    #: mover slots of the built problem (set at reset from the scenario and ``mover_slots``)
    _mover_slots = 0
    #: obstacle slots of the built problem: ``obstacle_slots``, or with the map unknown at least
    #: :data:`~controllers.mpc.config.PERCEIVED_OBSTACLE_SLOTS` (set at reset)
    _obstacle_slots = 0

    def __init__(
        self, model: PredictionModel | None = None, config: NMPCConfig | None = None, **options: Any
    ):
        super().__init__()
        self.config = (config or NMPCConfig()).with_options(type(self).__name__, **options)
        self.front_end = front_end_for(self.config.estimator, self.config.ablate)
        self.model = model
        #: RMS one-step position residual of the prediction model per robot [m], from calibration
        self.position_residual: NDArray[np.float64] | None = None
        self._problem: Problem | None = None
        self._key: tuple | None = None
        self._model_step: tuple[Any, tuple[ca.Function, NDArray, Any]] | None = None
        self._warm: dict[str, NDArray] | None = None
        self._fallback: NDArray | None = None
        self._fallback_used = 0
        self._failed = False
        #: (commands (T, N, 2), predicted poses (T, N, 3)) of the last successful solve
        self.last_plan: tuple[NDArray, NDArray] | None = None

    # ------------------------------------------------------------------ setup
    @property
    def problem(self) -> Problem | None:
        """The built problem (None before the first reset)."""
        return self._problem

    def share_problem(self, other: NMPCController) -> None:
        """Use ``other``'s built problem (and its model, unless this controller has its own):
        controllers of one problem structure then build and compile it once."""
        if self.model is None or self.model is other.model:
            self.model, self._model_step = other.model, other._model_step
        self._problem, self._key = other._problem, other._key
        self._mover_slots = other._mover_slots
        self._obstacle_slots = other._obstacle_slots

    def restart(self) -> None:
        """Start the next solve cold (from :meth:`_initial_guess`), not from the shifted plan."""
        self._warm = None

    def _model_for(self, scenario: Scenario) -> PredictionModel:
        if self.model is None:
            raise ValueError(f"{self.name}: no prediction model was given")
        return self.model

    def _problem_key(self, scenario: Scenario, structure: Any) -> tuple:
        """What the built problem depends on: one problem serves every scenario with this key."""
        return (
            structure,
            scenario.n_robots,
            # with obstacle slots one problem serves any obstacle count
            0 if self._obstacle_slots else scenario.obstacles.shape[0],
            scenario.task,
            tuple(scenario.robot_radius),
            scenario.workspace,
            scenario.v_max,
            scenario.omega_max,
            self.neighbour_slots,
            self._mover_slots,
        )

    def _movers_constrained(self, scenario: Scenario) -> int:
        """Mover slots of this scenario's problem: ``mover_slots``, at most the movers (tracked
        exactly under state sensing, by the perception front through the lidar)."""
        if scenario.n_movers == 0:
            return 0
        return min(self.config.mover_slots, scenario.n_movers)

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
        self._mover_slots = self._movers_constrained(scenario)
        # with the map unknown the lidar shows the obstacles a few at a time: slots, refilled
        # every period from what it has shown (obstacles_seen)
        self._obstacle_slots = self.config.obstacle_slots or (
            0 if scenario.map_known else PERCEIVED_OBSTACLE_SLOTS
        )
        key = self._problem_key(scenario, structure)
        if key != self._key:
            self._problem = Problem(
                model,
                scenario,
                self.config.with_options(obstacle_slots=self._obstacle_slots),
                step,
                terminal_slack=self.config.solver == "rti",
                neighbour_slots=self.neighbour_slots + self._mover_slots,
            )
            self._key = key
        assert self._problem is not None  # built above
        self._fill_parameters(scenario, theta_values)
        self._warm = None
        self._fallback = None
        self._fallback_used = 0
        self._failed = False
        self._settled = np.zeros(scenario.n_robots, dtype=bool)
        # a model with memory predicts from the commands the robots were sent: none yet (at rest)
        self._sent = np.zeros((coding_memory(self._problem.coding), scenario.n_robots, 2))
        # a model with velocity predicts from the poses measured a period before: none yet (standing)
        self._before: NDArray | None = None
        self._pursue: NDArray | None = None
        margin = max(self.config.obstacle_offset, self.config.robot_offset)
        unstall = self.config.unstall and self.resolves_stalls
        self._resolver = DeadlockResolver.for_scenario(scenario, margin) if unstall else None
        self.last_plan = None
        self._stats.solver = self.solver_label

    def obstacles_seen(self, obstacles: NDArray[np.float64]) -> bool:
        """The perceived obstacles (map unknown) fill the obstacle slots and the stall detours."""
        changed = super().obstacles_seen(obstacles)
        assert self.scenario is not None  # set by the base
        self._scenario_obstacles = self.scenario.obstacles
        if self._resolver is not None:
            self._resolver.obstacles = self.scenario.obstacles
        return changed

    def _fill_parameters(self, scenario: Scenario, theta_values: NDArray) -> None:
        """The episode's parameter values: goals, obstacles, margins, parked slots, model coefficients.

        Margins and model coefficients may change during an episode (:meth:`set_margins`,
        :meth:`set_model_parameters`), slots and goals every period.
        """
        assert self._problem is not None  # built by _reset
        layout = self._problem.layout
        obstacle_margin, pair_margin = self.safety_margins(scenario)
        self._scenario_obstacles = np.asarray(scenario.obstacles, dtype=float).reshape(-1, 3)
        self._pair_slots = PairSlots(
            self.config.pair_slots,
            scenario.n_robots,
            scenario.robot_radius,
            closing_distance(scenario.v_max, self.config.horizon, scenario.dt),
        )
        params = layout.zeros()
        params[layout["goal_xy"]] = scenario.targets[:, :2].reshape(-1)
        params[layout["goal_cs"]] = np.column_stack(
            [np.cos(scenario.targets[:, 2]), np.sin(scenario.targets[:, 2])]
        ).reshape(-1)
        params[layout["obstacles"]] = (
            nearest_obstacle_slots(scenario.starts[:, :2], self._scenario_obstacles, self._obstacle_slots)
            if self._obstacle_slots
            else scenario.obstacles.reshape(-1)
        )
        params[layout["obstacle_margin"]] = obstacle_margin
        params[layout["pair_margin"]] = pair_margin
        # moving-disc slots (team-mates, then movers) start parked (see set_neighbours,
        # set_movers), pair slots too (see PairSlots)
        slots = self.neighbour_slots + self._mover_slots
        self._moving_xy = np.full((self.config.horizon, slots, 2), PARKED)
        self._moving_reach = np.zeros(slots)
        params[layout["neighbour_xy"]] = PARKED
        params[layout["neighbour_reach"]] = 0.0
        pair = layout["pair_select"].start, layout["pair_reach"].stop
        params[pair[0] : pair[1]] = self._pair_slots.parked()
        params[layout["model"]] = theta_values
        self._params = params

    @property
    def solver_label(self) -> str:
        """The optimizer as reports name it: ``"rti/<qp solver>"`` or the ``nlpsol`` plugin."""
        config = self.config
        return f"rti/{config.qp_solver}" if config.solver == "rti" else config.solver

    def _fill_slots(self, positions: NDArray, pair_tightening: NDArray | None = None) -> None:
        """Refresh the obstacle slots and the pair slots from the robots' current positions (the
        pair margins widened by ``pair_tightening``, one per pair i < j, when given)."""
        if self._obstacle_slots:
            self._params[self._block("obstacles")] = nearest_obstacle_slots(
                positions, self._scenario_obstacles, self._obstacle_slots
            )
        if not self.config.pair_slots:
            return
        margins = self._params[self._block("pair_margin")]
        if pair_tightening is not None:
            margins = margins + pair_tightening
        values, dropped = self._pair_slots.assign(positions, margins)
        if dropped:
            self._stats.counts["pairs_dropped"] += dropped
        self._params[self._block("pair_select").start : self._block("pair_reach").stop] = values

    def _fill_movers(self, points: NDArray, movers: NDArray, radii: NDArray) -> None:
        """The movers nearest to ``points`` (N, 2), predicted over the horizon, into the mover
        slots, each with its radius (C,) and the margin."""
        scenario = self.scenario
        assert scenario is not None  # act() checked it
        positions, reach = mover_slots(
            points,
            movers,
            self._mover_slots,
            self.config.horizon,
            scenario.dt,
            self.config.mover_prediction,
            radii + self.config.mover_offset,
        )
        self.set_movers(positions, reach)

    def safety_margins(self, scenario: Scenario) -> tuple[NDArray, NDArray]:
        """Margins added to the radii: per robot toward obstacles (N,), per robot pair (i < j).

        ``obstacle_offset`` and ``robot_offset``, widened to ``uncertainty_margin`` times the
        prediction model's calibrated residual when that is larger.
        """
        n = scenario.n_robots
        margin_spread(self.name, self.config.uncertainty_margin, self.position_residual, n)  # checks it
        return self.margins_for(n, self.position_residual)

    def margins_for(self, n_robots: int, residual: NDArray | None) -> tuple[NDArray, NDArray]:
        """:meth:`safety_margins` for a given per-robot RMS position residual [m] (None: offsets only)."""
        config = self.config
        return offset_margins(
            n_robots, config.obstacle_offset, config.robot_offset, config.uncertainty_margin, residual
        )

    # -------------------------------------------------------------------- act
    def _initial_guess(self, state: NDArray) -> NDArray:
        """Hold the current state with zero commands (the first step of an episode)."""
        prob = self._problem
        assert prob is not None  # built by _reset, which act() requires
        w = np.zeros(prob.n_vars)
        w[prob.x_index] = np.tile(state, prob.horizon)
        w[: prob.nx] = state
        return w

    def _pursuit_guess(self, state: NDArray, goals: NDArray) -> NDArray:
        """A cold start that already moves toward ``goals`` (N, 2) (:func:`pursuit_rollout`): a
        plan that holds still has no gradient in the heading, so a robot stopped facing an
        obstacle or a team-mate would never turn away from it from :meth:`_initial_guess`."""
        prob, scenario = self._problem, self.scenario
        assert prob is not None and scenario is not None  # built by _reset
        commands, poses = pursuit_rollout(
            decode_state(state, prob.coding).reshape(-1, 3), goals, prob.horizon, scenario
        )
        w = np.zeros(prob.n_vars)
        w[: prob.nx] = state
        w[prob.u_index] = commands.ravel()
        states, sent, before = [], self._sent, decode_state(state, prob.coding).reshape(-1, 3)
        for command, pose in zip(commands, poses):
            sent = shift_memory(sent, command)  # a model with memory: stage t + 1 remembers u_t
            states.append(encode_state(pose, prob.coding, sent, before))  # ... and the pose of t
            before = pose
        w[prob.x_index] = np.concatenate(states)
        return w

    def _act(self, observation: NDArray, observed: Observed) -> NDArray[np.float64]:
        command = self._decide(observation, observed)
        assert self._problem is not None  # built by _reset, which act() requires
        if coding_velocity(self._problem.coding):
            self._before = np.array(observed.observed_poses, dtype=np.float64)
        if self._sent.shape[0]:
            # the commands the robots were sent, as the env applies them (saturated to the limits)
            scenario = self.scenario
            assert scenario is not None  # act() checked it
            limits = np.array([scenario.v_max, scenario.omega_max])
            self._sent = shift_memory(self._sent, np.clip(command.reshape(-1, 2), -limits, limits))
        return command

    def _decide(self, observation: NDArray, observed: Observed) -> NDArray[np.float64]:
        """This period's command (N * 2) from the solve (or the fallback on a failure)."""
        prob = self._problem
        assert prob is not None  # built by _reset, which act() requires
        poses = observed.observed_poses
        state = encode_state(poses, prob.coding, self._sent, self._before)
        assert self.scenario is not None  # act() checked it
        # an estimator in front hands on its covariance: chance-constrained margins (none without)
        covariance = observed.pose_covariance
        tightened = None if self.config.ablate == "tightening" else covariance
        per_robot, per_pair = chance_tightening(tightened, self.config.chance_risk, self.scenario.n_robots)
        if self._obstacle_slots or self.config.pair_slots:
            self._fill_slots(poses[:, :2], per_pair)
        if self._mover_slots:
            self._fill_movers(
                poses[:, :2],
                observed_movers(observed),
                observed_mover_radii(observed, self.scenario.mover_radius),
            )
        if self._resolver is not None:
            self._unstall(poses)
        params = self._params.copy()
        params[prob.layout["x_meas"]] = state
        if tightened is not None:
            self._tighten(params, per_robot, per_pair)
        cold = self._warm is None
        if self._warm is None:  # cold
            guess = {
                "x0": self._pursuit_guess(state, self._pursue)
                if self._pursue is not None
                else self._initial_guess(state),
                "lam_x0": np.zeros(prob.n_vars),
                "lam_g0": np.zeros(prob.n_cons),
            }
        else:
            guess = {"x0": self._warm["x"], "lam_x0": self._warm["lam_x"], "lam_g0": self._warm["lam_g"]}
        start = time.perf_counter()
        outcome = self._solve(params, guess, cold)
        self._stats.solve_times.append(time.perf_counter() - start)
        self._stats.iterations.append(outcome.iterations)  # QPs, plus IPOPT's iterations on a fallback
        self._stats.statuses[outcome.status] += 1
        if outcome.success:
            # a successful outcome carries its plan and multipliers (_solve_rti, _solve_nlp)
            assert outcome.w is not None and outcome.lam_x is not None and outcome.lam_g is not None
            commands, poses = prob.plan(outcome.w)
            self.last_plan = (commands, poses)
            self._failed = False
            self._warm = prob.shift(
                outcome.w, outcome.lam_x, outcome.lam_g, self._params[prob.layout["model"]]
            )
            self._fallback = commands
            self._fallback_used = 0
            return (
                self._settle(commands[0].copy(), observed)
                if covariance is not None and self.config.ablate != "settling"
                else commands[0].reshape(-1).copy()
            )
        self._stats.failures += 1
        self._failed = True
        self._warm = None  # a failed iterate is a poor starting point: restart cold next step
        return self._fallback_command()

    def _unstall(self, poses: NDArray) -> None:
        """This period's goals from :class:`~controllers.mpc.detour.DeadlockResolver` (the
        targets unless a robot stalled); a stall restarts the solver from a pursuit rollout."""
        scenario, resolver = self.scenario, self._resolver
        assert scenario is not None and resolver is not None  # act() checked; _reset built it
        goals, started = resolver.goals(poses, scenario.targets, scenario.goal_tolerance)
        self._params[self._block("goal_xy")] = goals.reshape(-1)
        self._pursue = goals if started else None
        for kind in started:
            self._warm = None
            self._stats.counts[f"unstall_{kind}"] += 1

    def _tighten(self, params: NDArray, per_robot: NDArray, per_pair: NDArray) -> None:
        """Widen this solve's collision margins (``params``, a copy) by :func:`chance_tightening`'s
        amounts (the pair slots took theirs in :meth:`_fill_slots`)."""
        prob = self._problem
        assert prob is not None  # built by _reset, which act() requires
        params[prob.layout["obstacle_margin"]] += per_robot
        params[prob.layout["pair_margin"]] += per_pair
        if self._mover_slots:  # a mover slot serves the whole team: the least certain robot's margin
            reach = prob.layout["neighbour_reach"]
            movers = slice(reach.start + self.neighbour_slots, reach.stop)
            params[movers] += per_robot.max() * (params[movers] > 0)
        self._stats.counts["tightened"] += 1

    def _settle(self, command: NDArray, observed: Observed) -> NDArray[np.float64]:
        """``command`` (N, 2) with the robots that have settled held still (``settle_fraction``):
        a robot settles when its estimate comes within that fraction of the goal tolerance of its
        target, and moves again when its estimate is farther than :data:`SETTLE_RELEASE` of it."""
        scenario = self.scenario
        assert scenario is not None  # act() checked it
        fraction = self.config.settle_fraction
        if fraction > 0:
            poses = observed.observed_poses
            distance = np.hypot(*(poses[:, :2] - scenario.targets[:, :2]).T)
            tolerance = scenario.goal_tolerance
            # released at 3/4 of the tolerance: the truth may lie a localization error beyond the
            # estimate, and a robot held just inside the tolerance would often be just outside it
            self._settled = (distance <= fraction * tolerance) | (
                self._settled & (distance <= SETTLE_RELEASE * tolerance)
            )
            command[self._settled] = 0.0
            self._stats.counts["settled_periods"] += int(self._settled.sum())
        return command.reshape(-1)

    def _solve(self, params: NDArray, guess: dict[str, NDArray], cold: bool) -> SolveOutcome:
        """The main solver, then the fallback solver on failure (both counted in the status)."""
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
        return outcome

    def solve_failed(self) -> bool:
        """Whether the last period's solve failed (its command came from the plan fallback;
        :attr:`last_plan` is then the last successful one's)."""
        return self._failed

    def _solve_rti(self, params: NDArray, guess: dict[str, NDArray]) -> SolveOutcome:
        """The real-time iteration (:func:`~controllers.mpc.solve.solve_rti`); after a stall,
        :data:`RESTART_ITERATIONS` SQP steps from the pursuit rollout, far from any optimum."""
        assert self._problem is not None  # built by _reset, which act() requires
        more = {"iterations": RESTART_ITERATIONS} if self._pursue is not None else {}
        outcome = solve_rti(self._problem, self.config, params, guess, **more)
        if outcome.status == "rti_large_slack":
            self._stats.counts["large_slack_accepted"] += 1
        return outcome

    def _solve_nlp(self, name: str, params: NDArray, guess: dict[str, NDArray], cold: bool) -> SolveOutcome:
        """One ``nlpsol`` call of plugin ``name`` to convergence (:func:`~controllers.mpc.solve.solve_nlp`)."""
        assert self._problem is not None  # built by _reset, which act() requires
        return solve_nlp(self._problem, name, params, guess, cold)

    def _fallback_command(self) -> NDArray[np.float64]:
        """Next command of the last successful plan, or a stop when that plan is used up."""
        assert self.scenario is not None  # act() checked it
        n = self.scenario.n_robots
        self._fallback_used += 1
        if self._fallback is not None and self._fallback_used < self._fallback.shape[0]:
            return self._fallback[self._fallback_used].reshape(-1).copy()
        return np.zeros(2 * n)
