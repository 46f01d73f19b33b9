"""The ekf: estimator (controllers/estimation.py): a per-robot unicycle EKF in front of any
controller, closer to the truth than the raw localization, with checked options."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import controllers
import koopman_envs  # noqa: F401 - registers the ids
from controllers.estimation import PoseEstimator


class _Recorder(controllers.BaseController):
    """Drives at a constant command and keeps the poses it was given."""

    name = "recorder"

    def _reset(self, scenario, seed):
        self.seen = []

    def _act(self, observation, info):
        self.seen.append(np.array(info["observed_poses"]))
        return np.tile([0.3, 0.1], len(info["observed_poses"]))


def test_the_estimate_is_closer_to_the_truth_than_the_measurement() -> None:
    env = gym.make(
        "KoopNav-TargetReaching-v0", pose_noise={"xy": 0.1, "heading": 0.05}, max_episode_steps=200
    )
    inner = _Recorder()
    ekf = PoseEstimator(inner, position_std=0.1, heading_std=0.05)
    obs, info = env.reset(seed=3)
    ekf.reset(env, seed=3)
    raw, estimated = [], []
    for _ in range(80):
        command = ekf.act(obs, info)
        raw.append(info["observed_poses"][:, :2] - info["poses"][:, :2])
        estimated.append(inner.seen[-1][:, :2] - info["poses"][:, :2])
        obs, _, terminated, truncated, info = env.step(command)
        if terminated or truncated:
            break
    raw_rmse = np.sqrt(np.mean(np.square(raw[10:])))
    ekf_rmse = np.sqrt(np.mean(np.square(estimated[10:])))
    assert ekf_rmse < 0.7 * raw_rmse, (ekf_rmse, raw_rmse)
    assert "estimator" in ekf.stats().extra_times


def test_the_prefix_builds_any_controller_and_checks_its_options() -> None:
    ctrl = controllers.make("ekf:consensus", ekf_position_std=0.05, goal_gain=0.5)
    assert ctrl.name == "ekf:consensus" and ctrl.inner.goal_gain == 0.5
    with pytest.raises(
        ValueError, match=r"unknown estimator option 'ekf_positon_std' \(did you mean 'ekf_position_std'\?\)"
    ):
        controllers.make("ekf:consensus", ekf_positon_std=0.05)
    with pytest.raises(ValueError, match=r"ekf_delay=-1 must be an integer >= 0"):
        controllers.make("ekf:consensus", ekf_delay=-1)
    names = [o.name for o in controllers.options("ekf:nominal-nmpc").options]
    assert "ekf_position_std" in names and "horizon" in names
