"""The per-episode metrics robotics papers report (koopman_envs/episodes/single.py): clearance, path
ratio, smoothness (acceleration and jerk), the share of time near an obstacle, against values
computed by hand on scripted episodes, and their fields in the evaluator's records."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from evaluation.stats.aggregate import episode_metrics
from koopman_envs.episodes.single import path_ratio, run_episode
from koopman_envs.params import PARAMS, PATH_RATIO_MIN_DISTANCE, STRICT_CLEARANCE_MARGIN
from koopman_envs.sim.maps.map_spec import MapSpec

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


# ------------------------------------------------------------------ the metrics the suite tests
class _Speeds:
    """Drives robot 0 straight ahead at ``speeds[t]`` in period t (0 after the list ends)."""

    def __init__(self, speeds: list[float], n_robots: int = 1) -> None:
        self.speeds, self.n, self.t = speeds, n_robots, 0

    def act(self, observation, info):
        v = self.speeds[self.t] if self.t < len(self.speeds) else 0.0
        self.t += 1
        command = np.zeros(2 * self.n)
        command[0] = v
        return command


def _lone(obstacles: list[list[float]], target: list[float]) -> gym.Env:
    lane = MapSpec("lone", obstacles=obstacles, starts=[[0.0, 0.0, 0.0]], targets=[target])
    return gym.make("KoopNav-TargetReaching-v0", map=lane, n_robots=1, max_episode_steps=20)


def test_a_straight_drive_to_the_target_has_path_ratio_one() -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map=LANE, n_robots=2, max_episode_steps=60)
    result = run_episode(env, _Script(40), seed=0)
    # robot 1 starts on its target: left out, so the team's ratio is robot 0's
    assert result.path_ratio == pytest.approx(1.0, abs=1e-9)
    assert path_ratio(result.path_length, result.straight_distance) == result.path_ratio


def test_path_ratio_is_per_robot_then_mean_and_none_without_a_robot_to_rate() -> None:
    # 2/2 and 3/2 rated, the third starts 5 cm from its target: (1.0 + 1.5) / 2
    assert path_ratio([2.0, 3.0, 0.5], [2.0, 2.0, 0.05]) == pytest.approx(1.25)
    assert path_ratio([0.3], [PATH_RATIO_MIN_DISTANCE]) is None  # at the limit: left out
    assert path_ratio(None, [1.0]) is None and path_ratio([1.0], None) is None


@pytest.mark.parametrize(
    "speeds, expected",
    [
        ([0.5] * 20, 0.0),  # constant speed
        ([0.01 * t for t in range(20)], 0.0),  # constant acceleration
        # a step down from 0.5 to 0 after 10 periods: second differences -0.5 and +0.5 (over dt^2)
        ([0.5] * 10, math.sqrt(2 * (0.5 / 0.1**2) ** 2 / 18)),
    ],
)
def test_jerk_is_the_rms_second_difference_of_the_speed_command(speeds, expected) -> None:
    result = run_episode(_lone([], [9.0, 0.0, 0.0]), _Speeds(speeds), seed=0)
    assert result.steps == 20 and not result.success
    assert result.jerk_rms is not None
    assert result.jerk_rms[0] == pytest.approx(expected, abs=1e-9)
    # the start from standing still is the first command's acceleration, not a jerk
    assert result.accel_rms[0] > 0


def test_an_episode_of_two_periods_has_no_jerk() -> None:
    lane = MapSpec("short", obstacles=[], starts=[[0.0, 0.0, 0.0]], targets=[[9.0, 0.0, 0.0]])
    env = gym.make("KoopNav-TargetReaching-v0", map=lane, n_robots=1, max_episode_steps=2)
    assert run_episode(env, _Speeds([0.5] * 2), seed=0).jerk_rms is None


def test_a_robot_parked_near_an_obstacle_for_half_the_episode_has_share_one_half() -> None:
    radius = PARAMS.robot_radius
    # an obstacle of 0.2 m behind the robot, its surface 3 cm from the robot's: parked for 10
    # periods, then 10 periods forward at 0.5 m/s (5 cm per period: 8 cm after the first)
    behind = [[-(radius + 0.03 + 0.2), 0.0, 0.2]]
    result = run_episode(_lone(behind, [9.0, 0.0, 0.0]), _Speeds([0.0] * 10 + [0.5] * 10), seed=0)
    assert result.steps == 20
    assert result.min_clearance["obstacle"] == pytest.approx(0.03, abs=1e-12)
    assert result.near_obstacle_share.tolist() == [0.5]
    assert result.time_to_goal is None  # not reached: no time to goal
    # the same obstacle 8 cm away: never within the margin
    farther = [[-(radius + STRICT_CLEARANCE_MARGIN + 0.03 + 0.2), 0.0, 0.2]]
    assert (
        run_episode(_lone(farther, [9.0, 0.0, 0.0]), _Speeds([0.0] * 20), seed=0).near_obstacle_share[0]
        == 0.0
    )


def test_the_record_carries_the_new_metrics_and_the_report_reads_them() -> None:
    from types import SimpleNamespace

    from controllers.base import ControllerStats
    from evaluation.episodes.records import json_safe, record_problem
    from evaluation.execution.worker import _result_fields

    radius = PARAMS.robot_radius
    behind = [[-(radius + 0.03 + 0.2), 0.0, 0.2]]
    result = run_episode(_lone(behind, [9.0, 0.0, 0.0]), _Speeds([0.0] * 10 + [0.5] * 10), seed=0)
    fields = json_safe(_result_fields(SimpleNamespace(trial=1), result, ControllerStats()))
    cell = dict(
        key="k", env_id="KoopNav-TargetReaching-v0", controller="c", map="m", slip="nominal", trial=1, seed=0
    )
    record = {**cell, **fields}
    assert record_problem(record) is None
    assert record["near_obstacle_share"] == [0.5]
    assert record["jerk_rms"] == [pytest.approx(math.sqrt(2 * (0.5 / 0.1**2) ** 2 / 18))]
    assert record["path_ratio"] == pytest.approx(0.5 / 9.0)
    assert record["time_to_goal"] is None
    for field, bad in (("near_obstacle_share", [1.5]), ("jerk_rms", [-1.0]), ("path_ratio", "1")):
        assert f"field {field!r}" in record_problem({**record, field: bad})
