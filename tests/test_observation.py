"""The compiled observation kernel against the layout documented in koopman_envs.tasks.observation."""

from __future__ import annotations

import numpy as np
import pytest

from koopman_envs.engine.config import EngineConfig
from koopman_envs.engine.engine import NavigationEngine
from koopman_envs.tasks.observation import FAR


def _expected_block(state, target, obstacles, radius, offsets, i, n_obstacle_obs, formation):
    """Robot i's block written straight from the module docstring's table (plain numpy)."""
    x, y, th = state[i]
    c, s = np.cos(th), np.sin(th)

    def body(dx, dy):
        return [c * dx + s * dy, c * dy - s * dx]

    tx, ty, tth = target[i]
    row = [x, y, c, s, *body(tx - x, ty - y), np.hypot(tx - x, ty - y), np.cos(tth - th), np.sin(tth - th)]
    for j in range(len(state)):
        if j != i:
            dx, dy = state[j, 0] - x, state[j, 1] - y
            row += [*body(dx, dy), np.hypot(dx, dy) - 2 * radius]
    gaps = np.hypot(obstacles[:, 0] - x, obstacles[:, 1] - y) - obstacles[:, 2] - radius
    for m in np.argsort(gaps, kind="stable")[:n_obstacle_obs]:
        row += [*body(obstacles[m, 0] - x, obstacles[m, 1] - y), gaps[m]]
    row += [0.0, 0.0, FAR] * (n_obstacle_obs - min(n_obstacle_obs, len(obstacles)))
    if formation:
        row += list(state[i, :2] - state[0, :2] - offsets[i])
    return np.array(row)


@pytest.mark.parametrize(
    "task, map_name, n_obstacle_obs",
    [("target_reaching", "map1", 4), ("formation", "map4", 2), ("target_reaching", "map2", 9)],
)
def test_features_follow_the_documented_layout(task: str, map_name: str, n_obstacle_obs: int) -> None:
    config = EngineConfig.create(task, map=map_name, n_obstacle_obs=n_obstacle_obs)
    engine = NavigationEngine(config, num_envs=2)
    rng = np.random.default_rng(7)
    for k in range(2):
        engine.reset_env(k, rng)
    poses = rng.uniform([-8, -8, -np.pi], [8, 8, np.pi], (2, config.n_robots, 3))
    poses[1, 0, :2] = [25.0, -25.0]  # outside the workspace: entries must be clipped into bounds
    engine.poses = poses
    features = engine.features()
    assert features.shape == (2, config.n_robots, engine.feature_size)
    for k in range(2):
        scenario = engine.scenario(k)
        for i in range(config.n_robots):
            expected = _expected_block(
                poses[k],
                scenario.targets,
                scenario.obstacles,
                0.2,
                scenario.formation_offsets,
                i,
                n_obstacle_obs,
                config.task.formation,
            )
            expected = np.clip(expected, engine.feature_low, engine.feature_high)
            np.testing.assert_allclose(features[k, i], expected, rtol=0, atol=1e-12)
    assert features[1, 0, 0] == 20.0 and features[1, 0, 1] == -20.0
