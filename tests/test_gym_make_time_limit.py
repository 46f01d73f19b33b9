"""``gym.make(..., max_episode_steps=N)`` is Gymnasium's own TimeLimit wrapper, never the env's
keyword (docs/environments.md, ``max_episode_steps``): any positive integer is accepted there (a
Python counter, ``10**12`` meaning no practical limit), while the env's keyword, kept in the
compiled step as a 64-bit integer, is bounded. This holds the documented decision both ways."""

from __future__ import annotations

import gymnasium as gym
import pytest
from gymnasium.envs.registration import load_env_creator
from gymnasium.wrappers import TimeLimit

import koopman_envs  # noqa: F401  # registers the ids
from koopman_envs.params import LIMITS

ENV = "KoopNav-TargetReaching-v0"


def test_gym_makes_time_limit_takes_a_huge_count_and_counts_in_python() -> None:
    env = gym.make(ENV, max_episode_steps=10**12)
    try:
        assert isinstance(env, TimeLimit) and env.spec is not None
        assert env.spec.max_episode_steps == 10**12
        env.reset(seed=0)
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        assert not truncated  # one step of 10**12
    finally:
        env.close()


def test_the_envs_own_keyword_is_bounded() -> None:
    # the registered class itself: gym.make keeps max_episode_steps for its TimeLimit
    entry_point = gym.spec(ENV).entry_point
    assert isinstance(entry_point, str)
    TargetReachingEnv = load_env_creator(entry_point)
    with pytest.raises(ValueError, match=rf"max_episode_steps={LIMITS.episode_steps + 1} must be an integer"):
        TargetReachingEnv(max_episode_steps=LIMITS.episode_steps + 1)
    TargetReachingEnv(max_episode_steps=LIMITS.episode_steps).close()  # the bound itself is allowed
