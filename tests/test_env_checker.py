"""Gymnasium's official checker on both ids, several maps and slip settings."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import koopman_envs


@pytest.mark.parametrize("env_id", koopman_envs.ENV_IDS)
@pytest.mark.parametrize("map_name", [*koopman_envs.BUILTIN_MAPS, "random"])
@pytest.mark.parametrize("slip", ["nominal", "high", [0.0, 0.3, 0.05]])
def test_check_env(env_id: str, map_name: str, slip) -> None:
    env = gym.make(env_id, map=map_name, slip=slip)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


@pytest.mark.parametrize(
    "env_id, kwargs",
    [
        ("KoopNav-TargetReaching-v0", {"map": "map5", "slip": "drift"}),
        ("KoopNav-Formation-v0", {"map": "map6", "slip": [(0.0, "low"), (0.5, 0.3)]}),
        ("KoopNav-Formation-v0", {"map": "random", "random_map": {"n_slip_zones": 2}, "slip": "drift"}),
    ],
)
def test_check_env_with_zones_and_schedules(env_id: str, kwargs: dict) -> None:
    env = gym.make(env_id, render_mode="rgb_array", **kwargs)
    check_env(env.unwrapped)
    env.close()


@pytest.mark.parametrize("env_id", koopman_envs.ENV_IDS)
def test_check_env_with_render(env_id: str) -> None:
    env = gym.make(env_id, render_mode="rgb_array")
    check_env(env.unwrapped)
    env.close()


def test_plugin_syntax_in_fresh_interpreter() -> None:
    import subprocess
    import sys

    code = (
        "import gymnasium as gym; env = gym.make('koopman_envs:KoopNav-Formation-v0'); "
        "obs, info = env.reset(seed=0); print(obs.shape, info['poses'].shape)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "(87,) (3, 3)"


@pytest.mark.parametrize("env_id", koopman_envs.ENV_IDS)
def test_info_and_scenario(env_id: str) -> None:
    env = gym.make(env_id, map="map2" if "Target" in env_id else "map4")
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    assert info["poses"].shape == (3, 3) and info["targets"].shape == (3, 3)
    assert info["distances"].shape == (3,)
    assert info["collision"] is False and info["is_success"] is False
    scenario = env.unwrapped.scenario
    np.testing.assert_array_equal(scenario.starts, info["poses"])
    np.testing.assert_array_equal(scenario.targets, info["targets"])
    assert scenario.dt == 0.1 and scenario.v_max == 0.6 and scenario.omega_max == pytest.approx(np.pi / 4)
    assert scenario.obstacles.shape[1] == 3 and scenario.robot_radius.shape == (3,)
    np.testing.assert_allclose(
        scenario.targets[:, :2], scenario.targets[0, :2] + scenario.formation_offsets, atol=1e-12
    )
    assert not hasattr(scenario, "lambdas")  # controllers must learn slip, not read it


def test_formation_targets_follow_the_leader() -> None:
    env = gym.make("KoopNav-Formation-v0", map="map3")
    _, info = env.reset(seed=0)
    spec = koopman_envs.load_map("map3")
    np.testing.assert_allclose(info["targets"][1:, :2] - info["targets"][0, :2], spec.formation_offsets[1:])
    np.testing.assert_allclose(info["targets"][:, 2], info["targets"][0, 2])
    assert "formation_error" in info


def test_actions_saturate_at_the_limits(open_map) -> None:
    env_a = gym.make("KoopNav-TargetReaching-v0", map=open_map)
    env_b = gym.make("KoopNav-TargetReaching-v0", map=open_map)
    env_a.reset(seed=0)
    env_b.reset(seed=0)
    _, _, _, _, info_a = env_a.step(np.array([5.0, 9.0] * 3))
    _, _, _, _, info_b = env_b.step(np.array([0.6, np.pi / 4] * 3))
    np.testing.assert_array_equal(info_a["poses"], info_b["poses"])
