"""PettingZoo's official API and seed tests on both tasks."""

from __future__ import annotations

import numpy as np
import pytest
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test

from koopman_envs import formation_v0, target_reaching_v0

MODULES = [target_reaching_v0, formation_v0]


@pytest.mark.parametrize("module", MODULES)
@pytest.mark.parametrize("map_name", [None, "random"])
def test_parallel_api(module, map_name) -> None:
    kwargs = {} if map_name is None else {"map": map_name}
    parallel_api_test(module.parallel_env(slip="high", **kwargs), num_cycles=300)


@pytest.mark.parametrize("module, map_name", [(target_reaching_v0, "map5"), (formation_v0, "map6")])
@pytest.mark.parametrize("slip", ["high", "drift"])
def test_parallel_api_on_the_slip_zone_maps(module, map_name: str, slip: str) -> None:
    parallel_api_test(module.parallel_env(map=map_name, slip=slip), num_cycles=300)


@pytest.mark.parametrize("module", MODULES)
def test_parallel_seed_with_zones_and_drift(module) -> None:
    zones = {"n_slip_zones": 2}
    parallel_seed_test(lambda: module.parallel_env(map="random", random_map=zones, slip="drift"))


@pytest.mark.parametrize("module", MODULES)
def test_parallel_seed(module) -> None:
    parallel_seed_test(lambda: module.parallel_env(map="random", slip="high"))


@pytest.mark.parametrize("module", MODULES)
def test_aec_api(module) -> None:
    api_test(module.env(slip="low"), num_cycles=100)


@pytest.mark.parametrize("module", MODULES)
def test_raw_env_is_unwrapped_aec(module) -> None:
    from pettingzoo import AECEnv

    assert isinstance(module.raw_env(), AECEnv)


def test_parallel_matches_gym_env() -> None:
    """The per-agent front runs the same core: same seed and actions, same poses."""
    import gymnasium as gym

    par = formation_v0.parallel_env(map="map4", slip="high")
    single = gym.make("KoopNav-Formation-v0", map="map4", slip="high")
    observations, _ = par.reset(seed=5)
    obs, _ = single.reset(seed=5)
    np.testing.assert_array_equal(np.concatenate([observations[a] for a in par.possible_agents]), obs)
    rng = np.random.default_rng(0)
    for _ in range(50):
        action = rng.uniform(-0.6, 0.6, 6).astype(np.float32)
        observations, rewards, _, _, infos = par.step(
            {a: action[2 * i : 2 * i + 2] for i, a in enumerate(par.possible_agents)}
        )
        obs, reward, _, _, info = single.step(action)
        np.testing.assert_array_equal(infos["robot_0"]["poses"], info["poses"])
        np.testing.assert_array_equal(par.state(), obs)
