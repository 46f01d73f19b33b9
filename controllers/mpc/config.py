"""The NMPC's options: :class:`NMPCConfig`, the solver option tables and their checks.

Everything a user sets on an NMPC (central or distributed) is a field of :class:`NMPCConfig`;
:meth:`NMPCConfig.validate` checks them all before any problem is built.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from controllers.estimation import ABLATIONS, ESTIMATORS, check_estimator
from controllers.movers import MOVER_PREDICTIONS, check_mover_prediction
from controllers.mpc.rti import check_rti_options
from controllers.solvers.compiled import jit_options
from controllers.tuning.search_space import Search
from koopman_envs.checks import Range, check_choice, did_you_mean
from koopman_envs.params import LIMITS, PARAMS

__all__ = [
    "DEFAULT_SOLVER_OPTIONS",
    "FATROP_OPTIONS",
    "IPOPT_OPTIONS",
    "JIT_ENV",
    "NLP_SOLVERS",
    "NMPC_RANGES",
    "NMPC_TUNABLE",
    "NMPCConfig",
    "PARKED",
    "ROBUST_UNCERTAINTY_MARGIN",
    "SOLVERS",
    "WARM_START_OPTIONS",
    "check_solver_options",
]

#: residuals, i.e. a prediction error that large is three standard deviations out for Gaussian errors.
ROBUST_UNCERTAINTY_MARGIN = 3.0

#: The allowed range of every numeric NMPC option (ours), checked by :meth:`NMPCConfig.validate`
#: and, before anything is built, by the evaluator's option check (:mod:`controllers.option_spec`).
#: Each is far beyond real use and bounded so that a typo is refused by name instead of building
#: a problem that exhausts the memory (``horizon=100000000`` died after 101 s in std::bad_alloc).
NMPC_RANGES: dict[str, Range] = {
    # 20 s of look-ahead at T_s = 0.1 s, ten times the paper's; the NLP grows linearly with it
    "horizon": Range(1, 200, integer=True, note="control periods"),
    # weights of the tracking cost, per entry; their ratios matter, not their scale
    "q_leader": Range(0, 1e6, note="per entry"),
    "q_follower": Range(0, 1e6, note="per entry"),
    "r_input": Range(0, 1e6, note="per entry"),
    # margins [m]: a metre of margin already closes every corridor of the built-in maps
    "obstacle_offset": Range(0, 1, note="m"),
    "robot_offset": Range(0, 1, note="m"),
    "mover_offset": Range(0, 1, note="m"),
    # standard deviations of the residual: ten is no longer a confidence margin
    "uncertainty_margin": Range(0, 10, note="standard deviations"),
    "formation_bound": Range(0, 10, note="m"),
    "slack_penalty": Range(0, 1e9, low_open=True),
    "rti_iterations": Range(1, 100, integer=True, note="QPs per period"),
    "slack_tolerance": Range(0, 10, low_open=True, note="m"),
    # constraint slots: the sizes the environments allow (koopman_envs.params.LIMITS)
    "pair_slots": Range(0, LIMITS.robots, integer=True, note="0: every pair"),
    "obstacle_slots": Range(0, LIMITS.obstacle_obs, integer=True, note="0: every obstacle"),
    "mover_slots": Range(0, LIMITS.movers, integer=True),
    # at 0.5 and above the chance quantile z <= 0 adds no margin
    "chance_risk": Range(0, 0.5, low_open=True, high_open=True, note="a probability"),
    "settle_fraction": Range(0, 1),
    "cbf_gamma": Range(0, 1, low_open=True, note="or None (null) for distance constraints"),
}

#: What the tuner (:mod:`evaluation.tune`) searches for the central NMPCs (ours), six options a
#: control engineer turns on a receding-horizon planner, each inside :data:`NMPC_RANGES`:
#:
#: - ``horizon``: how far ahead the plan sees (a longer horizon sees round an obstacle sooner and
#:   costs more per period); 10-40 periods is 1-4 s at T_s = 0.1 s, around the paper's 20;
#: - ``r_input``: the input weight against the fixed tracking weights (their ratio sets how
#:   aggressively the plan drives; one scale for v and omega, log-uniform over two decades);
#: - ``obstacle_offset`` and ``robot_offset``: the margins, which trade clearance for room in
#:   narrow passages (0-10 cm; the paper's 1.5 cm is inside);
#: - ``uncertainty_margin``: the margins widened by the model's calibrated residual (0 is the
#:   paper's, 3 the robust presets');
#: - ``unstall``: the stall resolution on or off (its waypoints are fixed constants of
#:   :mod:`controllers.mpc.detour`, not options).
#:
#: The tracking weights ``q_*`` stay the paper's: only the input-to-tracking ratio matters, and
#: ``r_input`` sets it. Solver choices are not tuned: they change the compute, not the problem.
NMPC_TUNABLE: dict[str, Search] = {
    "horizon": Search(10, 40, integer=True),
    "r_input": Search(0.01, 1.0, log=True, entries=2),
    "obstacle_offset": Search(0.0, 0.1),
    "robot_offset": Search(0.0, 0.1),
    "uncertainty_margin": Search(0.0, 4.0),
    "unstall": Search(choices=(True, False)),
}

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

#: obstacle slots of an NMPC whose map is unknown (``lidar.map_known=False``) and whose
#: ``obstacle_slots`` is 0: the perceived obstacles nearest each robot, refilled every period
#: (four: the most any robot of the paper's maps has within its horizon's reach)
PERCEIVED_OBSTACLE_SLOTS = 4

DEFAULT_SOLVER_OPTIONS: dict[str, dict[str, Any]] = {"ipopt": IPOPT_OPTIONS, "fatrop": FATROP_OPTIONS}

#: the ``nlpsol`` plugins an NMPC solves to convergence (and the real-time iteration's rescue)
NLP_SOLVERS = ("ipopt", "fatrop")
#: NMPC solvers: the real-time iteration and the ``nlpsol`` plugins solved to convergence
SOLVERS = ("rti", *NLP_SOLVERS)

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
        ``"rti"`` (default): the real-time iteration (:mod:`controllers.mpc.rti`): one
        structured QP per control period from the previous plan shifted by one step
        (``rti_iterations`` QPs), no compiler; with the stall resolution (``unstall``) it solves
        Map 2's crossing where it used to deadlock. Or a CasADi ``nlpsol`` plugin solved to convergence at every period:
        ``"ipopt"`` (the paper's, and the ``--paper`` protocol's) or ``"fatrop"`` (the structure-exploiting interior-point
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
        fallback (ignored when it equals ``solver``). None (default): no rescue, for a
        controller that keeps its period; a real-time-iteration plan with a large slack is then used as it is
        (counted as ``large_slack_accepted``) and a failed QP goes to the plan fallback. Under
        pose noise the rescue runs on up to one period in three and takes 0.3-2 s at 3 robots,
        and on the robustness sweep it did not raise success (docs/controllers.md).
    qp_solver : str
        QP solver of the real-time iteration, one of :data:`controllers.mpc.rti.QP_SOLVERS`
        (``"hpipm"``: structure-exploiting interior point).
    rti_iterations : int
        QPs per control period of the real-time iteration (>= 1).
    hessian : str
        QP Hessian of the real-time iteration: ``"exact"`` (the Lagrangian's, made convex
        stage by stage) or ``"gauss-newton"`` (see :data:`controllers.mpc.rti.HESSIANS`).
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
    mover_slots : int
        (ours) Moving obstacles (``movers`` keyword) the NMPC constrains: the K nearest to the
        team (to the robot, distributed), refreshed before every solve, each a disc whose centre
        moves over the horizon as ``mover_prediction`` says (time-varying obstacle slots). 0:
        movers are ignored. Only a problem of an env with movers has these rows.
    mover_prediction : str
        (ours) ``"constant_velocity"`` (default: the observed velocity held over the horizon) or
        ``"static"`` (prediction off: each mover stays where it is seen);
        :mod:`controllers.movers`.
    mover_offset : float
        (ours) Margin added to the radii toward a mover [m] (default: the paper's obstacle
        offset, 0.015 m, whatever ``obstacle_offset`` is set to: a tuned preset that widens the
        obstacle margin leaves this one as it is).
    chance_risk : float
        (ours) Risk level of the chance constraints, in (0, 0.5): when an estimator in front
        (``ekf:``) hands on its pose covariance (``Observed.pose_covariance``), every collision
        margin is widened by z sigma, z the standard normal quantile of 1 - ``chance_risk``
        (1.645 at the default 0.05) and sigma the position standard deviation along the worst
        direction (the 2x2 block's largest eigenvalue, rooted): toward obstacles and movers
        sigma_i, between robots sqrt(sigma_i^2 + sigma_j^2). The probability that the true
        position is past a planned margin along any one separating direction is then at most
        ``chance_risk``. Without a covariance (no estimator, or none of the uncertainty it
        models) the margins are the paper's, bit for bit.
    estimator : str
        (ours) What stands between the robots' localization and the planner, one of
        :data:`controllers.estimation.ESTIMATORS`: ``"auto"`` (default) the front-end a deployed MPC has
        (:class:`controllers.estimation.PoseFrontEnd` with everything identified online: the
        actuation delay compensated, the localization noise filtered, its covariance in the
        margins); on a team without localization error or delay it identifies none and is a
        no-op, bit for bit. ``"realistic"``: the same front-end told the ``realistic`` preset's
        delay and noise (a datasheet) instead of identifying them, held whatever the team has
        (the mis-specified case). ``"none"``: no front-end, as in the paper, planning from every
        measured pose as if it were exact.
    ablate : str
        (ours) One lever of the estimator and its margins switched off, for the ablation
        (:data:`controllers.estimation.LEVERS`): ``"estimation"`` (no filter: the measured poses
        with the measurement noise as their covariance), ``"delay_compensation"``,
        ``"tightening"`` (the chance constraints) or ``"settling"``; ``"none"`` (default) keeps
        every lever on.
    settle_fraction : float
        (ours) With an estimator's covariance handed on, a robot whose estimated position comes
        within ``settle_fraction`` times the goal tolerance of its target holds still (zero
        command) until its estimate is farther than 3/4 of the tolerance
        (:data:`controllers.mpc.controller.SETTLE_RELEASE`): near the goal, where the localization
        noise is as large as the remaining error, the NMPC would otherwise chase the noise and
        never settle. 0 turns it off; without a covariance it never acts (the paper's behaviour).
    cbf_gamma : float or None
        (ours; Zeng, Zhang and Sreenath 2021) None (default): the collision constraints are
        distance constraints on the predicted states, h(x_k) >= 0 for k = 1..T (the paper's).
        gamma in (0, 1]: discrete-time control barrier function constraints instead,
        h(x_k+1) >= (1 - gamma) h(x_k) for k = 0..T-1 (:func:`controllers.mpc.problem.barrier_rows`),
        h the squared clearance of every obstacle, team-mate and mover row with its margin: a
        clearance may shrink by at most the fraction gamma per period, so the plan slows before
        an obstacle instead of skimming its margin. Smaller is more cautious; 1 is the distance
        constraint one step on. The hand-set ``mpc-cbf`` preset (``mpc-cbf-v0``) sets 0.1; ``mpc-cbf``
        runs its tuned rate (controllers/tuned/mpc-cbf.json).
    unstall : bool
        (ours) Resolve a stall of the central NMPC (:class:`controllers.mpc.detour.DeadlockResolver`):
        a robot that has not moved for a second away from its target restarts cold, and, for
        three seconds, gives way to a team-mate it blocks (by a fixed priority) or drives to a
        waypoint beside the obstacle on its straight path. Without a stall it changes nothing,
        bit for bit. The distributed NMPC has its own (detour waypoints, cold restarts).
    jit : bool or None
        Compile the NLP's functions to C (several times faster derivative evaluations). The
        compiled objects are cached on disk (:mod:`controllers.solvers.compiled`), so a problem
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
    solver: str = "rti"
    solver_options: dict[str, Any] | None = None
    fallback_solver: str | None = None
    qp_solver: str = "hpipm"
    rti_iterations: int = 1
    hessian: str = "exact"
    slack_tolerance: float = 1e-2
    pair_slots: int = 0
    obstacle_slots: int = 0
    mover_slots: int = 4
    mover_prediction: str = "constant_velocity"
    mover_offset: float = PARAMS.obstacle_offset
    chance_risk: float = 0.05
    estimator: str = "auto"
    ablate: str = "none"
    settle_fraction: float = 0.5
    cbf_gamma: float | None = None
    unstall: bool = True
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
            # compiled once per machine (controllers.solvers.compiled); {} without a C compiler. The
            # fallback solver runs rarely: compiling it (minutes for a large NLP) would stall the
            # first episode that needs it
            for key, value in jit_options(background=True).items():
                options.setdefault(key, value)
        return options

    def with_options(self, owner: str = "NMPC", /, **changes: Any) -> NMPCConfig:
        """A validated copy with some fields changed: the one option merge of every NMPC
        (central and distributed).

        Parameters
        ----------
        owner : str
            The controller's class name, for the error message.
        **changes
            Field names and their new values.

        Raises
        ------
        ValueError
            An unknown field (with did-you-mean, naming ``owner``) or a bad value
            (:meth:`validate`).
        """
        allowed = [f.name for f in fields(self)]
        for name in changes:
            if name not in allowed:
                raise ValueError(
                    f"{owner}: unknown option {name!r}{did_you_mean(name, allowed)}; options: {sorted(allowed)}"
                )
        config = replace(self, **changes) if changes else self
        config.validate()
        return config

    @staticmethod
    def option_choices() -> dict[str, tuple[str, ...]]:
        """The allowed values of the text options (for :mod:`controllers.option_spec`)."""
        from controllers.mpc.rti import HESSIANS, QP_SOLVERS

        return {
            "solver": SOLVERS,
            "fallback_solver": NLP_SOLVERS,
            "qp_solver": tuple(sorted(QP_SOLVERS)),
            "hessian": HESSIANS,
            "mover_prediction": MOVER_PREDICTIONS,
            "estimator": ESTIMATORS,
            "ablate": ABLATIONS,
        }

    def validate(self) -> None:
        """Raise ``ValueError`` naming a bad option and what is allowed (before any problem is
        built): every numeric option within :data:`NMPC_RANGES` (each entry of a weight tuple),
        the flags, and the text options' choices."""
        for name, allowed in NMPC_RANGES.items():
            value = getattr(self, name)
            if value is None and name == "cbf_gamma":
                continue  # distance constraints
            if name in ("q_leader", "q_follower", "r_input"):
                if isinstance(value, (str, bytes)) or not isinstance(value, (tuple, list, np.ndarray)):
                    raise ValueError(f"{name}={value!r} must be a list of numbers, each in {allowed}")
                for i, entry in enumerate(value):
                    allowed.check(f"{name}[{i}]", entry)
            else:
                allowed.check(name, value)
        if not isinstance(self.unstall, (bool, np.bool_)):
            raise ValueError(f"unstall={self.unstall!r} must be True or False")
        if not isinstance(self.soft_constraints, (bool, np.bool_)):
            raise ValueError(f"soft_constraints={self.soft_constraints!r} must be True or False")
        if self.jit is not None and not isinstance(self.jit, (bool, np.bool_)):
            raise ValueError(f"jit={self.jit!r} must be True, False or None")
        if self.solver_options is not None and not isinstance(self.solver_options, dict):
            raise ValueError(
                f"solver_options={self.solver_options!r} must be a dict of solver options or None"
            )
        check_estimator(self.estimator, self.ablate)
        check_mover_prediction(self.mover_prediction)
        check_solver_options(self)


def check_solver_options(config: NMPCConfig) -> None:
    """Raise ``ValueError`` naming a bad solver option of ``config`` and what is allowed."""
    check_choice("solver", config.solver, SOLVERS)
    if config.fallback_solver is not None:
        check_choice("fallback_solver", config.fallback_solver, NLP_SOLVERS, " or None")
    check_rti_options(config.qp_solver, config.rti_iterations, config.hessian)
