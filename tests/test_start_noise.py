"""``start_noise``: seeded, bounded, valid perturbations of the start poses on every front."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test, parallel_seed_test

import koopman_envs
from koopman_envs import formation_v0, load_map, target_reaching_v0
from koopman_envs.fronts import gym_env, vector_env
from koopman_envs.fronts import parallel_env as parallel_front
from koopman_envs.params import PARAMS
from koopman_envs.sim.collision import check_collisions
from koopman_envs.sim.dynamics import wrap_angle
from koopman_envs.sim.maps.map_spec import MapSpec

TR, FO = koopman_envs.ENV_IDS
FIXED = [(TR, "map1"), (TR, "map2"), (FO, "map3"), (FO, "map4")]


def reset_starts(env_id: str, seed: int, **kwargs) -> np.ndarray:
    """Where the robots truly start (the engine's record; controllers are told the map's)."""
    env = gym.make(env_id, **kwargs)
    env.reset(seed=seed)
    return env.unwrapped.engine.starts[0].copy()


@pytest.mark.parametrize("env_id, map_name", FIXED)
@pytest.mark.parametrize("noise", [None, 0.0, 0])
def test_zero_noise_keeps_the_map_starts(env_id: str, map_name: str, noise) -> None:
    kwargs = {} if noise is None else {"start_noise": noise}
    env = gym.make(env_id, map=map_name, **kwargs)
    _, info = env.reset(seed=4)
    expected = load_map(map_name).starts[:3]
    np.testing.assert_array_equal(env.unwrapped.scenario.starts, expected)
    np.testing.assert_array_equal(info["poses"], expected)
    assert env.unwrapped.config.start_noise == 0.0


@pytest.mark.parametrize("map_name", ["map1", "random"])
def test_zero_noise_draws_nothing(map_name: str) -> None:
    """No draw at start_noise=0: the generator is where it was before the option existed."""
    plain = gym.make(TR, map=map_name, slip="random")
    zero = gym.make(TR, map=map_name, slip="random", start_noise=0.0)
    noisy = gym.make(TR, map=map_name, slip="random", start_noise=0.1)
    for env in (plain, zero, noisy):
        env.reset(seed=8)
    state = plain.unwrapped.np_random.bit_generator.state
    assert zero.unwrapped.np_random.bit_generator.state == state
    assert noisy.unwrapped.np_random.bit_generator.state != state
    np.testing.assert_array_equal(plain.unwrapped.scenario.starts, zero.unwrapped.scenario.starts)
    np.testing.assert_array_equal(plain.unwrapped.lambdas, zero.unwrapped.lambdas)


@pytest.mark.parametrize("env_id, map_name", [(TR, "map1"), (FO, "map4"), (FO, "random")])
def test_seeded_noise(env_id: str, map_name: str) -> None:
    a = reset_starts(env_id, 1, map=map_name, start_noise=0.3)
    b = reset_starts(env_id, 1, map=map_name, start_noise=0.3)
    c = reset_starts(env_id, 2, map=map_name, start_noise=0.3)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a[:, :2], c[:, :2]) and not np.array_equal(a[:, 2], c[:, 2])
    if map_name != "random":
        assert not np.array_equal(a, load_map(map_name).starts[:3])


@pytest.mark.parametrize("env_id, map_name", [*FIXED, (TR, "random"), (FO, "random")])
def test_noise_within_bounds_and_valid(env_id: str, map_name: str) -> None:
    noise = 0.4
    env = gym.make(env_id, map=map_name, start_noise=noise)
    env.reset(seed=0)
    shifts, turns = [], []
    for _ in range(60):
        _, info = env.reset()
        engine = env.unwrapped.engine
        spec = engine.maps[0]
        base = spec.starts[:3]
        starts = engine.starts[0]
        np.testing.assert_array_equal(starts, info["poses"])  # the engine records the starts used
        # the scenario a controller is handed tells the planned starts, not the perturbed ones
        np.testing.assert_array_equal(env.unwrapped.scenario.starts, base)
        shifts.append(np.hypot(*(starts[:, :2] - base[:, :2]).T))
        turns.append(wrap_angle(starts[:, 2] - base[:, 2]))
        assert np.all((starts[:, 2] >= -np.pi) & (starts[:, 2] < np.pi))
        assert spec.pose_problem(starts, PARAMS.robot_radius) is None
        assert check_collisions(starts[:, :2], spec.obstacles, np.full(3, 0.2), PARAMS.workspace) == 0
        assert not info["collision"]
    shifts, turns = np.concatenate(shifts), np.concatenate(turns)
    assert shifts.max() <= noise and np.abs(turns).max() <= noise + 1e-12
    # the draws fill the disc and the heading interval rather than sitting at the map's start
    assert shifts.max() > 0.9 * noise and turns.min() < -0.9 * noise and turns.max() > 0.9 * noise
    assert np.mean(shifts < noise / np.sqrt(2)) == pytest.approx(0.5, abs=0.15)  # uniform in area


def tight_map() -> MapSpec:
    """Robots 0.45 m apart (0.4 m needed) and robot 2 0.05 m from an obstacle: most draws overlap."""
    return MapSpec(
        "tight",
        obstacles=[[3.0, 0.0, 0.5]],
        starts=[[0.0, 0.0, 0.0], [0.45, 0.0, 3.1], [2.25, 0.0, -3.1]],
        targets=[[0.0, 5.0, 0.0], [1.0, 5.0, 0.0], [2.0, 5.0, 0.0]],
    )


def test_invalid_draws_are_redrawn() -> None:
    spec = tight_map()
    env = gym.make(TR, map=spec, start_noise=0.3)
    env.reset(seed=0)
    for _ in range(100):
        _, info = env.reset()
        starts = env.unwrapped.engine.starts[0]
        assert spec.pose_problem(starts, PARAMS.robot_radius) is None
        assert not info["collision"]
        # headings near +-pi wrap into [-pi, pi) like the simulator's
        assert np.all((starts[:, 2] >= -np.pi) & (starts[:, 2] < np.pi))
        assert np.all(np.abs(wrap_angle(starts[:, 2] - spec.starts[:, 2])) <= 0.3 + 1e-12)


def test_no_valid_draw_raises() -> None:
    env = gym.make(TR, map="map1", start_noise=50.0)
    with pytest.raises(RuntimeError, match=r"start_noise=50\.0: no valid start poses on map 'map1' in 100"):
        env.reset(seed=0)


@pytest.mark.parametrize("module, env_id", [(target_reaching_v0, TR), (formation_v0, FO)])
def test_pettingzoo_front(module, env_id: str) -> None:
    par = module.parallel_env(slip="high", start_noise=0.25)
    single = gym.make(env_id, slip="high", start_noise=0.25)
    observations, _ = par.reset(seed=6)
    obs, _ = single.reset(seed=6)
    np.testing.assert_array_equal(par.engine.starts, single.unwrapped.engine.starts)
    np.testing.assert_array_equal(np.concatenate([observations[a] for a in par.possible_agents]), obs)
    assert not np.array_equal(par.engine.starts[0], load_map(par.config.map_name).starts[:3])
    np.testing.assert_array_equal(par.scenario.starts, load_map(par.config.map_name).starts[:3])
    clone = pickle.loads(pickle.dumps(par))  # copies the config with the state
    assert clone.config.start_noise == 0.25


@pytest.mark.parametrize("module", [target_reaching_v0, formation_v0])
def test_pettingzoo_api_with_noise(module) -> None:
    parallel_api_test(module.parallel_env(map="random", start_noise=0.3), num_cycles=100)
    parallel_seed_test(lambda: module.parallel_env(slip="high", start_noise=0.3))


@pytest.mark.parametrize("env_id", koopman_envs.ENV_IDS)
@pytest.mark.parametrize("map_name", [None, "random"])
def test_check_env_with_noise(env_id: str, map_name) -> None:
    kwargs = {} if map_name is None else {"map": map_name}
    env = gym.make(env_id, start_noise=0.3, **kwargs)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_documented() -> None:
    for cls in (gym_env.TargetReachingEnv, gym_env.FormationEnv):
        assert "| start_noise" in cls.__doc__ and "start_noise" in cls.__doc__.split("## Starting State")[1]
    assert "start_noise" in parallel_front.KoopNavParallelEnv.__doc__
    assert "start_noise" in vector_env.KoopNavVectorEnv.__doc__


def test_a_controller_is_handed_the_scenario_with_the_planned_starts_only() -> None:
    """run_episode resets a controller with the episode's Scenario (never the env), whose starts
    are the map's: where each robot truly starts it learns from its localization."""
    from koopman_envs.episodes.single import run_episode
    from koopman_envs.scenario import Scenario

    class Spy:
        def reset(self, scenario, seed=None):
            self.scenario = scenario

        def act(self, observation, info):
            self.first = getattr(self, "first", np.array(info["poses"]))
            return np.zeros(6)

    env = gym.make(TR, map="map1", start_noise=0.05, max_episode_steps=2)
    spy = Spy()
    run_episode(env, spy, seed=3)
    assert type(spy.scenario) is Scenario
    np.testing.assert_array_equal(spy.scenario.starts, load_map("map1").starts[:3])
    assert not np.array_equal(spy.first, spy.scenario.starts)  # the truth differs by the noise
