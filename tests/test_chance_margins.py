"""Chance-constrained margins of the NMPCs (controllers/mpc/controller.py, ``chance_risk``): an
estimator's pose covariance widens every collision margin by z sigma, more for a larger
covariance, not at all without one.

The NMPC acting here is ``nominal-nmpc-v0``, the hand-set defaults: the tuned ``nominal-nmpc``
also widens its margins by the calibrated residual, so it acts only after ``calibrate``."""

from __future__ import annotations

import statistics

import gymnasium as gym
import numpy as np
import pytest

import controllers
import koopman_envs  # noqa: F401 - registers the ids
from controllers.mpc.margins import chance_tightening
from koopman_envs.sim.maps.map_spec import MapSpec

Z95 = statistics.NormalDist().inv_cdf(0.95)


def test_the_tightening_is_z_sigma_along_the_worst_direction() -> None:
    cov = np.zeros((3, 3, 3))
    cov[0, :2, :2] = np.diag([0.02**2, 0.01**2])  # worst direction: x, 2 cm
    cov[1, :2, :2] = [[0.0002, 0.0001], [0.0001, 0.0002]]  # eigenvalues 3e-4 and 1e-4
    cov[2] = np.diag([0.0, 0.0, 0.5])  # heading only: no position margin
    per_robot, per_pair = chance_tightening(cov, 0.05, 3)
    sigma = np.array([0.02, np.sqrt(3e-4), 0.0])
    assert per_robot == pytest.approx(Z95 * sigma, rel=1e-12)
    assert per_pair == pytest.approx(
        Z95 * np.sqrt([sigma[0] ** 2 + sigma[1] ** 2, sigma[0] ** 2, sigma[1] ** 2]), rel=1e-12
    )
    # a smaller risk, a larger z; a larger covariance, a larger margin
    assert np.all(chance_tightening(cov, 0.01, 3)[0][:2] > per_robot[:2])
    assert np.all(chance_tightening(4 * cov, 0.05, 3)[0][:2] == pytest.approx(2 * per_robot[:2]))


def test_no_covariance_no_tightening_and_bad_covariances_are_named() -> None:
    per_robot, per_pair = chance_tightening(None, 0.05, 4)
    assert np.array_equal(per_robot, np.zeros(4)) and np.array_equal(per_pair, np.zeros(6))
    with pytest.raises(ValueError, match=r"pose_covariance has shape \(2, 3, 3\)"):
        chance_tightening(np.zeros((2, 3, 3)), 0.05, 3)
    with pytest.raises(ValueError, match="non-finite"):
        chance_tightening(np.full((3, 3, 3), np.nan), 0.05, 3)


@pytest.mark.parametrize("risk", [0, 0.5, 0.7, -0.1, float("nan"), "0.1"])
def test_chance_risk_outside_0_and_half_is_refused(risk) -> None:
    with pytest.raises(ValueError, match=f"chance_risk={risk!r} must"):
        controllers.make("nominal-nmpc", chance_risk=risk)


def test_the_nmpc_keeps_farther_from_an_obstacle_the_less_certain_it_is() -> None:
    """One solve next to an obstacle: with a covariance handed on, the planned path keeps a wider
    berth; without one, the plan is the paper's, bit for bit as before."""
    # one robot whose straight path to its target runs through an obstacle: the plan skirts it
    detour = MapSpec(
        "detour", obstacles=[[1.2, 0.05, 0.3]], starts=[[0.0, 0.0, 0.0]], targets=[[2.4, 0.0, 0.0]]
    )
    env = gym.make("KoopNav-TargetReaching-v0", map=detour, n_robots=1)
    obs, info = env.reset(seed=0)
    scenario = env.unwrapped.scenario
    plans = {}
    for label, covariance in (("none", None), ("small", 0.01**2), ("large", 0.08**2)):
        ctrl = controllers.make("nominal-nmpc-v0", solver="rti", fallback_solver=None)
        ctrl.reset(env, seed=0)
        view = dict(info)
        if covariance is not None:
            view["pose_covariance"] = np.tile(
                np.diag([covariance, covariance, 1e-4]), (scenario.n_robots, 1, 1)
            )
        for _ in range(8):  # real-time iterations from the same state converge the plan
            ctrl.act(obs, view)
        _, poses = ctrl.last_plan
        clearance = (
            np.linalg.norm(poses[:, :, None, :2] - scenario.obstacles[None, None, :, :2], axis=-1)
            - scenario.obstacles[None, None, :, 2]
        )
        plans[label] = clearance.min() - scenario.robot_radius[0]
        assert ctrl.stats().counts.get("tightened", 0) == (0 if covariance is None else 8)
    assert plans["none"] < plans["small"] < plans["large"], plans
    # the berth grows by about the margins' difference (z sigma: 1.6 cm, then 13 cm)
    assert plans["large"] - plans["none"] > 0.08, plans


