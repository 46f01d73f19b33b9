"""Shared fixtures: small hand-made maps for exact scenarios."""

from __future__ import annotations

import os

import pytest

# NMPC solvers run uncompiled in the tests: the suite builds dozens of one-off problem structures,
# and compiling each once (30-60 s on a fresh machine) would dominate its run time. The compiled
# path and its cache have their own tests (tests/test_solver_cache.py), which set jit explicitly.
# Set before any controller is built; worker processes and subprocesses inherit it.
os.environ.setdefault("KOOPNAV_NMPC_JIT", "0")

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
