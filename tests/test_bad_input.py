"""Every bad input named by the environments issue raises a clear ValueError."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401
from koopman_envs import formation_v0

ENV = "KoopNav-TargetReaching-v0"


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"map": "map9"}, r"map='map9' is not one of \['map1', 'map2', 'map3', 'map4', 'map5', 'map6', 'random'\]"),
        ({"slip": "extreme"}, r"slip='extreme' is not one of \['nominal', 'low', 'high'\]"),
        ({"slip": [0.0, -0.1, 0.2]}, r"negative lambda; allowed: lambda >= 0"),
        ({"slip": [0.0, float("nan"), 0.2]}, r"non-finite lambda"),
        ({"slip": [0.0, float("inf"), 0.2]}, r"non-finite lambda"),
        ({"slip": [0.0, 0.1]}, r"has 2 values; expected one lambda per robot \(3\)"),
        ({"n_robots": 0}, r"n_robots=0 must be an integer >= 1"),
        ({"n_robots": 4}, r"n_robots=4 is larger than map 'map1' supports \(1..3\)"),
        ({"goal_tolerance": -0.1}, r"goal_tolerance=-0.1 must be a finite number > 0"),
        ({"render_mode": "ascii"}, r"render_mode='ascii' is not one of \['human', 'rgb_array'\]"),
        ({"map": "random", "random_map": {"obstacles": 2}}, r"random_map has unknown fields \['obstacles'\]; allowed"),
        ({"map": "random", "random_map": 3}, r"random_map=3 must be a RandomMapConfig, a dict"),
        ({"start_noise": -0.1}, r"start_noise=-0.1 must be a finite number >= 0"),
        ({"start_noise": -1}, r"start_noise=-1 must be a finite number >= 0"),
        ({"start_noise": float("nan")}, r"start_noise=nan must be a finite number >= 0"),
        ({"start_noise": float("inf")}, r"start_noise=inf must be a finite number >= 0"),
        ({"start_noise": "0.1"}, r"start_noise='0.1' must be a finite number >= 0"),
        ({"start_noise": None}, r"start_noise=None must be a finite number >= 0"),
        ({"start_noise": True}, r"start_noise=True must be a finite number >= 0"),
        ({"start_noise": [0.1, 0.2]}, r"start_noise=\[0.1, 0.2\] must be a finite number >= 0"),
    ],
)
def test_bad_constructor_arguments(kwargs, message) -> None:
    with pytest.raises(ValueError, match=message):
        gym.make(ENV, **kwargs)


def test_bad_arguments_in_every_front() -> None:
    with pytest.raises(ValueError, match="slip='extreme'"):
        formation_v0.parallel_env(slip="extreme")
    with pytest.raises(ValueError, match="map='nowhere'"):
        gym.make_vec(ENV, num_envs=2, map="nowhere")
    with pytest.raises(ValueError, match="start_noise=-0.5 must be a finite number >= 0"):
        formation_v0.parallel_env(start_noise=-0.5)
    with pytest.raises(ValueError, match="start_noise=False must be a finite number >= 0"):
        gym.make_vec(ENV, num_envs=2, start_noise=False)


def test_overlapping_starts_in_a_map_file(tmp_path) -> None:
    path = tmp_path / "bad.json"
    path.write_text(
        json.dumps(
            {
                "obstacles": [],
                "starts": [[0, 0, 0], [0.3, 0, 0], [3, 3, 0]],
                "targets": [[5, 0, 0], [5, 2, 0], [5, 4, 0]],
            }
        )
    )
    with pytest.raises(ValueError, match="overlapping starts of robots 0 and 1"):
        gym.make(ENV, map=str(path))


def test_start_inside_an_obstacle(tmp_path) -> None:
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({"obstacles": [[0, 0, 1]], "starts": [[0.5, 0, 0]], "targets": [[5, 0, 0]]}))
    with pytest.raises(ValueError, match="start of robot 0 .* overlaps obstacle 0"):
        gym.make(ENV, map=str(path), n_robots=1)


@pytest.mark.parametrize("content", ["{not json", "[1, 2]", '{"obstacles": []}'])
def test_malformed_map_files(tmp_path, content) -> None:
    path = tmp_path / "broken.json"
    path.write_text(content)
    with pytest.raises(ValueError, match="broken"):
        gym.make(ENV, map=str(path))


def test_missing_map_file() -> None:
    with pytest.raises(ValueError, match="cannot be read"):
        gym.make(ENV, map="/no/such/map.json")


@pytest.mark.parametrize("action", [np.zeros(5), np.zeros((2, 3)), np.zeros(7)])
def test_wrong_action_shape(action) -> None:
    env = gym.make(ENV)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action has shape .*; expected \(6,\) or \(3, 2\)"):
        env.unwrapped.step(action)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_action(bad) -> None:
    env = gym.make(ENV)
    env.reset(seed=0)
    action = np.zeros(6)
    action[3] = bad
    with pytest.raises(ValueError, match="non-finite value at index"):
        env.unwrapped.step(action)
    # the state is untouched: no silent NaN
    assert np.isfinite(env.unwrapped.engine.poses).all()


def test_bad_parallel_actions() -> None:
    env = formation_v0.parallel_env()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="missing \\['robot_2'\\]"):
        env.step({"robot_0": [0, 0], "robot_1": [0, 0]})
    with pytest.raises(ValueError, match="action of robot_0 has shape"):
        env.step({"robot_0": [0, 0, 0], "robot_1": [0, 0], "robot_2": [0, 0]})
    with pytest.raises(ValueError, match="non-finite"):
        env.step({"robot_0": [np.nan, 0], "robot_1": [0, 0], "robot_2": [0, 0]})


def test_bad_vector_actions() -> None:
    venv = gym.make_vec(ENV, num_envs=2)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match=r"expected \(2, 6\) or \(2, 3, 2\)"):
        venv.step(np.zeros((3, 6)))
