"""The physics plant (``plant="mujoco"``) beyond tests/test_physics_plant.py: pickling a world
mid-episode, rendering the bodies' poses, straight-line lag per surface, friction zones, and
PettingZoo's target-reaching front."""

from __future__ import annotations

import pickle
from typing import Any, cast

import gymnasium as gym
import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

import koopman_envs  # noqa: E402, F401 - registers the ids

TR = "KoopNav-TargetReaching-v0"


def test_a_physics_env_pickled_mid_episode_steps_on_bit_for_bit() -> None:
    """The world drops the ``mujoco`` module, its thread pool and its array views from a pickle
    and makes them again on load; the loaded env and the original then step alike."""
    env: Any = gym.make(TR, plant="mujoco", slip="low", map="map1").unwrapped
    env.reset(seed=5)
    actions = np.random.default_rng(5).uniform(-1, 1, (40, 6)).astype(np.float32) * env.action_space.high
    for action in actions[:10]:
        env.step(action)
    copy = pickle.loads(pickle.dumps(env))
    for action in actions[10:]:
        one, two = env.step(action), copy.step(action)
        np.testing.assert_array_equal(one[0], two[0])
        assert one[1:4] == two[1:4]
        np.testing.assert_array_equal(one[4]["poses"], two[4]["poses"])
        if one[2] or one[3]:
            break
    # the views are the loaded world's own arrays, not copies: a write reaches MuJoCo's data
    world = copy.engine.physics
    world._ctrl_views[0][0] = 123.0
    assert world.datas[0].ctrl[0] == 123.0


def test_a_pickled_vector_world_steps_on_its_threads() -> None:
    """A batch pickled after a threaded period (pool made) loads without the pool and makes it again."""
    venv = gym.make_vec(TR, num_envs=2, plant="mujoco")
    venv.reset(seed=1)
    actions = np.random.default_rng(1).uniform(-0.5, 0.5, (12, 2, 6)).astype(np.float32)
    for action in actions[:4]:
        venv.step(action)
    world = cast(Any, venv.unwrapped).engine.physics
    assert world.threads > 1 and world._pool is not None
    copy = pickle.loads(pickle.dumps(venv.unwrapped))
    assert copy.engine.physics._pool is None
    for action in actions[4:]:
        one, two = venv.step(action), copy.step(action)
        np.testing.assert_array_equal(one[0], two[0])
        np.testing.assert_array_equal(one[1], two[1])
    venv.close()
