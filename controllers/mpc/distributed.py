"""Distributed NMPC: every robot solves its own small NMPC, the others' plans as moving obstacles.

The central NMPC (:mod:`controllers.mpc.controller`) optimizes the whole team at once: every pair of robots
is a constraint at every stage, and its cost grows with N^2 rows and an N-robot KKT system. Here
each robot optimizes only its own commands over the horizon, with

- its own prediction model block (the slip-free unicycle of one robot),
- its own goal (its target; a formation follower's target is the leader's target plus its
  offset, as the env defines it),
- the K nearest obstacles (fewer: the rest of the slots parked far away),
- K *neighbour slots*: the robots that can come within reach over the horizon (centre distance
  below ``2 v_max T dt`` plus both radii and the margins), each as a disc that moves along that
  robot's latest predicted plan; unused slots are parked far away, so their rows never bind.

One problem is built per structure (horizon, slots, radius, limits) and serves every robot and
every step: its parameters carry the robot's state, goal, obstacles and neighbour plans.

Coordination (``coordination=``):

``"sequential"`` (default)
    Gauss-Seidel by priority: within a period, robots solve in index order; robot i sees the
    plans robots 0..i-1 made in this period and the others' plans of the previous period,
    shifted by one step. A neighbour's plan is then at most one period old.
``"jacobi"``
    Every robot solves against the previous period's plans of all others (shifted by one step;
    the solves are independent and could run in parallel). The one-period delay is covered by
    widening every neighbour's disc by ``v_max dt`` (how far a robot can deviate from its plan
    in one period).

Each robot's problem is solved as the central NMPC's is (``solver``: the real-time iteration by
default, ``fallback_solver`` (IPOPT, or none) on failure, then the rest of the robot's last plan,
then a stop), and every
fallback is counted in :meth:`stats`. A robot without a plan yet (the first period, or after a
failure) is predicted to hold its position.

Formation (``formation_goal=``): ``"leader-plan"`` (default), a follower's goal in each period
is the end of the leader's latest predicted plan plus its offset, so it tracks the leader on the
way; ``"target"``, it drives to its formation target (the leader's target plus its offset) and
only keeps clear of the leader's plan. On the paper protocol's formation cells (60 paired
episodes) both succeed equally often (68% vs 67%), and tracking the plan cuts the formation
RMS error from 0.71 to 0.54 m (paired mean -0.17 m [-0.26, -0.07]), with 9 solver failures
(recovered by the plan fallback) against none. What is not distributed:
the central NMPC's relative-motion rows, which bound how fast a follower's offset to the leader
may change.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from controllers.base import BaseController, ControllerStats
from controllers.estimation import front_end_for
from controllers.koopman.dictionary import DICTIONARIES
from controllers.koopman.model import KoopmanModel
from controllers.koopman.store import calibrated_model
from controllers.mpc.config import PARKED, NMPCConfig
from controllers.mpc.controller import NMPCController
from controllers.mpc.detour import DETOUR_CLEARANCE, StallMonitor, detour_waypoint
from controllers.mpc.margins import chance_tightening, margin_spread
from controllers.mpc.models import PredictionModel, UnicycleModel
from controllers.mpc.plan_exchange import PlanLog
from controllers.mpc.slots import closing_distance, nearest_obstacle_slots
from koopman_envs import CalibrationPlant, Observed, nearest_order
from koopman_envs.checks import Range, check_choice
from koopman_envs.params import LIMITS
from koopman_envs.scenario import Scenario

__all__ = ["COORDINATION", "FORMATION_GOALS", "MODELS", "DistributedNMPC"]

#: coordination schemes (see the module docstring)
COORDINATION = ("sequential", "jacobi")
#: prediction models: the slip-free unicycle, or each robot's block of the per-robot Koopman model
MODELS = ("nominal", "koopman")
#: what a formation follower drives to (see the module docstring)
FORMATION_GOALS = ("target", "leader-plan")


class _RobotNMPC(NMPCController):
    """One robot's NMPC: the central NMPC's solver chain on a one-robot problem with neighbour slots."""

    name = "robot-nmpc"
    resolves_stalls = False
    radio_station = None  # the distributed NMPC hands each robot what it knows

    def __init__(self, config: NMPCConfig, slots: int) -> None:
        super().__init__(None, config)
        self.neighbour_slots = slots
        self.front_end = None  # the team's estimator stands in front of the distributed NMPC

    #: the point the robot drives to in this period (its target or a detour waypoint)
    goal: NDArray[np.float64] | None = None

    def _initial_guess(self, state: NDArray) -> NDArray:
        """A cold start that already moves toward the robot's goal (:meth:`_pursuit_guess`)."""
        if self.goal is None:
            return super()._initial_guess(state)
        return self._pursuit_guess(state, self.goal[None])

    def _model_for(self, scenario: Scenario) -> PredictionModel:
        if self.model is None:  # the nominal variant; the Koopman one is handed its robot's block
            self.model = UnicycleModel(1, scenario.dt)
        return self.model


