"""What a set policy reads on beams: the observation blocks a state-sensing env would have given,
rebuilt from what the team's lidars show.

A set policy (:mod:`baselines.features.set_features`) reads each robot's nearest obstacles and movers as
sets. Under ``sensing="lidar"`` the env lists no obstacles (the beams replace them) and no
movers; the perception front (:mod:`controllers.perception.front`, run by
:meth:`controllers.base.BaseController.act` for every controller that perceives) turns the beams
into tracked movers and, with the map unknown, a local map of obstacles. This module lists those
exactly as the env lists the true ones under ``sensing="state"``: it runs the env's own
observation builder (:func:`koopman_envs.observation_from_beliefs`, the same compiled
kernels) on the robots' pose estimates, their messages, the obstacles the planner knows (the
map's, or the local map's) and the moving tracks. So a policy trained on listed obstacles reads
the perceived ones in the same units, order and clipping, and with the map known and nothing
unmapped in view the blocks equal the state env's bit for bit (tests/test_perceived_policy.py).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from koopman_envs import ENV_KEYWORDS, Observed, observation_from_beliefs
from koopman_envs.scenario import Scenario
from koopman_envs.settings import MoverConfig

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
    age = observed.message_age.reshape(n, n)
    listed = np.zeros((0, 4)) if observed.observed_movers is None else observed.observed_movers
    movers = np.array(listed, dtype=np.float64).reshape(-1, 4)
    if (
        observed.mover_tracked is not None
    ):  # the env's tracker (sensing="state"): an untracked mover is not listed
        movers[~observed.mover_tracked] = np.nan
    blocks = observation_from_beliefs(
        scenario, own, observed.known_poses, age, observed.targets, movers, n_obstacle_obs, mover_slots
    )
    return blocks.reshape(-1)
