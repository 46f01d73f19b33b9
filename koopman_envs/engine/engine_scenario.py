"""The scenario of an engine's environment: what a model-based controller may know of its
episode (:class:`~koopman_envs.scenario.Scenario`), from the episode's layout and the config."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from koopman_envs.engine.config import EngineConfig
from koopman_envs.params import PARAMS
from koopman_envs.scenario import Scenario
from koopman_envs.sim.maps import MapSpec

__all__ = ["engine_scenario"]


def engine_scenario(
    config: EngineConfig,
    spec: MapSpec | None,
    obstacles: NDArray[np.float64],
    starts: NDArray[np.float64],
    targets: NDArray[np.float64],
    offsets: NDArray[np.float64],
    settle_steps: int,
) -> Scenario:
    """The scenario of one environment: its map ``spec``, obstacles (M, 3), planned starts
    (N, 3), targets (3, N) and formation offsets (2, N) as the engine holds them.

    Raises
    ------
    RuntimeError
        The environment has not been reset (``spec`` is None).
    """
    if spec is None:
        raise RuntimeError("call reset() before reading the scenario")
    layout = config.observation_layout
    return Scenario(
        task=config.task.name,
        map_name=spec.name,
        n_robots=config.n_robots,
        obstacles=obstacles.copy(),
        robot_radius=config.robot_radius.copy(),
        starts=starts.copy(),
        targets=targets.T.copy(),
        formation_offsets=offsets.T.copy(),
        leader=0,
        v_max=PARAMS.v_max,
        omega_max=PARAMS.omega_max,
        workspace=PARAMS.workspace,
        dt=PARAMS.dt,
        goal_tolerance=config.goal_tolerance,
        settle_steps=settle_steps,
        lidar_beams=layout.beams,
        message_ages=layout.comm,
        n_movers=config.movers.count,
        mover_radius=config.movers.radius,
        mover_slots=layout.movers,
        observation_layout=layout,
        **config.lidar_datasheet,
    )
