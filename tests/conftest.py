"""Shared fixtures: small hand-made maps for exact scenarios."""

from __future__ import annotations

import pytest

from koopman_envs.sim.maps import MapSpec


@pytest.fixture
def open_map() -> MapSpec:
    """Three robots in an obstacle-free area, targets 1 m ahead."""
    return MapSpec(
        "open",
        obstacles=[],
        starts=[[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]],
        targets=[[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, -1.0, 0.0]],
    )


@pytest.fixture
def parked_map() -> MapSpec:
    """Every robot starts on its target: success after the settling time with zero commands."""
    poses = [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]]
    return MapSpec("parked", obstacles=[[3.0, 3.0, 0.5]], starts=poses, targets=poses)
