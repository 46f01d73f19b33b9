"""``orca``: every robot runs ORCA (optimal reciprocal collision avoidance, van den Berg et al.
2011) through the RVO2 library's ``pyrvo`` bindings (the ``[crowd]`` extra), and a heading
controller turns the holonomic velocity into a unicycle command.

Per period and robot (decentralized: robot i plans from ``known_poses[i]``, see
:mod:`controllers.classic.common`):

1. **preferred velocity** towards its goal (its target; on the formation task a follower's slot,
   the leader's position as it knows it plus its offset, with the leader's velocity as
   feed-forward): ``v_pref = clip(goal_gain * (goal - p) + feed-forward, v_max)``, turned
   ``keep_right`` radians clockwise, which breaks the symmetry of an exact head-on meeting (RVO2's
   examples perturb at random for this; ``koopman_envs.sim.movers.crowd`` does the same for people);
2. **ORCA** among its neighbours: the team-mates it has heard of (at their positions carried to
   now, with their velocities estimated from their messages; they run ORCA too, so avoidance is
   shared half and half, as ORCA assumes), the movers (``observed_movers``: position and velocity,
   constant-velocity by default; they do not run our ORCA, so they are enlarged by
   ``mover_margin`` for the half they do not take) and the map's obstacles. The discs are
   **obstacle polygons** (a circumscribed 16-gon each, counter-clockwise: RVO2's static
   obstacles, with their own time horizon, never smaller than the disc), built once per episode;
   the agents are set anew every period;
3. **unicycle tracking** of the ORCA velocity ``u`` by a heading controller with a speed cap:
   ``e = angle(u) - theta``, ``omega = clip(heading_gain * e, omega_max)``,
   ``v = min(|u| max(cos e, 0), v_max)``: a robot drives at the projection of ``u`` on its heading
   and turns on the spot when ``u`` points behind it. The tracking error this leaves (NH-ORCA's
   point, Alonso-Mora et al. 2010) is absorbed by ``radius_margin``: ORCA plans with the robot's
   radius plus the margin, as NH-ORCA plans with an effective radius.

Settings and where they come from: the radius is the scenario's ``robot_radius`` plus
``radius_margin`` (0.05 m, ours); the time horizon for agents (2 s), the neighbour distance (3 m)
and the neighbour count (10) are the values KoopNav's crowd of pedestrians uses
(``koopman_envs.sim.movers.crowd``: RVO2's example values scaled to a person); the horizon for
obstacles is ours, 4 s where the crowd uses 1 s (a unicycle at ``omega_max`` = 0.79 rad/s needs
2 s for a quarter turn: with 1 s it met the obstacles it saw too late, docs/controllers.md has the
count); the maximum speed is ``v_max``. The tracking gains and margins are ours.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from controllers.classic.common import ClassicController, ClassicSettings, goals
from controllers.movers import (
    observed_mover_radii,
    observed_movers,
)
from controllers.tuning.search_space import Search
from koopman_envs import Observed
from koopman_envs.checks import Range, import_optional
from koopman_envs.params import LIMITS
from koopman_envs.scenario import Scenario

__all__ = ["ORCAController", "ORCASettings", "unicycle_tracking"]

#: sides of the polygon that stands in for a round obstacle (circumscribed: never smaller)
POLYGON_SIDES = 16
#: where agents out of a view wait [m] (far outside every map)
_PARKING = 1e5
INSTALL_HINT = (
    "orca needs pyrvo (ORCA from the RVO2 library): pip install -e '.[crowd]' (or pip install pyrvo)"
)


def _import_pyrvo() -> Any:
    return import_optional("pyrvo", INSTALL_HINT)


def unicycle_tracking(
    velocity: NDArray[np.float64], theta: NDArray[np.float64], gain: float, v_max: float, omega_max: float
) -> NDArray[np.float64]:
    """(N, 2) unicycle commands tracking the holonomic ``velocity`` (N, 2) from headings ``theta``
    (N,): heading controller with a speed cap (module docstring, step 3)."""
    speed = np.hypot(velocity[:, 0], velocity[:, 1])
    error = np.arctan2(velocity[:, 1], velocity[:, 0]) - theta
    error = (error + np.pi) % (2 * np.pi) - np.pi
    error = np.where(speed > 1e-9, error, 0.0)
    v = np.minimum(speed * np.maximum(np.cos(error), 0.0), v_max)
    omega = np.clip(gain * error, -omega_max, omega_max)
    return np.column_stack([v, omega])


@dataclass(frozen=True)
class ORCASettings(ClassicSettings):
    """The options of :class:`ORCAController` (ranges and choices checked on construction).

    Attributes
    ----------
    time_horizon : float
        ORCA's time horizon for other agents (team-mates, movers) [s]: velocities that avoid
        them for this long (default 2 s: koopman_envs.sim.movers.crowd's value).
    time_horizon_obstacles : float
        ORCA's time horizon for the map's obstacles [s] (ours: 4 s, where the crowd's pedestrians
        use 1 s: a unicycle turning at omega_max needs 2 s for a quarter turn, so it must react
        to an obstacle earlier than a person does).
    neighbour_distance : float
        Agents farther than this are not neighbours [m] (default 3 m: koopman_envs.sim.movers.crowd's).
    max_neighbours : int
        Most agents each robot takes into account, nearest first (default 10, RVO2's examples').
    radius_margin : float
        (ours) Added to the robot's radius in ORCA [m], absorbing the unicycle's tracking error
        (the role of NH-ORCA's effective radius).
    mover_margin : float
        (ours) Added to a mover's radius in ORCA [m]: a mover does not run our ORCA, so the robot
        keeps this much more room than its half of the avoidance.
    goal_gain : float
        (ours) Gain of the preferred velocity towards the goal [1/s] (capped at v_max).
    heading_gain : float
        (ours) Gain of the heading controller that tracks the ORCA velocity [1/s].
    keep_right : float
        (ours) The preferred velocity turned this far clockwise [rad], so that two robots that
        meet exactly head-on pass each other on the right (0: off).
    velocity_window : int
        (ours) Periods between the two messages of a team-mate whose difference is its velocity.
    mover_prediction : str
        What ORCA takes as a mover's velocity: ``"constant_velocity"`` (default) the observed
        one; ``"static"`` zero (:data:`controllers.movers.MOVER_PREDICTIONS`).
    estimator : str
        (ours) The estimator front-end (:data:`controllers.estimation.ESTIMATORS`): ``"auto"``
        (default, delay and noise identified online), ``"realistic"`` or ``"none"``.
    ablate : str
        (ours) ``"none"`` (default), or one lever of the estimator switched off:
        ``"estimation"`` or ``"delay_compensation"``.
    """

    time_horizon: float = 2.0
    time_horizon_obstacles: float = 4.0
    neighbour_distance: float = 3.0
    max_neighbours: int = 10
    radius_margin: float = 0.05
    mover_margin: float = 0.1
    goal_gain: float = 1.0
    heading_gain: float = 4.0
    keep_right: float = 0.05
    velocity_window: int = 5
    mover_prediction: str = "constant_velocity"
    estimator: str = "auto"
    ablate: str = "none"

    #: the allowed range of every numeric option (ours; :mod:`controllers.option_spec` reads it as
    #: the controller's ``OPTION_RANGES``)
    RANGES: ClassVar[dict[str, Range]] = {
        "time_horizon": Range(0, 60, low_open=True, note="s"),
        "time_horizon_obstacles": Range(0, 60, low_open=True, note="s"),
        "neighbour_distance": Range(0, LIMITS.lidar_range, low_open=True, note="m"),
        "max_neighbours": Range(1, LIMITS.robots + LIMITS.movers, integer=True),
        "radius_margin": Range(0, 1, note="m"),
        "mover_margin": Range(0, 1, note="m"),
        "goal_gain": Range(0, 100, low_open=True, note="1/s"),
        "heading_gain": Range(0, 100, low_open=True, note="1/s"),
        # below pi/2: a turn of less than 90 degrees
        "keep_right": Range(0, math.pi / 2, high_open=True, note="rad"),
        "velocity_window": Range(1, 100, integer=True, note="periods"),
    }


class ORCAController(ClassicController):
    """ORCA per robot through pyrvo (RVO2), unicycle commands by a heading controller.

    Parameters
    ----------
    config : ORCASettings, optional
        The settings (default: ``ORCASettings()``).
    **options
        Fields of :class:`ORCASettings` by name, in place of ``config``'s
        (``controllers.make("orca", time_horizon=3.0)``).
    """

    name = "orca"
    #: the options (:class:`~controllers.classic.common.ClassicController`: their tables read off it)
    SETTINGS: ClassVar[type[ORCASettings]] = ORCASettings
    config: ORCASettings
    #: what the tuner searches (:mod:`evaluation.tune`; ours): the two avoidance horizons (how
    #: early ORCA gives way to team-mates and to obstacles), the radius margin (clearance against
    #: room), the two gains of the unicycle's tracking of ORCA's holonomic velocity, and the
    #: head-on symmetry breaking. Neighbour counts and mover settings are left: the suites'
    #: teams are small and have no movers.
    TUNABLE: ClassVar[dict[str, Search]] = {
        "time_horizon": Search(0.5, 5.0, log=True),
        "time_horizon_obstacles": Search(1.0, 8.0, log=True),
        "radius_margin": Search(0.0, 0.2),
        "goal_gain": Search(0.3, 3.0, log=True),
        "heading_gain": Search(1.0, 10.0, log=True),
        "keep_right": Search(0.0, 0.3),
    }

    def __init__(self, config: ORCASettings | None = None, **options: Any) -> None:
        _import_pyrvo()  # refused here, with the extra to install, rather than at the first reset
        super().__init__(config, options)
        self._sim: Any = None
        self._movers_held = 0

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without its RVO2 simulator (a C++ object), which the next period rebuilds."""
        return {**self.__dict__, "_sim": None, "_movers_held": 0}

    def _reset(self, scenario: Scenario, seed: int | None) -> None:
        self._reset_team(scenario)
        self._build(scenario)

    def _build(self, scenario: Scenario) -> None:
        """The episode's RVO2 simulator: the obstacles, and an agent per robot."""
        sim = _import_pyrvo().RVOSimulator()
        sim.set_time_step(scenario.dt)
        scale = 1.0 / math.cos(math.pi / POLYGON_SIDES)
        angles = 2 * math.pi * np.arange(POLYGON_SIDES) / POLYGON_SIDES
        for ox, oy, r in scenario.obstacles:
            sim.add_obstacle(
                [(float(ox + r * scale * math.cos(a)), float(oy + r * scale * math.sin(a))) for a in angles]
            )
        if len(scenario.obstacles):
            sim.process_obstacles()
        # the agents are made once and moved every period (RVO2 as koopman_envs.sim.movers.crowd uses it:
        # pyrvo's clear_agents left garbage velocities behind in our trials): one per robot, then
        # one per mover seen so far; those not in a view wait far away, out of everyone's range
        sim.set_agent_defaults(
            self.config.neighbour_distance,
            self.config.max_neighbours,
            self.config.time_horizon,
            self.config.time_horizon_obstacles,
            float(scenario.robot_radius.max()) + self.config.radius_margin,
            float(scenario.v_max),
        )
        self._sim = sim
        self._movers_held = 0
        for j in range(scenario.n_robots):
            sim.add_agent(self._parking(j))

    def obstacles_seen(self, obstacles: NDArray[np.float64]) -> bool:
        """Perceived obstacles (map unknown): RVO2 cannot move an obstacle, so the simulator is
        rebuilt on the new ones before the next decision (the agents are placed every period)."""
        changed = super().obstacles_seen(obstacles)
        if changed:
            self._sim = None
        return changed

    def _parking(self, agent: int) -> tuple[float, float]:
        """Where an agent out of the view waits: far from the map and from every other agent."""
        return (_PARKING + 4.0 * self.config.neighbour_distance * agent, _PARKING)

    def _agents_for(self, movers: int) -> None:
        """Agents enough for ``movers`` movers after the robots' (never removed)."""
        sc = self.scenario
        assert sc is not None
        while self._movers_held < movers:
            self._sim.add_agent(self._parking(sc.n_robots + self._movers_held))
            self._movers_held += 1

    def _place(self, agent: int, position: Any, velocity: Any, preferred: Any, radius: float) -> None:
        sim = self._sim
        sim.set_agent_position(agent, (float(position[0]), float(position[1])))
        sim.set_agent_velocity(agent, (float(velocity[0]), float(velocity[1])))
        sim.set_agent_pref_velocity(agent, (float(preferred[0]), float(preferred[1])))
        sim.set_agent_radius(agent, radius)

    def _park(self, agent: int) -> None:
        self._place(agent, self._parking(agent), (0.0, 0.0), (0.0, 0.0), 0.0)

    def _act(self, observation: NDArray, observed: Observed) -> NDArray[np.float64]:
        sc = self.scenario
        assert sc is not None  # act() checked it
        if self._sim is None:  # unpickled
            self._build(sc)
        known, ages = observed.known_poses, observed.message_age
        position, velocity, heard = self._team.update(known, ages, self._last)
        movers = observed_movers(observed)
        self._mover_radii = observed_mover_radii(observed, sc.mover_radius)
        if self.config.mover_prediction == "static":
            movers = np.column_stack([movers[:, :2], np.zeros((len(movers), 2))])
        goal, moving = goals(sc, position, velocity, heard)
        own = np.arange(sc.n_robots)
        preferred = self._preferred(position[own, own], goal, moving)
        if (ages == 0).all() and (known == known[:1]).all():  # one view for all: one ORCA step
            chosen = self._orca(position[0], velocity[0], preferred, np.ones(sc.n_robots, bool), movers)
        else:
            chosen = np.stack(
                [self._orca(position[i], velocity[i], preferred, heard[i], movers)[i] for i in own]
            )
        command = unicycle_tracking(
            chosen, known[own, own, 2], self.config.heading_gain, sc.v_max, sc.omega_max
        )
        self._last = command
        return command.reshape(-1)

    def _preferred(
        self, position: NDArray[np.float64], goal: NDArray[np.float64], moving: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """(N, 2) preferred velocities: towards the goal, capped at v_max, turned ``keep_right``."""
        sc = self.scenario
        assert sc is not None
        wish = self.config.goal_gain * (goal - position) + moving
        speed = np.hypot(wish[:, 0], wish[:, 1])
        wish = wish * np.minimum(1.0, sc.v_max / np.maximum(speed, 1e-12))[:, None]
        c, s = math.cos(self.config.keep_right), math.sin(self.config.keep_right)
        return np.column_stack([c * wish[:, 0] + s * wish[:, 1], c * wish[:, 1] - s * wish[:, 0]])

    def _orca(
        self,
        position: NDArray[np.float64],
        velocity: NDArray[np.float64],
        preferred: NDArray[np.float64],
        heard: NDArray[np.bool_],
        movers: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """One ORCA step from one robot's view: the team (those ``heard`` of) at ``position``
        with ``velocity`` (N, 2) wishing ``preferred``, and the movers (C, 4). Returns the new
        velocities (N, 2; zero for a robot not heard of)."""
        sc = self.scenario
        assert sc is not None
        sim = self._sim
        self._agents_for(len(movers))
        for j in range(sc.n_robots):
            if heard[j]:
                self._place(
                    j,
                    position[j],
                    velocity[j],
                    preferred[j],
                    float(sc.robot_radius[j]) + self.config.radius_margin,
                )
            else:
                self._park(j)
        for c in range(self._movers_held):
            agent = sc.n_robots + c
            if c < len(movers):
                x, y, vx, vy = movers[c]
                sim.set_agent_max_speed(agent, max(float(math.hypot(vx, vy)), 1e-3))
                self._place(
                    agent, (x, y), (vx, vy), (vx, vy), float(self._mover_radii[c]) + self.config.mover_margin
                )
            else:
                self._park(agent)
        sim.do_step()
        out = np.zeros((sc.n_robots, 2))
        for robot in np.flatnonzero(heard):
            v = sim.get_agent_velocity(int(robot))
            out[robot] = (v.x, v.y)
        return out
