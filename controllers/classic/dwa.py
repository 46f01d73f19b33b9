"""``dwa``: the dynamic window approach (Fox, Burgard and Thrun 1997) per robot, scored as the ROS
navigation stack's ``dwa_local_planner`` scores it, with its default weights, over a navfn-like
global plan (:mod:`controllers.classic.plan`); pure numpy, deterministic, every robot and every
sample in one array computation.

Per period and robot (decentralized: robot i plans from ``known_poses[i]``, see
:mod:`controllers.classic.common`):

1. **dynamic window**: ``vx_samples`` x ``vth_samples`` velocity pairs evenly spread over what
   the accelerations ``acc_lim_x``, ``acc_lim_theta`` reach from the last command within one
   period, inside ``[0, v_max] x [-omega_max, omega_max]`` (forward only, as ROS's default
   ``min_vel_x = 0``);
2. **forward simulation**: each pair held for ``sim_time`` seconds on the unicycle (its exact
   arc), at points ``sim_granularity`` metres apart at full speed;
3. **scoring** (lowest cost wins), ROS's critics with its weights (distances in metres):
   ``path_distance_bias * (d_path(end) + d_path(nose)) + goal_distance_bias * (d_goal(end) +
   d_goal(nose)) + occdist_scale * occupancy``. ``end`` is the trajectory's last point, ``nose``
   the point ``forward_point_distance`` ahead of it along the final heading (the nose's path term
   is dropped within that distance of the goal, as in ROS). ``d_path`` is the distance to the
   global plan, ``d_goal`` the wavefront distance to the goal (:mod:`controllers.classic.plan`);
   with the goal in line of sight the plan is the straight segment (bent round the right side of
   a team-mate or mover standing on it, where ROS's global costmap would hold the other robot),
   ``d_goal`` the straight-line distance, and the nose is drawn to the goal pushed
   ``forward_point_distance`` further (ROS's goal-front critic). A nose inside an obstacle's lethal band counts as the end point (ours: ROS
   gives it a prohibitive cost, which stalls a robot turning on the spot past an obstacle).
   ``occupancy`` is the costmap value of the trajectory's worst point: ROS's inflation,
   ``252 exp(-cost_scaling_factor * c)`` at a clearance ``c`` [m] when the obstacle's surface is
   within ``inflation_radius`` of the robot's centre, 0 beyond;
4. **admissibility**: a trajectory that comes closer than ``safety_margin`` to a disc (the map's
   obstacles; the team-mates it has heard of and the movers, both at their constant-velocity
   predicted positions along the trajectory) is refused. A robot already closer than the margin
   may keep its clearance but not shrink it; when every sample is refused, the one keeping the
   largest clearance is taken (ours: ROS stops and calls its recovery behaviours);
5. within ``xy_goal_tolerance`` of its goal the robot brakes to a stop (ROS's stop-and-rotate
   controller; KoopNav's targets have no heading to rotate to).

Defaults, from ROS ``dwa_local_planner`` (melodic) and ``costmap_2d``'s inflation layer:
acc_lim_x 2.5 m/s^2, acc_lim_theta 3.2 rad/s^2, sim_time 1.7 s, sim_granularity 0.025 m,
vth_samples 20, path_distance_bias 32, goal_distance_bias 24, occdist_scale 0.01,
forward_point_distance 0.325 m, inflation_radius 0.55 m, cost_scaling_factor 10. Ours:
vx_samples 7 (ROS: 3, which leaves a robot 0.13 m short of its goal here), safety_margin 0.1 m
(ROS pads the footprint by 0.01 m), xy_goal_tolerance 0.05 m (ROS: 0.1, KoopNav's whole success
tolerance) and the plan's 0.1 m grid (ROS's costmap: 0.05 m).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from controllers.classic.common import ClassicController, ClassicSettings, goals
from controllers.classic.kernels import closest_approach, unicycle_arcs
from controllers.classic.plan import Detour, GlobalPlanner, Plan
from controllers.movers import (
    observed_mover_radii,
    observed_movers,
)
from controllers.tuning.search_space import Search
from koopman_envs import Observed
from koopman_envs.checks import Range
from koopman_envs.scenario import Scenario

__all__ = ["DWAController", "DWASettings", "segment_distance"]

#: ROS costmap_2d's highest cost of a free cell (INSCRIBED_INFLATED_OBSTACLE - 1)
_FREE_MAX_COST = 252.0


def segment_distance(
    point: NDArray[np.float64], start: NDArray[np.float64], end: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Distance of ``point`` (..., 2) to the segment ``start``-``end`` (broadcast, (..., 2))."""
    along = end - start
    length2 = (along * along).sum(axis=-1)
    t = ((point - start) * along).sum(axis=-1) / np.maximum(length2, 1e-12)
    nearest = start + np.clip(t, 0.0, 1.0)[..., None] * along
    return np.asarray(np.linalg.norm(point - nearest, axis=-1))