class DistributedNMPC(BaseController):
    """Distributed nominal NMPC (see the module docstring).

    Parameters
    ----------
    neighbours : int
        Neighbour slots K per robot (>= 1): the nearest robots within reach get one each.
    obstacles : int
        Obstacle slots per robot (>= 1): the nearest obstacles (by clearance) get one each.
    reach : float, optional
        Centre distance [m] within which another robot gets a slot (> 0; default
        ``2 v_max T dt`` plus both radii and the margins: every robot that can meet this one
        within the horizon).
    coordination : str
        ``"sequential"`` or ``"jacobi"``.
    model : str
        ``"nominal"`` (the slip-free unicycle) or ``"koopman"`` (each robot's own block of the
        per-robot Koopman model that :meth:`calibrate` fits on the calibration plant).
    dictionary : str
        The Koopman model's dictionary (``"minimal"``: the paper's).
    detour : bool
        Steer around an obstacle that blocks the straight line to the target through a
        waypoint beside it (see :meth:`_waypoint`; ours).
    formation_goal : str
        Formation task: what a follower drives to, one of :data:`FORMATION_GOALS` (see the
        module docstring).
    config : NMPCConfig, optional
        Options of every robot's NMPC; ``**options`` are shorthand for its fields (``horizon``,
        ``solver``, ``robot_offset``, ...). Default solver: the real-time iteration.
    """

    name = "dmpc-nominal"
    #: NMPC options whose default differs from NMPCConfig's (controllers.options reads them too)
    NMPC_DEFAULTS: ClassVar[dict[str, Any]] = {}
    #: allowed values of the text options (controllers.option_spec)
    OPTION_CHOICES: ClassVar[dict[str, tuple[str, ...]]] = {
        "coordination": COORDINATION,
        "formation_goal": FORMATION_GOALS,
        "model": MODELS,
        "dictionary": tuple(DICTIONARIES),
    }
    #: the allowed range of its own numeric options (:mod:`controllers.option_spec`; the NMPC's:
    #: controllers.mpc.config.NMPC_RANGES): the slots the environments allow
    OPTION_RANGES: ClassVar[dict[str, Range]] = {
        "neighbours": Range(1, LIMITS.robots, integer=True),
        "obstacles": Range(1, LIMITS.obstacle_obs, integer=True),
        "reach": Range(0, LIMITS.lidar_range, low_open=True, note="m, or None (null)"),
    }

    def __init__(
        self,
        neighbours: int = 4,
        obstacles: int = 4,
        reach: float | None = None,
        coordination: str = "sequential",
        detour: bool = True,
        formation_goal: str = "leader-plan",
        model: str = "nominal",
        dictionary: str = "minimal",
        config: NMPCConfig | None = None,
        **options: Any,
    ) -> None:
        super().__init__()
        self.neighbours = self.OPTION_RANGES["neighbours"].check("neighbours", neighbours)
        self.obstacle_slots = self.OPTION_RANGES["obstacles"].check("obstacles", obstacles)
        self.reach = None if reach is None else self.OPTION_RANGES["reach"].check("reach", reach)
        check_choice("coordination", coordination, COORDINATION)
        self.coordination = coordination
        check_choice("formation_goal", formation_goal, FORMATION_GOALS)
        self.formation_goal = formation_goal
        self.detour = bool(detour)
        check_choice("model", model, MODELS)
        self.model_kind = model
        self.name = f"dmpc-{model}"
        self.dictionary = dictionary
        self._residual: NDArray[np.float64] | None = None
        self._spread: NDArray[np.float64] = np.zeros(0)
        self._blocks: list[KoopmanModel] = []
        self.config = (config or NMPCConfig(**self.NMPC_DEFAULTS)).with_options(
            type(self).__name__, **options
        )
        self._robot = _RobotNMPC(self.config, self.neighbours)
        self.front_end = front_end_for(self.config.estimator, self.config.ablate)
        self._agents: list[_RobotNMPC] = []
        self._plans: NDArray[np.float64] = np.zeros((0, 0, 2))
        self._per_robot_times: list[float] = []
        self._stats.solver = self._robot.solver_label

    # ------------------------------------------------------------------ setup
    def _robot_scenario(self, scenario: Scenario, i: int) -> Scenario:
        """The one-robot scenario robot ``i``'s problem is built for (obstacle slots parked)."""
        slots = np.tile([PARKED, PARKED, 0.0], (self.obstacle_slots, 1))
        return dataclasses.replace(
            scenario,
            task="target_reaching",  # formation followers drive to their formation targets
            n_robots=1,
            obstacles=slots,
            robot_radius=scenario.robot_radius[i : i + 1].copy(),
            starts=scenario.starts[i : i + 1].copy(),
            targets=scenario.targets[i : i + 1].copy(),
            formation_offsets=np.zeros((1, 2)),
            leader=0,
            # its obstacles are the slots the team fills (perceived ones too): known, by itself
            # it perceives nothing (the team's perception runs once, in front of the team)
            lidar_beams=0,
            map_known=True,
        )

    def calibrate(self, plant: CalibrationPlant, *, seed: int = 0) -> dict[str, Any]:
        """The Koopman variant fits the team's per-robot model on ``plant`` (cached) and gives
        each robot its own block; the nominal variant needs no data."""
        margin = self.config.uncertainty_margin
        if self.model_kind == "nominal":
            if margin == 0:
                self._residual = None
                return {"transitions": 0, "source": "not needed"}
            # the unicycle's residual on the plant's data, as the central nominal NMPC measures it
            from controllers.mpc.variants import NominalNMPC

            measure = NominalNMPC(uncertainty_margin=margin)
            summary = measure.calibrate(plant, seed=seed)
            self._residual = measure.position_residual
            return summary
        model, summary = calibrated_model(plant, seed, self.dictionary, structure="per-robot")
        self._blocks = [model.robot_block(r) for r in range(model.n_robots)]
        residual = model.metadata.get("position_residual")
        self._residual = None if residual is None else np.asarray(residual, dtype=float)
        return {**summary, "structure": "per-robot"}

    def _spreads(self, n: int) -> NDArray[np.float64]:
        """Every robot's margin spread: ``uncertainty_margin`` times its calibrated RMS one-step
        position residual [m] (zeros without the margin)."""
        spread = margin_spread(self.name, self.config.uncertainty_margin, self._residual, n)
        return np.zeros(n) if spread is None else spread

    def _reset(self, scenario: Scenario, seed: int | None) -> None:
        n = scenario.n_robots
        if self.model_kind == "koopman" and len(self._blocks) != n:
            raise ValueError(
                f"{self.name}: no Koopman model for {n} robots; call calibrate(plant) with a plant of this "
                "team first (the evaluator does)"
            )
        self._spread = self._spreads(n)
        self._pair_tightening = np.zeros(n)
        while len(self._agents) < n:
            self._agents.append(_RobotNMPC(self.config, self.neighbours))
        for i in range(n):  # each robot's obstacle margin widens by its own residual
            self._agents[i].position_residual = (
                None if self._residual is None else np.asarray(self._residual[i : i + 1], dtype=float)
            )
        first = self._agents[0]
        if self._blocks:
            first.model = self._blocks[0]
        first.reset(self._robot_scenario(scenario, 0), seed=seed)
        for i in range(1, n):
            agent = self._agents[i]
            # one problem per structure: the first robot's problem serves every robot whose model
            # has the same structure (its own coefficients are parameters); the nominal variant
            # shares the model too
            if self._blocks:
                agent.model = self._blocks[i]
            agent.share_problem(first)
            agent.reset(self._robot_scenario(scenario, i), seed=seed)
        horizon = self.config.horizon
        # every robot's predicted positions at its last solve's stages 1..T; no plan yet: its start
        self._plans = np.repeat(scenario.starts[None, :, :2], horizon, axis=0)
        radius = float(np.max(scenario.robot_radius))
        delay = scenario.v_max * scenario.dt if self.coordination == "jacobi" else 0.0
        self._delay = delay
        self._reach = (
            self.reach
            if self.reach is not None
            else closing_distance(scenario.v_max, horizon, scenario.dt)
            + 2 * radius
            + 2 * max(self.config.robot_offset, 2 * float(np.max(self._spread)))
            + delay
        )
        self._per_robot_times = []
        self._monitor = StallMonitor(n)
        # the plans by period, for team-mates whose messages arrive late (controllers.mpc.plan_exchange)
        self._plan_log = PlanLog(self.config.horizon)
        self._leader_end: NDArray[np.float64] | None = None  # the leader's plan end as robot i heard it
        self._stats.solver = self._robot.solver_label

    def _goal(self, i: int) -> NDArray[np.float64]:
        """Robot ``i``'s goal before any detour: its target, or (``formation_goal="leader-plan"``,
        a follower) the end of the leader's latest plan plus its formation offset."""
        scenario = self.scenario
        assert scenario is not None  # act() checked it
        leader_end = self._leader_end
        if self.formation_goal == "leader-plan" and scenario.is_formation and i != scenario.leader:
            if leader_end is not None:  # nothing heard of the leader yet: the formation target
                return leader_end + scenario.formation_offsets[i]
        return scenario.targets[i, :2]

    def _waypoint(self, i: int, position: NDArray[np.float64]) -> NDArray[np.float64]:
        """Robot ``i``'s goal for this period: its target, or, when the straight line to it runs
        through an obstacle (inflated by the robot's radius and a clearance), a point beside
        that obstacle on the side the line passes (a distance-tracking cost has a local minimum
        behind an obstacle straight ahead; the horizon is too short to see around it)."""
        scenario = self.scenario
        assert scenario is not None  # act() checked it
        target = self._goal(i)
        inflate = scenario.robot_radius[i] + self.config.obstacle_offset + DETOUR_CLEARANCE
        return detour_waypoint(position, target, scenario.obstacles, inflate)

    # -------------------------------------------------------------------- act
    def _plan_heard(
        self, j: int, age: int, fresh: bool, last_known: NDArray[np.float64], count: bool = True
    ) -> NDArray[np.float64]:
        """Robot j's plan as another robot has it (:meth:`PlanLog.heard`), counted in :meth:`stats`."""
        plan, kind = self._plan_log.heard(self._plans, j, age, fresh, last_known)
        if kind and count:
            self._stats.counts[kind] += 1
        return plan

    def _surroundings(
        self, i: int, poses: NDArray[np.float64], ages: NDArray[np.int64], fresh: NDArray[np.bool_]
    ) -> None:
        """Set robot ``i``'s nearest obstacles and neighbour slots for this period's solve from
        what it knows: ``poses`` (N, 3), its own estimate and its last messages of the others,
        ``ages`` (N,) their ages in periods (-1: nothing heard; such a robot gets no slot)."""
        scenario = self.scenario
        assert scenario is not None  # act() checked it
        agent = self._agents[i]
        position = poses[i, :2]
        leader = scenario.leader
        self._leader_end = (
            self._plan_heard(leader, int(ages[leader]), bool(fresh[leader]), poses[leader], count=False)[-1]
            if ages[leader] >= 0
            else None
        )
        # the central NMPC's obstacle slots, for a team of one
        agent.set_obstacles(nearest_obstacle_slots(position[None], scenario.obstacles, self.obstacle_slots))
        agent.goal = self._waypoint(i, position) if self.detour else self._goal(i)
        agent.set_goal(0, agent.goal)
        horizon, k = self.config.horizon, self.neighbours
        positions = np.full((horizon, k, 2), PARKED)
        reach = np.zeros(k)
        distance = np.hypot(*(poses[:, :2] - position).T)
        distance[i] = np.inf
        unheard = ages < 0
        if unheard.any():
            distance[unheard] = np.inf
            self._stats.counts["neighbours_unheard"] += int(unheard.sum())
        candidates = [j for j in nearest_order(distance, distance.size) if distance[j] < self._reach][:k]
        for slot, j in enumerate(candidates):
            # stage s of this solve is step s of the plan as heard (see _plan_heard)
            positions[:, slot] = self._plan_heard(j, int(ages[j]), bool(fresh[j]), poses[j])
            # the central NMPC's pair margin: the offset, widened to both robots' spreads
            margin = max(self.config.robot_offset, self._spread[i] + self._spread[j])
            reach[slot] = scenario.robot_radius[j] + margin + self._delay + self._pair_tightening[i]
        agent.set_neighbours(positions, reach)

    def _act(self, observation: NDArray, observed: Observed) -> NDArray[np.float64]:
        scenario = self.scenario
        assert scenario is not None  # act() checked it
        n = scenario.n_robots
        known = observed.known_poses  # (N, N, 3): robot i's view in row i
        ages = observed.message_age
        poses = observed.observed_poses  # every robot's own estimate
        commands = np.zeros((n, 2))
        fresh = np.zeros(n, dtype=bool)  # whose plan in self._plans was made in this period
        new_plans = self._plans.copy()
        # an estimator in front hands on each robot's covariance: its own NMPC tightens its
        # obstacle and mover margins by it, and each team-mate's disc by z sigma sqrt(2) (a
        # message carries a pose, not its covariance: the team-mate's is taken to be as large)
        covariance = observed.pose_covariance
        tightened = None if self.config.ablate == "tightening" else covariance
        per_robot, _ = chance_tightening(tightened, self.config.chance_risk, n)
        self._pair_tightening = np.sqrt(2.0) * per_robot
        start = time.perf_counter()
        for i in range(n):
            robot_start = time.perf_counter()
            agent = self._agents[i]
            self._surroundings(i, known[i], ages[i], fresh)
            if self._stalled(i, poses[i, :2]):
                agent.restart()
                self._stats.counts["restarts"] += 1
            # the robot's own NMPC: its own pose (and covariance) and the team's movers, which it
            # puts nearest first into its mover slots; it hears no team-mate over its radio
            alone = poses[i : i + 1]
            commands[i] = agent.act(
                observation,
                Observed(
                    observed_poses=alone,
                    known_poses=alone[None],
                    message_age=np.zeros((1, 1), dtype=np.int64),
                    pose_covariance=None if covariance is None else covariance[i : i + 1],
                    observed_movers=observed.observed_movers,
                    mover_tracked=observed.mover_tracked,
                    mover_radii=observed.mover_radii,
                    perceived=observed.perceived,
                ),
            )
            if not agent.solve_failed() and agent.last_plan is not None:
                new_plans[:, i] = agent.last_plan[1][:, 0, :2]
            else:  # no new plan: predicted to hold its position
                new_plans[:, i] = poses[i, :2]
            if self.coordination == "sequential":  # the robots after i see this plan at once
                self._plans[:, i] = new_plans[:, i]
                fresh[i] = True
            self._per_robot_times.append(time.perf_counter() - robot_start)
        self._plans = new_plans
        self._plan_log.record(new_plans)
        self._stats.solve_times.append(time.perf_counter() - start)
        return commands.reshape(-1)

    def _stalled(self, i: int, position: NDArray[np.float64]) -> bool:
        """Robot ``i`` has stalled (:class:`~controllers.mpc.detour.StallMonitor`): its solver
        restarts cold, once per stall."""
        scenario = self.scenario
        assert scenario is not None  # act() checked it
        return self._monitor.stalled(i, position, scenario.targets[i, :2], scenario.goal_tolerance)

    def stats(self) -> ControllerStats:
        """The team's statistics: per-period solve time of all robots together (``robot`` in
        ``extra_times``: one robot's solve), the robots' failures, fallbacks and statuses summed."""
        own = self._stats
        team = ControllerStats(
            solve_times=list(own.solve_times),
            # the robots' solves, and the team's perception (the lidar's, when it runs one)
            extra_times={"robot": list(self._per_robot_times)}
            | {k: v for k, v in own.extra_times.items() if k == "perception"},
            solver=own.solver,
        )
        team.counts.update(own.counts)  # the team's own: restarts, plans aged or replaced, robots unheard
        n = self.scenario.n_robots if self.scenario is not None else 0
        for agent in self._agents[:n]:
            robot = agent.stats()
            team.failures += robot.failures
            team.statuses.update(robot.statuses)
            team.counts.update(robot.counts)
            team.iterations.extend(robot.iterations)
        return team
