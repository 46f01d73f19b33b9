"""What a model-based controller may know about an episode: geometry, goals, limits, timing.

The scenario deliberately carries no slip parameters: a controller that needs a model of the
slipping robots has to learn it from data. Slip zones are map data (``MapSpec.slip_zones``, with
their lambdas), not part of the scenario either.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from koopman_envs.layout import ObservationLayout

__all__ = ["Scenario", "scenario_of"]


@dataclass(frozen=True, eq=False)
class Scenario:
    """Geometry and limits of the current episode (``env.unwrapped.scenario``).

    Attributes
    ----------
    task : str
        ``"target_reaching"`` or ``"formation"``.
    map_name : str
        Name of the map in use.
    n_robots : int
        Team size N.
    obstacles : ndarray, shape (M, 3)
        Obstacle centre x, y and radius [m].
    robot_radius : ndarray, shape (N,)
        Robot radii [m].
    starts : ndarray, shape (N, 3)
        Start poses (x [m], y [m], theta [rad]) as planned: the map's (or the reset options'),
        without the ``start_noise`` perturbation, which a controller learns only through the
        robots' localization (the true starts are in the env's ``info["poses"]`` at reset).
    targets : ndarray, shape (N, 3)
        Target poses.
    formation_offsets : ndarray, shape (N, 2)
        Target position of each robot relative to the leader's (robot 0) [m].
    leader : int
        Index of the leader robot (0).
    v_max, omega_max : float
        Actuation limits [m/s], [rad/s].
    workspace : tuple of float
        (x_min, x_max, y_min, y_max) [m].
    dt : float
        Control period [s].
    goal_tolerance : float
        Success tolerance on each robot's distance to its target [m].
    settle_steps : int
        Periods every robot must stay within tolerance for success.
    lidar_beams : int
        Lidar readings in each robot's observation block (``sensing="lidar"``; 0: the block lists
        the nearest obstacles instead).
    message_ages : bool
        Whether each block ends with the team-mates' message ages and arrival flags (a ``comm``
        setting): the observation layout a learned policy must expect.
    n_movers : int
        Moving obstacles per episode (``movers`` keyword; their states are in the info).
    mover_radius : float
        Their disc radius [m].
    mover_slots : int
        Movers listed at the end of each robot's observation block (0 with lidar).
    observation_layout : ObservationLayout, optional
        One robot's observation block by name (:mod:`koopman_envs.layout`; the envs fill
        it; None for a scenario built by hand).
    lidar_fov, lidar_range, lidar_noise : float
        The lidar's field of view [rad], range [m] and range noise (standard deviation) [m]: its
        datasheet, which a robot's perception knows (``sensing="lidar"``; defaults otherwise).
    map_known : bool
        Whether the planners may use ``obstacles`` (``lidar.map_known``); when False a
        controller plans on :meth:`planner_view`, which holds none.
    """

    task: str
    map_name: str
    n_robots: int
    obstacles: NDArray[np.float64]
    robot_radius: NDArray[np.float64]
    starts: NDArray[np.float64]
    targets: NDArray[np.float64]
    formation_offsets: NDArray[np.float64]
    leader: int
    v_max: float
    omega_max: float
    workspace: tuple[float, float, float, float]
    dt: float
    goal_tolerance: float
    settle_steps: int
    lidar_beams: int = 0
    message_ages: bool = False
    n_movers: int = 0
    mover_radius: float = 0.0
    mover_slots: int = 0
    observation_layout: ObservationLayout | None = None
    lidar_fov: float = 2 * math.pi
    lidar_range: float = 5.0
    lidar_noise: float = 0.0
    map_known: bool = True

    @property
    def is_formation(self) -> bool:
        """True for the leader-follower formation task."""
        return self.task == "formation"

    def planner_view(self) -> Scenario:
        """What a planner may know: this scenario, without the map's obstacles when the map is
        not known (``lidar.map_known=False``: the beams are all the robots have of them)."""
        if self.map_known:
            return self
        return replace(self, obstacles=np.zeros((0, 3)))


def scenario_of(source: Any) -> Scenario:
    """The scenario of ``source``: a :class:`Scenario` itself, or any KoopNav env (Gymnasium,
    wrapped or not, or PettingZoo) after its ``reset``.

    Raises
    ------
    TypeError
        ``source`` is neither (the message names its type).
    """
    if isinstance(source, Scenario):
        return source
    for candidate in (getattr(source, "unwrapped", None), source):
        scenario = getattr(candidate, "scenario", None) if candidate is not None else None
        if isinstance(scenario, Scenario):
            return scenario
    raise TypeError(
        f"expected a koopman_envs.Scenario or a KoopNav env (after reset), got {type(source).__name__}"
    )