@dataclass(frozen=True)
class DWASettings(ClassicSettings):
    """The options of :class:`DWAController` (ranges and choices checked on construction).

    Attributes
    ----------
    acc_lim_x : float
        Translational acceleration bounding the window [m/s^2] (ROS default 2.5).
    acc_lim_theta : float
        Rotational acceleration bounding the window [rad/s^2] (ROS default 3.2).
    sim_time : float
        Seconds each velocity pair is simulated forward [s] (ROS default 1.7).
    sim_granularity : float
        Spacing of the simulated points at full speed [m] (ROS default 0.025).
    vx_samples : int
        Translational velocities sampled in the window (ours 7, ROS default 3: with 3 over
        KoopNav's 0.25 m/s window the slowest move from rest is 0.2 m over sim_time, and a
        robot stops 0.13 m short of its goal, outside the 0.1 m tolerance).
    vth_samples : int
        Rotational velocities sampled in the window (ROS default 20).
    path_distance_bias : float
        Weight of the distance to the plan (trajectory end and nose) [1/m] (ROS default 32).
    goal_distance_bias : float
        Weight of the distance to the goal (trajectory end and nose) [1/m] (ROS default 24).
    occdist_scale : float
        Weight of the worst costmap value along the trajectory (ROS default 0.01).
    forward_point_distance : float
        How far ahead of the trajectory's end its nose is [m] (ROS default 0.325).
    inflation_radius : float
        Distance from the robot's centre to an obstacle's surface below which the costmap is
        inflated [m] (ROS costmap_2d default 0.55).
    cost_scaling_factor : float
        Decay of the inflated cost with clearance [1/m] (ROS costmap_2d default 10).
    safety_margin : float
        (ours) A trajectory closer than this to any disc is refused [m]; the global plan keeps
        it too.
    xy_goal_tolerance : float
        (ours) Within this distance of its goal the robot brakes to a stop [m] (half KoopNav's
        success tolerance; ROS's default is 0.1).
    plan_resolution : float
        Cell size of the global plan's grid [m] (:mod:`controllers.classic.plan`; ROS's
        costmap default is 0.05, ours is coarser for speed).
    velocity_window : int
        (ours) Periods between the two messages of a team-mate whose difference is its velocity.
    mover_prediction : str
        Where a mover is along the trajectory: ``"constant_velocity"`` (default) moving on with
        its observed velocity; ``"static"`` where it is seen now
        (:data:`controllers.movers.MOVER_PREDICTIONS`).
    estimator : str
        (ours) The estimator front-end (:data:`controllers.estimation.ESTIMATORS`): ``"auto"``
        (default, delay and noise identified online), ``"realistic"`` or ``"none"``.
    ablate : str
        (ours) ``"none"`` (default), or one lever of the estimator switched off:
        ``"estimation"`` or ``"delay_compensation"``.
    """

    acc_lim_x: float = 2.5
    acc_lim_theta: float = 3.2
    sim_time: float = 1.7
    sim_granularity: float = 0.025
    vx_samples: int = 7
    vth_samples: int = 20
    path_distance_bias: float = 32.0
    goal_distance_bias: float = 24.0
    occdist_scale: float = 0.01
    forward_point_distance: float = 0.325
    inflation_radius: float = 0.55
    cost_scaling_factor: float = 10.0
    safety_margin: float = 0.1
    xy_goal_tolerance: float = 0.05
    plan_resolution: float = 0.1
    velocity_window: int = 5
    mover_prediction: str = "constant_velocity"
    estimator: str = "auto"
    ablate: str = "none"

    #: the allowed range of every numeric option (ours; :mod:`controllers.option_spec` reads it as
    #: the controller's ``OPTION_RANGES``): far beyond ROS's defaults and bounded so that the
    #: trajectory rollouts stay small (at most 32 x 64 samples of at most 10 s / 0.01 s = 1,000
    #: steps per robot and period)
    RANGES: ClassVar[dict[str, Range]] = {
        "acc_lim_x": Range(0, 100, low_open=True, note="m/s^2"),
        "acc_lim_theta": Range(0, 100, low_open=True, note="rad/s^2"),
        "sim_time": Range(0, 10, low_open=True, note="s"),
        "sim_granularity": Range(0.01, 1, note="s"),
        "vx_samples": Range(1, 32, integer=True),
        "vth_samples": Range(1, 64, integer=True),
        "path_distance_bias": Range(0, 1e6),
        "goal_distance_bias": Range(0, 1e6),
        "occdist_scale": Range(0, 1e6),
        "forward_point_distance": Range(0, 10, note="m"),
        "inflation_radius": Range(0, 10, note="m"),
        "cost_scaling_factor": Range(0, 1000, low_open=True),
        "safety_margin": Range(0, 1, note="m"),
        "xy_goal_tolerance": Range(0, 1, low_open=True, note="m"),
        # the global plan's grid: 0.02 m cells are 1.4 M cells on the largest workspace
        "plan_resolution": Range(0.02, 1, note="m"),
        "velocity_window": Range(1, 100, integer=True, note="periods"),
    }


