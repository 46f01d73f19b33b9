"""Success after settling, the settled final distance, truncation, rewards."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from koopman_envs.params import PARAMS
from koopman_envs.sim.collision import CollisionKind


def test_success_after_two_seconds_of_settling(parked_map) -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map=parked_map)
    env.reset(seed=0)
    zero = np.zeros(6)
    for step in range(1, PARAMS.settle_steps):
        _, _, terminated, _, info = env.step(zero)
        assert not terminated and info["settled_steps"] == step
    _, reward, terminated, truncated, info = env.step(zero)
    assert terminated and not truncated and info["is_success"] and not info["collision"]
    assert reward > 5  # the success bonus
    np.testing.assert_array_equal(info["distances"], 0.0)


def test_leaving_the_tolerance_restarts_the_settling_clock(parked_map) -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map=parked_map, goal_tolerance=0.05)
    env.reset(seed=0)
    for _ in range(10):
        env.step(np.zeros(6))
    _, _, _, _, info = env.step(np.array([0.6, 0, 0, 0, 0, 0]))  # robot 0 moves 6 cm away
    assert info["settled_steps"] == 0 and info["distances"][0] > 0.05


def test_final_distance_is_the_settled_distance(open_map) -> None:
    """A robot that crosses the tolerance and comes to rest reports where it rests."""
    env = gym.make("KoopNav-TargetReaching-v0", map=open_map, n_robots=1)
    env.reset(seed=0)
    # 17 periods at 0.55 m/s: inside the 0.1 m tolerance from period 17 on (6.5 cm short)
    for _ in range(17):
        _, _, _, _, info = env.step(np.array([0.55, 0.0]))
    assert info["settled_steps"] == 1
    terminated = False
    steps = 0
    while not terminated:
        _, _, terminated, _, info = env.step(np.zeros(2))
        steps += 1
    assert info["is_success"] and steps == PARAMS.settle_steps - 1
    np.testing.assert_allclose(info["distances"], [0.065], atol=1e-9)


def test_truncation_at_the_time_limit(open_map) -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map=open_map, max_episode_steps=7)
    env.reset(seed=0)
    for _ in range(6):
        assert env.step(np.zeros(6))[3] is False
    assert env.step(np.zeros(6))[3] is True


def test_default_time_limit_is_registered() -> None:
    assert gym.spec("KoopNav-Formation-v0").max_episode_steps == PARAMS.max_episode_steps


def test_progress_reward_sign(open_map) -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map=open_map)
    env.reset(seed=0)
    forward = env.step(np.array([0.6, 0.0] * 3))[1]
    backward = env.step(np.array([-0.6, 0.0] * 3))[1]
    assert forward > 0 > backward


def test_formation_reward_charges_the_true_slot_error() -> None:
    """With zero commands and no slip nothing moves: the reward is the progress and formation
    terms of the engine's state (the error ``info`` reports), not a copy read from the observation."""
    env = gym.make("KoopNav-Formation-v0", map="map4")
    env.reset(seed=0)
    engine = env.unwrapped.engine
    poses = engine.poses.copy()
    poses[0, 2, :2] += [0.5, -0.3]  # robot 3 out of its slot
    engine.poses = poses
    before = engine.distances[0].copy()
    _, reward, _, _, info = env.step(np.zeros(6))
    weights = env.unwrapped.config.task.reward
    assert info["formation_error"][2] == pytest.approx(np.hypot(0.5, 0.3))
    expected = (
        weights.progress * (before - info["distances"]).sum()
        - weights.formation * info["formation_error"].sum()
    )
    assert reward == pytest.approx(expected, rel=1e-12)


def test_robot_collision_names_the_robots_that_collided() -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map="map1")
    env.reset(seed=0)
    engine = env.unwrapped.engine
    poses = engine.poses.copy()
    poses[0, 1, :2] = engine.obstacles[0, 0, :2]  # robot 1 onto the first obstacle's centre
    engine.poses = poses
    _, _, terminated, _, info = env.step(np.zeros(6))
    assert terminated and "obstacle" in CollisionKind.describe(info["collision_code"])
    assert info["robot_collision"].tolist() == [False, True, False]