def test_the_distributed_nmpc_passes_each_robot_its_covariance_and_widens_team_mates() -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map="map2")
    obs, info = env.reset(seed=0)
    n = env.unwrapped.scenario.n_robots
    plain = controllers.make("dmpc-nominal", solver="rti")
    plain.reset(env, seed=0)
    plain.act(obs, info)
    wide = controllers.make("dmpc-nominal", solver="rti")
    wide.reset(env, seed=0)
    covariance = np.tile(np.diag([0.05**2, 0.05**2, 1e-4]), (n, 1, 1))
    wide.act(obs, {**info, "pose_covariance": covariance})
    assert np.array_equal(plain._pair_tightening, np.zeros(n))
    assert wide._pair_tightening == pytest.approx(np.full(n, Z95 * 0.05 * np.sqrt(2)))
    assert wide.stats().counts["tightened"] == n and plain.stats().counts.get("tightened", 0) == 0


def test_a_robot_near_its_goal_under_an_uncertain_estimate_holds_still_and_moves_again_when_pushed_off() -> (
    None
):
    env = gym.make("KoopNav-TargetReaching-v0", map="map1")
    obs, info = env.reset(seed=0)
    scenario = env.unwrapped.scenario
    ctrl = controllers.make("nominal-nmpc-v0", solver="rti", fallback_solver=None)
    ctrl.reset(env, seed=0)
    covariance = np.tile(np.diag([0.01**2, 0.01**2, 1e-4]), (scenario.n_robots, 1, 1))
    tolerance = scenario.goal_tolerance
    n = scenario.n_robots

    def seen(poses, **extra):  # every robot's estimate, heard at once over the radio
        return {**info, "observed_poses": poses, "known_poses": np.broadcast_to(poses, (n, n, 3)), **extra}

    poses = scenario.targets.copy()
    poses[0, 0] += 0.4 * tolerance  # robot 0 within half the tolerance: settles
    poses[1, 0] += 2.0  # robot 1 far away: drives
    poses[2, 0] += 0.6 * tolerance  # robot 2 between a half and 3/4 of it: not settled yet
    command = ctrl.act(obs, seen(poses, pose_covariance=covariance)).reshape(-1, 2)
    assert np.array_equal(command[0], [0.0, 0.0]) and np.any(command[1] != 0) and np.any(command[2] != 0)
    poses[0, 0] = scenario.targets[0, 0] + 0.7 * tolerance  # pushed off, still within 3/4: stays settled
    command = ctrl.act(obs, seen(poses, pose_covariance=covariance)).reshape(-1, 2)
    assert np.array_equal(command[0], [0.0, 0.0])
    poses[0, 0] = scenario.targets[0, 0] + 0.8 * tolerance  # beyond 3/4: moves again
    command = ctrl.act(obs, seen(poses, pose_covariance=covariance)).reshape(-1, 2)
    assert np.any(command[0] != 0)
    # without a covariance (the paper's setting) nothing settles
    plain = controllers.make("nominal-nmpc-v0", solver="rti", fallback_solver=None)
    plain.reset(env, seed=0)
    poses[0, 0] = scenario.targets[0, 0] + 0.4 * tolerance
    assert np.any(plain.act(obs, seen(poses)).reshape(-1, 2)[0] != 0)


def test_the_safety_filter_widens_its_barriers_by_the_estimate_uncertainty() -> None:
    """A robot driving at an obstacle 0.3 m past its filter margin: left alone without a covariance,
    braked when the estimate is uncertain enough that z sigma eats the clearance."""
    from controllers.safety.barriers import BarrierFilter
    from controllers.safety.options import SafetyOptions

    detour = MapSpec("wall", obstacles=[[1.0, 0.0, 0.3]], starts=[[0.0, 0.0, 0.0]], targets=[[2.0, 0.0, 0.0]])
    env = gym.make("KoopNav-TargetReaching-v0", map=detour, n_robots=1)
    env.reset(seed=0)
    scenario = env.unwrapped.scenario
    barrier = BarrierFilter(scenario, SafetyOptions())
    pose = np.array([[1.0 - 0.3 - scenario.robot_radius[0] - 0.05 - 0.02 - 0.3, 0.0, 0.0]])
    full_ahead = np.array([[0.3, 0.0]])
    plain = barrier.filter(pose, full_ahead)
    assert not plain.changed.any()
    widened = barrier.filter(pose, full_ahead, widen=np.array([0.3]))
    assert widened.changed.all() and widened.command[0, 0] < plain.command[0, 0]
    assert widened.barrier_min < plain.barrier_min
    # the wrapper: safe:consensus takes the consensus's estimator in front of both
    ctrl = controllers.make("safe:consensus")
    assert ctrl.front_end is not None and ctrl.inner.front_end is None
    assert controllers.make("safe:consensus", estimator="none").front_end is None
    with pytest.raises(ValueError, match=r"safety filter option safety_chance_risk=0.5 is out of range"):
        controllers.make("safe:consensus", safety_chance_risk=0.5)