class DWAController(ClassicController):
    """The dynamic window approach per robot, with ROS dwa_local_planner's scoring and defaults.

    Parameters
    ----------
    config : DWASettings, optional
        The settings (default: ``DWASettings()``, ROS's defaults and ours).
    **options
        Fields of :class:`DWASettings` by name, in place of ``config``'s
        (``controllers.make("dwa", sim_time=2.0)``).
    """

    name = "dwa"
    #: the options (:class:`~controllers.classic.common.ClassicController`: their tables read off it)
    SETTINGS: ClassVar[type[DWASettings]] = DWASettings
    config: DWASettings
    #: what the tuner searches (:mod:`evaluation.tune`; ours): the rollout length and the three
    #: weights of the trajectory score (the ratios ROS users tune: plan against goal against
    #: obstacle cost), the hard clearance and the costmap's inflation. Sample counts and grid
    #: resolutions trade compute for precision and are left at their defaults.
    TUNABLE: ClassVar[dict[str, Search]] = {
        "sim_time": Search(0.8, 3.0),
        "path_distance_bias": Search(4.0, 128.0, log=True),
        "goal_distance_bias": Search(4.0, 96.0, log=True),
        "occdist_scale": Search(0.001, 0.1, log=True),
        "safety_margin": Search(0.02, 0.2),
        "inflation_radius": Search(0.2, 1.0),
    }

    def __init__(self, config: DWASettings | None = None, **options: Any) -> None:
        super().__init__(config, options)
        self._planner = GlobalPlanner(
            self.config.plan_resolution,
            self.config.safety_margin,
            self.config.inflation_radius,
            self.config.cost_scaling_factor,
        )
        self._times = np.zeros(0)

    def _reset(self, scenario: Scenario, seed: int | None) -> None:
        self._reset_team(scenario)
        self._planner.reset(scenario)
        steps = max(1, int(np.ceil(scenario.v_max * self.config.sim_time / self.config.sim_granularity)))
        self._times = self.config.sim_time * np.arange(1, steps + 1) / steps

    def obstacles_seen(self, obstacles: NDArray[np.float64]) -> bool:
        """Perceived obstacles (map unknown): the global planner's grid is rebuilt when they
        change on it (as a costmap updates from the sensors)."""
        changed = super().obstacles_seen(obstacles)
        assert self.scenario is not None  # set by the base
        if changed and self._planner.outdated(self.scenario.obstacles):
            self._planner.reset(self.scenario)
        return changed

    def _act(self, observation: NDArray, observed: Observed) -> NDArray[np.float64]:
        sc = self.scenario
        assert sc is not None  # act() checked it
        known, ages = observed.known_poses, observed.message_age
        position, velocity, heard = self._team.update(known, ages, self._last)
        own = np.arange(sc.n_robots)
        pose = known[own, own]
        goal, moving = goals(sc, position, velocity, heard)
        samples = self._window()  # (N, S, 2)
        path = self._rollout(pose, samples)  # (N, S, K, 3)
        movers = observed_movers(observed)
        self._mover_radii = observed_mover_radii(observed, sc.mover_radius)
        blockers = self._blockers(position, heard, movers)
        cost = self._goal_cost(pose[:, :2], path, goal + moving * self.config.sim_time, blockers)
        clearance, now = self._clearances(path, position, velocity, heard, movers)
        worst = clearance  # (N, S, O): each disc's closest approach
        cost = cost + self.config.occdist_scale * self._occupancy(worst.min(axis=-1))
        refused = (worst < np.minimum(self.config.safety_margin, now)[:, None, :] - 1e-9).any(axis=-1)
        cost = np.where(refused, np.inf, cost)
        best = np.argmin(cost, axis=1)
        stuck = ~np.isfinite(cost[own, best])
        best = np.where(stuck, np.argmax(worst.min(axis=-1), axis=1), best)  # nothing admissible
        command = samples[own, best]
        arrived = np.hypot(*(pose[:, :2] - goal).T) <= self.config.xy_goal_tolerance
        command[arrived] = self._brake(self._last[arrived])
        self._last = command
        return command.reshape(-1)

    def _window(self) -> NDArray[np.float64]:
        """(N, S, 2) velocity pairs of each robot's dynamic window around its last command."""
        sc = self.scenario
        assert sc is not None
        v0, w0 = self._last[:, 0], self._last[:, 1]
        v_lo = np.clip(v0 - self.config.acc_lim_x * sc.dt, 0.0, sc.v_max)
        v_hi = np.clip(v0 + self.config.acc_lim_x * sc.dt, 0.0, sc.v_max)
        w_lo = np.clip(w0 - self.config.acc_lim_theta * sc.dt, -sc.omega_max, sc.omega_max)
        w_hi = np.clip(w0 + self.config.acc_lim_theta * sc.dt, -sc.omega_max, sc.omega_max)
        fv = np.linspace(0.0, 1.0, self.config.vx_samples) if self.config.vx_samples > 1 else np.ones(1)
        fw = (
            np.linspace(0.0, 1.0, self.config.vth_samples) if self.config.vth_samples > 1 else np.full(1, 0.5)
        )
        v = v_lo[:, None] + (v_hi - v_lo)[:, None] * fv  # (N, Sv)
        w = w_lo[:, None] + (w_hi - w_lo)[:, None] * fw  # (N, Sw): right turns first on a tie
        grid_v = np.repeat(v, len(fw), axis=1)
        grid_w = np.tile(w, (1, len(fv)))
        return np.stack([grid_v, grid_w], axis=-1)

    def _rollout(self, pose: NDArray[np.float64], samples: NDArray[np.float64]) -> NDArray[np.float64]:
        """(N, S, K, 3) poses along each sample's arc at the simulated times (exact unicycle;
        compiled, :func:`controllers.classic.kernels.unicycle_arcs`)."""
        return unicycle_arcs(np.ascontiguousarray(pose), np.ascontiguousarray(samples), self._times)

    def _goal_cost(
        self,
        start: NDArray[np.float64],
        path: NDArray[np.float64],
        goal: NDArray[np.float64],
        blockers: list[tuple[NDArray[np.float64], NDArray[np.float64]]],
    ) -> NDArray[np.float64]:
        """(N, S) ROS's path, goal, alignment and goal-front critics (module docstring, step 3);
        ``blockers[i]``: the centres and reaches of the discs that may stand on robot i's plan."""
        end, heading = path[:, :, -1, :2], path[:, :, -1, 2]
        reach = self.config.forward_point_distance
        nose = end + reach * np.stack([np.cos(heading), np.sin(heading)], axis=-1)
        cost = np.empty(end.shape[:2])
        for i in range(end.shape[0]):
            to_goal = goal[i] - start[i]
            far = float(np.hypot(*to_goal)) > reach  # the nose's path term is dropped near the goal
            plan: Plan | Detour | None = self._planner.plan(start[i], goal[i])
            if plan is None:  # in line of sight, unless a team-mate or mover stands on it
                plan = self._planner.detour(start[i], goal[i], *blockers[i])
            if plan is None:  # the plan is the straight segment
                front = goal[i] + reach * to_goal / max(float(np.hypot(*to_goal)), 1e-9)
                on_path = segment_distance(end[i], start[i], goal[i])
                on_path = on_path + (segment_distance(nose[i], start[i], goal[i]) if far else 0.0)
                to_end = np.linalg.norm(end[i] - goal[i], axis=-1) + np.linalg.norm(nose[i] - front, axis=-1)
            else:
                on_path = plan.path_distance(end[i]) + (plan.path_distance(nose[i]) if far else 0.0)
                to_end = plan.goal_distance(end[i])
                to_end = to_end + plan.goal_distance(nose[i], fallback=to_end)
            cost[i] = self.config.path_distance_bias * on_path + self.config.goal_distance_bias * to_end
        return cost

    def _blockers(
        self, position: NDArray[np.float64], heard: NDArray[np.bool_], movers: NDArray[np.float64]
    ) -> list[tuple[NDArray[np.float64], NDArray[np.float64]]]:
        """Per robot, the team-mates it has heard of and the movers where they are now: centres
        (B, 2) and the distance its centre keeps from them (B,) [m]."""
        sc = self.scenario
        assert sc is not None
        out = []
        for i in range(sc.n_robots):
            mates = heard[i] & (np.arange(sc.n_robots) != i)
            centres = np.vstack([position[i, mates], movers[:, :2]])
            radii = np.concatenate([sc.robot_radius[mates], self._mover_radii])
            out.append((centres, radii + sc.robot_radius[i] + self.config.safety_margin))
        return out

    def _clearances(
        self,
        path: NDArray[np.float64],
        position: NDArray[np.float64],
        velocity: NDArray[np.float64],
        heard: NDArray[np.bool_],
        movers: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Each trajectory's closest approach [m] to every disc as its robot sees them, (N, S, O),
        and the clearances now (N, O): the map's obstacles, then the team-mates (infinite for oneself and
        those not heard of), then the movers; moving discs at their predicted positions."""
        sc = self.scenario
        assert sc is not None
        n = sc.n_robots
        t = np.concatenate([[0.0], self._times])  # (K + 1,)
        if self.config.mover_prediction == "static":
            movers = np.column_stack([movers[:, :2], np.zeros((len(movers), 2))])
        mates = position[:, None] + t[None, :, None, None] * velocity[:, None]  # (N, K+1, N, 2)
        crowd = movers[None, :, :2] + t[:, None, None] * movers[None, :, 2:4]  # (K+1, C, 2)
        crowd = np.broadcast_to(crowd[None], (n, *crowd.shape))
        fixed = np.broadcast_to(sc.obstacles[None, None, :, :2], (n, len(t), len(sc.obstacles), 2))
        centres = np.concatenate([fixed, mates, crowd], axis=2)  # (N, K+1, O, 2)
        radii = np.concatenate([sc.obstacles[:, 2], sc.robot_radius, self._mover_radii])
        reach = radii[None, :] + sc.robot_radius[:, None]  # (N, O)
        ignored = np.zeros((n, len(radii)), dtype=bool)
        ignored[:, len(sc.obstacles) : len(sc.obstacles) + n] = ~heard | np.eye(n, dtype=bool)
        reach = np.where(ignored, -np.inf, reach)
        own = np.arange(n)
        start = position[own, own]  # (N, 2)
        now = np.hypot(*(start[:, None] - centres[:, 0]).transpose(2, 0, 1)) - reach
        # (N, S, O): min over the K times of the distance, compiled (the (N, S, K, O) arrays of
        # the numpy expression took most of a decision)
        closest = closest_approach(np.ascontiguousarray(path), np.ascontiguousarray(centres[:, 1:]))
        return closest - reach[:, None], now

    def _occupancy(self, clearance: NDArray[np.float64]) -> NDArray[np.float64]:
        """(N, S) costmap value of each trajectory's worst point from its closest approach
        ``clearance`` (N, S) [m] (ROS's inflation, step 3)."""
        sc = self.scenario
        assert sc is not None
        closest = clearance
        inflated = closest + sc.robot_radius[:, None] <= self.config.inflation_radius
        cost = _FREE_MAX_COST * np.exp(-self.config.cost_scaling_factor * np.maximum(closest, 0.0))
        return np.where(inflated, cost, 0.0)

    def _brake(self, last: NDArray[np.float64]) -> NDArray[np.float64]:
        """Commands slowing ``last`` (M, 2) to a stop within the acceleration limits."""
        sc = self.scenario
        assert sc is not None
        step = np.array([self.config.acc_lim_x, self.config.acc_lim_theta]) * sc.dt
        return np.sign(last) * np.maximum(np.abs(last) - step, 0.0)
