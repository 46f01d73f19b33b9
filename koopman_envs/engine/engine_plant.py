"""The engine's plant pass: one control period of the robots' motion, kinematic or physical.

:func:`make_physics` builds the physics plant's worlds for an engine (``plant="mujoco"``; None
on the kinematic plant) and :func:`advance_plant` runs the period on whichever plant the engine
has: the paper's unicycle with drawn slip (:func:`~koopman_envs.sim.dynamics.advance_teams`,
after the slip zones' pass) or the MuJoCo robots
(:meth:`~koopman_envs.sim.physics.world.PhysicsWorld.advance`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from koopman_envs.params import PARAMS
from koopman_envs.sim.dynamics import advance_teams

__all__ = ["advance_plant", "make_physics"]


def make_physics(config: Any, num_envs: int) -> Any:
    """The :class:`~koopman_envs.sim.physics.world.PhysicsWorld` of an engine of ``num_envs``
    environments of ``config`` (an :class:`~koopman_envs.engine.config.EngineConfig`), or None
    on the kinematic plant (MuJoCo is imported only here, for ``plant="mujoco"``)."""
    if config.plant != "mujoco":
        return None
    from koopman_envs.sim.physics.world import PhysicsWorld

    return PhysicsWorld(
        num_envs,
        config.n_robots,
        config.n_obstacles,
        config.n_slip_zones,
        float(np.max(config.robot_radius)),
        config.floor,
    )


def advance_plant(
    engine: Any, commands: NDArray[np.float64], active: NDArray[np.bool_] | None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The poses (K, 3, N) one period after ``engine.state`` under ``commands`` (K, N, 2), and
    the commands' effort (K, N), for the ``active`` environments (None: all) of ``engine`` (a
    :class:`~koopman_envs.engine.engine.NavigationEngine`; typed ``Any`` so that the two
    modules do not import each other)."""
    stepping = engine.all_active if active is None else active
    new = np.empty_like(engine.state)
    effort = np.empty(engine.distances.shape)
    limits = (engine.command_low, engine.command_high, engine.effort_scale)
    if engine.physics is not None:
        engine.physics.advance(engine.state, commands, stepping, *limits, new, effort)
        return new, effort
    slip = engine.slip
    slip.prepare(active)
    # one branch per step: maps without zones scale the draws by the base levels directly
    means = slip.lambdas
    if engine.zones is not None:
        means = engine.zones.slip_means(engine.state, slip.lambdas, engine.zone_means)
    advance_teams(
        engine.state, commands, slip.unit, slip.cursor, means, stepping, *limits, PARAMS.dt, new, effort
    )
    return new, effort
