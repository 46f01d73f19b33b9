"""What a set policy reads on beams: the observation blocks a state-sensing env would have given,
rebuilt from what the team's lidars show.

A set policy (:mod:`baselines.set_features`) reads each robot's nearest obstacles and movers as
sets. Under ``sensing="lidar"`` the env lists no obstacles (the beams replace them) and no
movers; the perception front (:mod:`controllers.perception.front`, run by
:meth:`controllers.base.BaseController.act` for every controller that perceives) turns the beams
into tracked movers and, with the map unknown, a local map of obstacles. This module lists those
exactly as the env lists the true ones under ``sensing="state"``: it runs the env's own
observation builder (:class:`koopman_envs.tasks.observation.FeatureBuilder`, the same compiled
kernels) on the robots' pose estimates, their messages, the obstacles the planner knows (the
map's, or the local map's) and the moving tracks. So a policy trained on listed obstacles reads
the perceived ones in the same units, order and clipping, and with the map known and nothing
unmapped in view the blocks equal the state env's bit for bit (tests/test_perceived_policy.py).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from numpy.typing import NDArray

from koopman_envs import Observed
from koopman_envs.builder.keywords import ENV_KEYWORDS
from koopman_envs.layout import ObservationLayout
from koopman_envs.movers import MoverConfig
from koopman_envs.scenario import Scenario
from koopman_envs.sim.geometry import TeamGeometry
from koopman_envs.tasks.observation import FeatureBuilder

__all__ = ["LISTED_MOVERS", "LISTED_OBSTACLES", "perceived_blocks"]

#: obstacles a state-sensing env lists per robot by default (what the shipped policies read)
LISTED_OBSTACLES: int = next(k.default for k in ENV_KEYWORDS if k.name == "n_obstacle_obs")
#: movers a state-sensing env lists per robot by default (``movers.observed``)
LISTED_MOVERS: int = MoverConfig().observed


def perceived_blocks(
    observed: Observed,
    scenario: Scenario,
    n_obstacle_obs: int = LISTED_OBSTACLES,
    mover_slots: int = LISTED_MOVERS,
) -> NDArray[np.float64]:
    """The team's observation, flat (N * F,), in the layout of a state-sensing env with
    ``n_obstacle_obs`` listed obstacles, ``mover_slots`` listed movers and the scenario's message
    ages, built from what the team observes after the perception front.

    Parameters
    ----------
    observed : Observed
        ``observed_poses`` (N, 3), ``known_poses`` (N, N, 3), ``message_age`` (N, N),
        ``targets`` (N, 3) and where present ``observed_movers`` (C, 4: x, y, vx, vy) and
        ``mover_tracked`` (C,).
    scenario : Scenario
        The planner's scenario: its ``obstacles`` are what the planner knows (the map's with
        ``lidar.map_known``, else the local map the perception handed on), its
        ``formation_offsets``, radii and ``mover_radius`` those of the env.
    n_obstacle_obs, mover_slots : int
        Obstacles and movers listed per robot, as in the env the policy was trained in.
    """
    n = scenario.n_robots
    if observed.targets is None:
        raise ValueError("perceived_blocks needs the targets; this Observed has none")
    own = observed.observed_poses.reshape(n, 3)
    known = observed.known_poses
    age = observed.message_age.reshape(1, n, n)
    obstacles = np.asarray(scenario.obstacles, dtype=np.float64).reshape(-1, 3)
    listed = np.zeros((0, 4)) if observed.observed_movers is None else observed.observed_movers
    movers = np.array(listed, dtype=np.float64).reshape(1, -1, 4)
    if (
        observed.mover_tracked is not None
    ):  # the env's tracker (sensing="state"): a mover without a track is not listed
        movers[0, ~observed.mover_tracked] = np.nan
    layout = ObservationLayout(
        n, n_obstacle_obs, scenario.is_formation, comm=scenario.message_ages, movers=mover_slots
    )
    builder = FeatureBuilder(1, layout, len(obstacles), mover_radius=scenario.mover_radius)
    geometry = TeamGeometry(1, np.asarray(scenario.robot_radius, dtype=np.float64), len(obstacles))
    geometry.set_obstacles(0, obstacles)
    poses = own.T[None]  # (1, 3, N)
    perception = SimpleNamespace(
        observed=np.ascontiguousarray(poses),
        known=np.ascontiguousarray(known.reshape(1, n, n, 3)),
        age=age,
        ranges=np.zeros((1, n, 0)),
    )
    target = np.ascontiguousarray(observed.targets.reshape(n, 3).T[None])
    offsets = np.ascontiguousarray(
        np.asarray(scenario.formation_offsets, dtype=np.float64).reshape(n, 2).T[None]
    )
    blocks, _ = builder.build(
        poses,
        target,
        geometry,
        offsets if scenario.is_formation else None,
        perception,  # type: ignore[arg-type]  # the Perception fields the builder reads
        movers,
    )
    return blocks.reshape(-1)
