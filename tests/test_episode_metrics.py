"""The per-episode metrics robotics papers report (koopman_envs/fronts/episode.py): clearance, path
ratio, smoothness, against values computed by hand on scripted episodes."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from evaluation.aggregate import episode_metrics
from koopman_envs.fronts.episode import run_episode
from koopman_envs.sim.maps import MapSpec

#: one robot driving straight along the x axis past one obstacle, and a second parked far away
LANE = MapSpec(
    "lane",
    obstacles=[[1.0, 0.7, 0.2]],
    starts=[[0.0, 0.0, 0.0], [0.0, -3.0, 0.0]],
    targets=[[2.0, 0.0, 0.0], [0.0, -3.0, 0.0]],
)


class _Script:
    """Drives robot 0 at 0.5 m/s for ``steps`` periods, then stops; robot 1 stands still."""

    def __init__(self, steps: int) -> None:
        self.steps, self.t = steps, 0

    def act(self, observation, info):
        self.t += 1
        return np.array([0.5 if self.t <= self.steps else 0.0, 0.0, 0.0, 0.0])


def test_clearance_path_ratio_and_smoothness_by_hand() -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map=LANE, n_robots=2, max_episode_steps=60)
    result = run_episode(env, _Script(40), seed=0)  # 40 periods of 0.1 s at 0.5 m/s: 2 m
    radius = env.unwrapped.scenario.robot_radius
    # the obstacle at (1.0, 0.7), radius 0.2: closest when robot 0 passes x = 1.0
    assert result.min_clearance["obstacle"] == pytest.approx(0.7 - radius[0] - 0.2, abs=1e-9)
    assert result.min_clearance["robot"] == pytest.approx(3.0 - radius[0] - radius[1], abs=1e-9)
    assert result.min_clearance["mover"] is None
    np.testing.assert_allclose(result.straight_distance, [2.0, 0.0], atol=1e-12)
    assert result.path_length[0] == pytest.approx(2.0, abs=1e-9)
    # the command steps 0 -> 0.5 m/s at the first period and 0.5 -> 0 at the 41st: two changes
    # of 5 m/s^2 over the episode's periods
    steps = result.steps
    assert result.accel_rms[0] == pytest.approx(math.sqrt(2 * 5.0**2 / steps))
    assert result.accel_rms[1] == 0.0 and np.all(result.angular_accel_rms == 0.0)


def test_the_movers_clearance_is_the_smallest_over_the_episode() -> None:
    env = gym.make("KoopNav-TargetReaching-v0", movers={"count": 4}, max_episode_steps=30)
    seen = []
    result = run_episode(env, _Zero(), seed=1, on_step=lambda _s, _a, info: seen.append(info["movers"]))
    scenario = env.unwrapped.scenario
    xy = result.trajectory[0, :, :2]  # the robots stand still
    by_hand = min(
        float((np.linalg.norm(xy[:, None] - m[None, :, :2], axis=-1) - scenario.robot_radius[:, None]).min())
        - scenario.mover_radius
        for m in seen
    )
    # the episode's start is measured too, so the smallest is at most the steps' smallest
    assert result.min_clearance["mover"] <= by_hand + 1e-12
    assert result.min_clearance["mover"] > by_hand - 0.05  # one period of mover travel at most


class _Zero:
    def act(self, observation, info):
        return np.zeros(2 * len(info["poses"]))


def test_the_table_metrics_pool_episodes_as_stated() -> None:
    # the second robot of the failure starts at its target: left out of its ratio
    records = [
        {
            "success": True,
            "time_to_goal": 10.0,
            "path_length": [3.0, 2.0],
            "straight_distance": [2.0, 2.0],
            "min_clearance": {"obstacle": 0.05, "robot": 0.3, "mover": None},
            "accel_rms": [1.0, 3.0],
        },
        {
            "success": False,
            "time_to_goal": None,
            "path_length": [1.0, 4.0],
            "straight_distance": [1.0, 0.05],
            "min_clearance": {"obstacle": 0.2, "robot": -0.01, "mover": None},
            "accel_rms": [0.0, 0.0],
        },
        {
            "success": True,
            "time_to_goal": 20.0,
            "path_length": [2.0, 2.0],
            "straight_distance": [2.0, 2.0],
            "min_clearance": {"obstacle": 0.1, "robot": 0.4, "mover": 0.02},
            "accel_rms": [2.0, 2.0],
        },
    ]
    metrics = episode_metrics(records)
    assert metrics["time_to_goal_s"] == 15.0
    # over the successes: (1.25 + 1.0) / 2 (the failure's path ended early)
    assert metrics["path_ratio"] == pytest.approx((1.25 + 1.0) / 2)
    assert metrics["min_clearance_cm"] == pytest.approx(2.0)  # median of 5, -1, 2 cm
    assert metrics["accel_rms"] == pytest.approx((2.0 + 0.0 + 2.0) / 3)
    # records written before the metrics existed: NaN, not an error
    old = episode_metrics([{"success": False, "time_to_goal": None, "path_length": [1.0]}])
    assert all(math.isnan(v) for v in old.values())
