"""The batched navigation engine under every front.

It owns K environments of N robots: their poses, maps, targets, slip generators and episode
counters, and advances all of them in compiled batch loops (numba). The Gymnasium env is this
engine with K = 1, the vector env is the engine with K = num_envs, and the PettingZoo env reads per-agent
blocks of the same observation features. Because all fronts run this one code path,
sub-environment i of a batch seeded with s + i reproduces a lone environment seeded s + i.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from koopman_envs.checks import check_commands
from koopman_envs.engine.config import EngineConfig, check_engine_memory, engine_array_bytes
from koopman_envs.engine.episode import engine_scenario, reset_episodes
from koopman_envs.engine.plant import advance_plant, make_physics
from koopman_envs.params import PARAMS
from koopman_envs.scenario import Scenario
from koopman_envs.settings.reset_options import ResetOptions
from koopman_envs.sim.collision import CollisionFault, collision_flags
from koopman_envs.sim.geometry import TeamGeometry
from koopman_envs.sim.maps.map_spec import MapSpec, formation_offsets
from koopman_envs.sim.movers.field import MoverField
from koopman_envs.sim.movers.tracking import MoverTracker, listed_movers, observed_movers
from koopman_envs.sim.perception import Perception, observed_info
from koopman_envs.sim.slip.sampling import SlipSampler
from koopman_envs.sim.slip.schedule import SlipClock
from koopman_envs.sim.slip.zones import ZoneTable
from koopman_envs.sim.starts import START_NOISE_ATTEMPTS
from koopman_envs.tasks.observation import FeatureBuilder
from koopman_envs.tasks.reward import (
    ELAPSED,
    SETTLED,
    SUCCESS,
    TERMINATED,
    TRUNCATED,
    score_rule,
    score_step,
    slot_errors,
)

__all__ = ["START_NOISE_ATTEMPTS", "NavigationEngine", "StepResult", "engine_array_bytes"]


@dataclass
class StepResult:
    """Arrays produced by one batched step (K environments, N robots, F features)."""

    features: NDArray[np.float64]  # (K, N, F)
    robot_reward: NDArray[np.float64]  # (K, N)
    team_reward: NDArray[np.float64]  # (K,)
    reward: NDArray[np.float64]  # (K,): the robots' terms summed, plus the team's
    terminated: NDArray[np.bool_]  # (K,)
    truncated: NDArray[np.bool_]  # (K,)


class NavigationEngine:
    """K navigation environments advanced together.

    The state is kept channel-first, ``state[k] = [x; y; theta]`` of shape (3, N);
    :attr:`poses` gives the familiar (K, N, 3) view. A step is four compiled passes over the
    batch: the plant (:func:`~koopman_envs.engine.plant.advance_plant`: the kinematic
    :func:`~koopman_envs.sim.dynamics.advance_teams`, or MuJoCo's robots), collision flags,
    observation features, and rewards with episode ends (:mod:`koopman_envs.tasks.reward`).
    Maps with slip zones add a fifth before the physics
    (:func:`~koopman_envs.sim.slip.zones.zone_slip_means`: every robot's slip mean where it stands),
    and a slip schedule updates the base levels after the step
    (:class:`~koopman_envs.sim.slip.schedule.SlipClock`); without them neither runs.

    Parameters
    ----------
    config : EngineConfig
        The validated environment definition.
    num_envs : int
        Batch size K.
    """

    def __init__(self, config: EngineConfig, num_envs: int = 1) -> None:
        self.config = config
        self.num_envs = int(num_envs)
        # every keyword is bounded by itself, their product over the batch here, before allocating
        check_engine_memory(config, self.num_envs)
        k, n, m = self.num_envs, config.n_robots, config.n_obstacles
        self.state = np.zeros((k, 3, n))
        self.target = np.zeros((k, 3, n))
        self.offset = np.zeros((k, 2, n))
        #: start poses of the current episodes, (K, N, 3): the map's, perturbed by ``start_noise``
        self.starts = np.zeros((k, n, 3))
        #: the starts a controller is told (:meth:`scenario`): the map's (or the reset options'),
        #: not perturbed; where each robot truly starts it learns from its localization, as a
        #: robot placed by hand does
        self.nominal_starts = np.zeros((k, n, 3))
        self.maps: list[MapSpec | None] = [None] * k
        self.distances = np.zeros((k, n))
        #: the episode counters, rows SETTLED and ELAPSED (read as :attr:`settled`, :attr:`elapsed`)
        self.counters = np.zeros((2, k), dtype=np.int64)
        self.collision = np.zeros(k, dtype=np.int64)
        self.success = np.zeros(k, dtype=bool)
        self.slip = SlipSampler(k, n)
        #: slip zones of every environment, None on maps without zones (then no zone pass runs)
        self.zones = ZoneTable(k, config.n_slip_zones, n) if config.n_slip_zones else None
        self.zone_means = np.zeros((k, n))  # the zone pass's output
        #: the physics plant's worlds (``plant="mujoco"``), None on the kinematic plant
        self.physics = make_physics(config, k)
        #: scheduled base levels, None for a slip level that is constant through an episode
        self.slip_clock = None if config.slip_schedule is None else SlipClock(config.slip_schedule, k, n)
        self.geometry = TeamGeometry(k, config.robot_radius, m)
        #: what the robots believe (noise, radio, lidar, command queue); None when they know the truth
        settings = (config.pose_noise, config.comm, config.lidar, config.actuation_delay)
        self.perception = (
            Perception(k, n, *settings, PARAMS.dt, PARAMS.workspace) if config.perceives else None
        )
        #: the moving obstacles; None without any (then no mover pass runs)
        self.movers = (
            MoverField(k, config.movers, n, PARAMS.dt, PARAMS.workspace) if config.movers.active else None
        )
        #: one robot's observation block by name (the public seam of every policy)
        self.observation_layout = config.observation_layout
        layout = self.observation_layout
        #: the people tracker the movers are observed through (None: exact, or not at all)
        self.mover_tracker = MoverTracker.for_movers(config.movers, k, layout.movers, PARAMS.dt)
        self.builder = FeatureBuilder(
            k,
            layout,
            m,
            lidar_range=0.0 if config.lidar is None else config.lidar.range,
            mover_radius=config.movers.radius,
        )
        self._all_rows = np.arange(k, dtype=np.int64)
        self.feature_size = self.builder.shape[-1]
        self.feature_low, self.feature_high = self.builder.low, self.builder.high
        self.command_low = np.array([-PARAMS.v_max, -PARAMS.omega_max])
        self.command_high = np.array([PARAMS.v_max, PARAMS.omega_max])
        # effort weight per command channel: (1 / v_max^2, 1 / omega_max^2)
        self.effort_scale = 1.0 / self.command_high**2
        self._workspace = np.asarray(PARAMS.workspace, dtype=np.float64)
        self.all_active = np.ones(k, dtype=bool)
        self._no_formation = np.zeros((k, n))
        #: periods every robot must stay within tolerance for success
        self.settle_steps = PARAMS.settle_steps
        self._score_rule = score_rule(
            config.task.reward,
            config.task.formation,
            config.goal_tolerance,
            self.settle_steps,
            config.max_episode_steps,
        )
        if config.map_spec is not None:
            for index in range(k):
                self._set_map(index, config.map_spec)

    def close(self) -> None:
        """Release what the plant holds beyond arrays (the physics plant's thread pool)."""
        if self.physics is not None:
            self.physics.close()

    # ----------------------------------------------------------------- spaces
    def robot_spaces(self) -> tuple[spaces.Box, spaces.Box]:
        """(action, observation) spaces of one robot: (v, omega) and its feature block."""
        action = spaces.Box(
            self.command_low.astype(np.float32), self.command_high.astype(np.float32), dtype=np.float32
        )
        observation = spaces.Box(
            self.feature_low.astype(np.float32), self.feature_high.astype(np.float32), dtype=np.float32
        )
        return action, observation

    def team_spaces(self) -> tuple[spaces.Box, spaces.Box]:
        """(action, observation) spaces of the whole team of one environment (flat, robot 0 first)."""
        n = self.config.n_robots
        action, observation = self.robot_spaces()
        return (
            spaces.Box(np.tile(action.low, n), np.tile(action.high, n), dtype=np.float32),
            spaces.Box(np.tile(observation.low, n), np.tile(observation.high, n), dtype=np.float32),
        )

    # ------------------------------------------------------------------ views
    @property
    def poses(self) -> NDArray[np.float64]:
        """Poses of every robot, shape (K, N, 3) (a view of :attr:`state`)."""
        return self.state.transpose(0, 2, 1)

    @poses.setter
    def poses(self, value: NDArray[np.float64]) -> None:
        self.state = np.ascontiguousarray(np.asarray(value, dtype=np.float64).transpose(0, 2, 1))

    #: rows of :attr:`counters`, (K,) views: periods within the goal tolerance, since the reset
    settled = property(lambda self: self.counters[SETTLED])
    elapsed = property(lambda self: self.counters[ELAPSED])

    @property
    def obstacles(self) -> NDArray[np.float64]:
        """Every environment's obstacles, shape (K, M, 3): x, y, radius [m] each (a view of the
        geometry's channel-first obstacle sets)."""
        return self.geometry.obstacles.transpose(0, 2, 1)

    @property
    def targets(self) -> NDArray[np.float64]:
        """Target poses, shape (K, N, 3) (a view)."""
        return self.target.transpose(0, 2, 1)

    @property
    def offsets(self) -> NDArray[np.float64]:
        """Formation offsets, shape (K, N, 2) (a view)."""
        return self.offset.transpose(0, 2, 1)

    # ------------------------------------------------------------------ reset
    def _set_map(self, index: int, spec: MapSpec) -> None:
        n = self.config.n_robots
        self.maps[index] = spec
        self.geometry.set_obstacles(index, spec.obstacles)
        self.target[index] = spec.targets[:n].T
        self.offset[index] = formation_offsets(spec.targets[:n]).T
        self.starts[index] = spec.starts[:n]
        self.nominal_starts[index] = spec.starts[:n]
        if self.zones is not None:
            self.zones.set_env(index, spec.slip_zones)

    def reset_env(self, index: int, rng: np.random.Generator, options: ResetOptions | None = None) -> None:
        """Start a new episode in environment ``index``, drawing only from ``rng``:
        :meth:`reset_envs` for one environment.

        The episode's map, starts and targets come from
        :func:`~koopman_envs.engine.episode.episode_layout`: ``options`` (from
        :func:`parse_reset_options`) replace the map's start poses and/or targets for this
        episode; they are checked against the episode's map (a new one per reset with
        ``map="random"``) before anything changes.

        Raises
        ------
        ValueError
            A start pose or target of ``options`` that is outside the workspace, overlaps an
            obstacle or another robot's (the environment keeps its previous episode).
        """
        reset_episodes(self, [index], [rng], [options])

    def reset_envs(
        self,
        rows: Sequence[int],
        rngs: Sequence[np.random.Generator],
        options: Sequence[ResetOptions | None] | None = None,
    ) -> None:
        """Start a new episode in each environment of ``rows`` together, environment
        ``rows[b]`` drawing only from ``rngs[b]`` exactly as :meth:`reset_env` would
        (:func:`~koopman_envs.engine.episode.reset_episodes`); a rejected option
        leaves every environment of the batch in its previous episode."""
        reset_episodes(self, rows, rngs, options)

    def _flush_perception(self) -> None:
        """The first readings of the environments reset since the last step (one batched call)."""
        if self.perception is not None:
            self.perception.flush(self.state, self._obstacle_discs(), self.config.robot_radius)

    def _obstacle_discs(self) -> NDArray[np.float64]:
        """What the lidar's beams hit besides the robots, (K, 3, M + C): the static obstacles,
        then the movers (rows x, y, radius [m])."""
        if self.movers is None:
            return self.geometry.obstacles
        return np.concatenate([self.geometry.obstacles, self.movers.discs()], axis=2)

    def features(self) -> NDArray[np.float64]:
        """Observation blocks of every robot, shape (K, N, F)."""
        self._flush_perception()
        features, _ = self.builder.build(
            self.state,
            self.target,
            self.geometry,
            self.offset if self.config.task.formation else None,
            self.perception,
            listed_movers(self.observed_movers()),
        )
        return features

    # ------------------------------------------------------------------- step
    def validate_commands(self, commands: Any) -> NDArray[np.float64]:
        """Check a batch of joint commands and return it as float64 (K, N, 2)
        (:func:`~koopman_envs.checks.check_commands`: ValueError naming a wrong shape or value)."""
        return check_commands(commands, self.num_envs, self.config.n_robots)

    def step(self, commands: NDArray[np.float64], active: NDArray[np.bool_] | None = None) -> StepResult:
        """Advance every (active) environment by one control period.

        Parameters
        ----------
        commands : ndarray, shape (K, N, 2)
            Validated commands (v [m/s], omega [rad/s]); saturated here to the limits.
        active : ndarray of bool, shape (K,), optional
            Environments to advance; the others keep their state and consume no randomness.

        Returns
        -------
        StepResult
        """
        stepping = self.all_active if active is None else active
        perception = self.perception
        rows = self._all_rows if active is None else np.flatnonzero(active)
        if perception is not None:
            commands = perception.delayed(commands, rows)
        new, effort = advance_plant(self, commands, active)
        before, self.state = self.state, new
        geometry = self.geometry
        collision = np.empty(self.num_envs, dtype=np.int64)
        collision_flags(new, geometry.obstacles, geometry.radius_sum, self._workspace, collision)
        features, distances = self._sense(before, new, rows, stepping, collision)
        k, n = distances.shape
        robot_reward, team_reward, reward = np.empty((k, n)), np.empty(k), np.empty(k)
        ends = np.empty((3, k), dtype=bool)
        score_step(
            self._score_rule,
            self.distances,
            distances,
            effort,
            self._formation_error(),
            collision,
            stepping,
            self.counters,
            (robot_reward, team_reward, reward),
            ends,
        )
        self.distances = distances
        self.collision = collision
        self.success = ends[SUCCESS]
        if self.slip_clock is not None:
            self.slip_clock.advance(self.elapsed, active, self.slip.rngs, self.slip.lambdas)
        return StepResult(features, robot_reward, team_reward, reward, ends[TERMINATED], ends[TRUNCATED])

    def _sense(
        self,
        before: NDArray[np.float64],
        new: NDArray[np.float64],
        rows: NDArray[np.int64],
        stepping: NDArray[np.bool_],
        collision: NDArray[np.int64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The world after the robots' move: the movers move and meet the team (their contacts
        into ``collision``, whose fault each is from the robots' move ``before`` to ``new`` in
        the ``stepping`` environments), the robots sense, the tracker follows the movers;
        returns the observation blocks and the true target distances (the rewards')."""
        cfg, perception, movers = self.config, self.perception, self.movers
        if movers is not None:  # the movers move through the same period, then meet the team
            movers.step(before, new, rows)
            movers.meet(before, new, stepping, cfg.robot_radius, collision)
        if perception is not None:
            perception.update(new, self._obstacle_discs(), cfg.robot_radius, rows)
        if self.mover_tracker is not None:
            assert movers is not None  # a tracker is only made with movers
            estimates = new if perception is None else perception.observed
            self.mover_tracker.step(movers.states(), new, estimates, rows)
        features, distances = self.builder.build(
            new,
            self.target,
            self.geometry,
            self.offset if cfg.task.formation else None,
            perception,
            None if movers is None else listed_movers(self.observed_movers()),
        )
        if perception is not None:  # the builder measured what the robots believe; rewards need the truth
            dx = self.target[:, 0] - new[:, 0]
            dy = self.target[:, 1] - new[:, 1]
            distances = np.sqrt(dx * dx + dy * dy)
        return features, distances

    def slip_means(self) -> NDArray[np.float64]:
        """Slip mean lambda of every robot for the period that starts now, shape (K, N).

        The base level (the slip setting, this episode's draw, or the schedule's level at the
        current time) with the slip zones that contain the robot's centre applied: exactly the
        scale the next :meth:`step` gives the robot's Exponential draws. Ground truth, for tests
        and analysis; controllers must not read it.
        """
        if self.zones is None:
            return self.slip.lambdas.copy()
        return self.zones.slip_means(self.state, self.slip.lambdas, np.empty_like(self.slip.lambdas))

    # ------------------------------------------------------------------- info
    def scenario(self, index: int = 0) -> Scenario:
        """The scenario a model-based controller may use for environment ``index``
        (:func:`~koopman_envs.engine.episode.engine_scenario`)."""
        return engine_scenario(
            self.config,
            self.maps[index],
            self.obstacles[index],
            self.nominal_starts[index],
            self.target[index],
            self.offset[index],
            self.settle_steps,
        )

    def _formation_error(self) -> NDArray[np.float64]:
        """What the reward charges: the slot errors for formation, a placeholder otherwise."""
        return self.formation_errors() if self.config.task.formation else self._no_formation

    def formation_errors(self) -> NDArray[np.float64]:
        """Distance of every robot from its formation slot relative to the leader [m], (K, N)
        (the leader's is 0), from the engine's state, not from the clipped observation."""
        errors = np.empty(self.distances.shape)
        slot_errors(self.state, self.offset, errors)
        return errors

    def robot_collisions(self) -> NDArray[np.bool_]:
        """Which robots are in collision, (K, N): overlapping an obstacle, another robot or a mover,
        or with the centre outside the workspace (the per-robot view of the collision flags)."""
        return self._robot_collisions()[0]

    def _robot_collisions(
        self,
    ) -> tuple[NDArray[np.bool_], NDArray[np.int64], NDArray[np.int_], NDArray[np.int_]]:
        """:meth:`robot_collisions`, whose fault each robot's collision is, (K, N) codes of
        :class:`~koopman_envs.sim.collision.CollisionFault` (the rule is there), and how many
        robots of each environment are at fault and not at fault, (K,) each."""
        k, n = self.distances.shape
        out = np.zeros((k, n), dtype=bool)
        fault = np.zeros((k, n), dtype=np.int64)
        hit = self.collision.nonzero()[0]
        if not hit.size:  # the common case, on every step: no fault anywhere
            return out, fault, np.zeros(k, dtype=np.int_), np.zeros(k, dtype=np.int_)
        # only the environments that collided
        x, y = self.state[hit, 0], self.state[hit, 1]
        touching = (self.geometry.clearances(x, y, rows=hit) < 0.0).any(axis=-1)
        x_min, x_max, y_min, y_max = PARAMS.workspace
        out[hit] = static = touching | (x < x_min) | (x > x_max) | (y < y_min) | (y > y_max)
        # a static contact is the robot's whatever a mover did in the same period
        fault[hit] = np.where(
            static, CollisionFault.ROBOT, 0 if self.movers is None else self.movers.fault[hit]
        )
        if self.movers is not None:
            out[hit] |= self.movers.hit[hit]
        return (
            out,
            fault,
            (fault == CollisionFault.ROBOT).sum(axis=1),
            (fault == CollisionFault.MOVER).sum(axis=1),
        )

    def batch_info(self) -> dict[str, Any]:
        """The true structured state of every environment, one array per key (copies).

        Keys: ``poses`` (K, N, 3), ``targets`` (K, N, 3), ``distances`` (K, N), ``collision``
        (K,) bool, ``collision_code`` (K,) int (bit flags of
        :class:`~koopman_envs.sim.collision.CollisionKind`: 1 obstacle, 2 robot, 4 workspace,
        8 mover;
        ``CollisionKind.describe(code)`` names them, e.g. ``"robot+workspace"``; every value of
        an info is a number or an array, which RL libraries stack into tensors),
        ``robot_collision`` (K, N) bool (which robots collided), ``collision_fault`` (K, N) int
        (whose fault each robot's collision is: 0 none, 1 the robot's, 2 a mover's, by the rule of
        :class:`~koopman_envs.sim.collision.CollisionFault`, which ``describe`` names),
        ``robots_at_fault`` and ``robots_not_at_fault`` (K,) int (the robots of each fault),
        ``is_success`` (K,), ``settled_steps`` (K,), ``formation_error`` (K, N) for formation, and with ``movers``
        ``movers`` (K, C, 4): every mover's true x, y [m], vx, vy [m/s].
        :meth:`info` is row ``index`` of this, so every front reports the same keys.
        """
        robot_collision, fault, at_fault, not_at_fault = self._robot_collisions()
        info = {
            **self.observed_info(),
            "poses": self.poses.copy(),
            "targets": self.targets.copy(),
            "distances": self.distances.copy(),
            "collision": self.collision.astype(bool),
            "collision_code": self.collision.copy(),  # int64 already
            "robot_collision": robot_collision,
            "collision_fault": fault,
            "robots_at_fault": at_fault,
            "robots_not_at_fault": not_at_fault,
            "is_success": self.success.copy(),
            "settled_steps": self.settled.copy(),
        }
        if self.config.task.formation:
            info["formation_error"] = self.formation_errors()
        if self.movers is not None:
            info["movers"] = self.movers.states()
        return info

    def observed_info(self) -> dict[str, Any]:
        """What the robots believe, one array per key (copies): the part of an info a controller
        may read (:func:`koopman_envs.sim.perception.observed_info` lists the keys)."""
        self._flush_perception()
        observed = observed_info(self.perception, self.poses)
        movers = self.observed_movers()
        if movers is not None:
            observed["observed_movers"], observed["mover_tracked"] = movers
        return observed

    def observed_movers(self) -> tuple[NDArray[np.float64], NDArray[np.bool_]] | None:
        """The movers as the robots observe them (:func:`~koopman_envs.sim.movers.tracking.observed_movers`)."""
        return observed_movers(self.movers, self.mover_tracker, self.observation_layout.movers)

    def info(self, index: int = 0) -> dict[str, Any]:
        """The true structured state of environment ``index``: row ``index`` of :meth:`batch_info`
        (per-env flags and counters as Python scalars)."""
        return {
            key: value.item(index) if value.ndim == 1 else value[index]
            for key, value in self.batch_info().items()
        }
