"""The team's reward summed in the scoring kernel (koopman_envs.tasks.reward.numpy_sum) is numpy's
sum bit for bit, for every team size the env takes and beyond numpy's pairwise block."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from numba import njit

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs.params import LIMITS
from koopman_envs.tasks.reward import numpy_sum


@njit  # not cached: a cache here would not see numpy_sum change
def _row_sums(values: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
    for k in range(values.shape[0]):
        out[k] = numpy_sum(values[k], 0, values.shape[1])


def _bits(values: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(values, dtype=np.float64).view(np.int64)


@pytest.mark.parametrize("n", [*range(1, 40), 127, 128, 129, 135, 200, 255, LIMITS.robots, 1000])
def test_the_kernels_sum_is_numpys_bit_for_bit(n: int) -> None:
    rng = np.random.default_rng(n)
    # magnitudes 16 orders apart, so that every change of the order of the additions shows
    values = rng.normal(0.0, 1.0, (64, n)) * rng.choice([1e-8, 1.0, 1e8], (64, n))
    values[::4, ::3] = -0.0
    values[1] = -0.0  # a row of negative zeros sums to +0.0
    out = np.empty(64)
    _row_sums(values, out)
    np.testing.assert_array_equal(_bits(out), _bits(values.sum(-1)))
    np.testing.assert_array_equal(_bits(out[:4]), _bits([np.add.reduce(row) for row in values[:4]]))


def test_a_part_of_a_row_is_summed_as_numpy_sums_the_slice() -> None:
    values = np.random.default_rng(0).normal(0.0, 1e4, 300)
    for start, count in ((0, 0), (5, 3), (7, 17), (1, 131), (40, 260)):
        assert _bits(numpy_sum(values, start, count)) == _bits(np.add.reduce(values[start : start + count]))


@pytest.mark.parametrize("n_robots", [3, 9])
def test_the_engines_reward_is_numpys_sum_of_the_robots_terms_plus_the_teams(n_robots: int) -> None:
    """What the fronts return as the reward: numpy's sum of the robots' own terms, plus the
    team's, bit for bit, over an episode with random commands (inactive environments included)."""
    venv = gym.make_vec("KoopNav-Formation-v0", num_envs=4, n_robots=n_robots, map="random")
    venv.reset(seed=3)
    engine = venv.unwrapped.engine
    rng = np.random.default_rng(0)
    active = np.array([True, False, True, True])
    for step in range(40):
        commands = rng.uniform(-1, 1, (4, n_robots, 2)) * [0.6, 0.8]
        result = engine.step(commands, active=None if step % 3 else active)
        expected = result.robot_reward.sum(-1) + result.team_reward
        np.testing.assert_array_equal(_bits(result.reward), _bits(expected))
