"""The simulator core: RK4 against the analytic circle, slip statistics, collisions."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from koopman_envs.engine.config import EngineConfig
from koopman_envs.engine.engine import NavigationEngine
from koopman_envs.sim.collision import CollisionKind, check_collisions
from koopman_envs.sim.dynamics import rk4_step, slip_velocity
from koopman_envs.sim.maps.map_spec import MapSpec


def circle(t: np.ndarray, v: float, w: float) -> np.ndarray:
    """Slip-free unicycle from (0, 0, 0) under constant (v, w): a circle of radius v / w."""
    r = v / w
    return np.stack([r * np.sin(w * t), r * (1 - np.cos(w * t)), w * t], axis=-1)


@pytest.mark.parametrize("dt", [0.1, 0.05])
def test_rk4_follows_the_analytic_circle(dt: float) -> None:
    v, w, steps = 0.3, 0.3, int(round(21.0 / dt))
    pose = np.zeros((1, 3))
    command = np.array([[v, w]])
    no_slip = np.zeros((1, 3))
    error = 0.0
    for k in range(1, steps + 1):
        pose = rk4_step(pose, command, no_slip, dt)
        error = max(error, np.abs(pose[0] - circle(np.array(k * dt), v, w)).max())
    assert error < 1e-7


def test_rk4_is_fourth_order_under_slip() -> None:
    """Against a fine-step reference, halving dt shrinks the error about 16-fold."""
    pose0 = np.array([[0.3, -0.2, 0.4]])
    command = np.array([[0.6, 0.7]])
    slip = np.array([[0.3, 0.2, 0.5]])

    def run(dt: float, t_end: float = 2.0) -> np.ndarray:
        pose = pose0.copy()
        for _ in range(int(round(t_end / dt))):
            pose = rk4_step(pose, command, slip, dt)
        return pose

    ref = run(0.001)
    e1 = np.abs(run(0.2) - ref).max()
    e2 = np.abs(run(0.1) - ref).max()
    assert 12 < e1 / e2 < 20


def test_rk4_matches_the_vector_field_for_small_steps() -> None:
    pose = np.array([[1.0, 2.0, 0.3], [0.0, 0.0, -2.0]])
    command = np.array([[0.5, 0.2], [-0.4, 0.6]])
    slip = np.array([[0.1, 0.2, 0.3], [0.0, 0.05, 0.0]])
    dt = 1e-6
    numeric = (rk4_step(pose, command, slip, dt) - pose) / dt
    np.testing.assert_allclose(numeric, slip_velocity(pose, command, slip), atol=1e-5)


def test_slip_is_exponential_with_mean_lambda(open_map: MapSpec) -> None:
    """Recover alpha, beta, gamma from one-period displacements; their means match lambda."""
    lambdas = [0.0, 0.1, 0.2]
    cfg = EngineConfig.create("target_reaching", map=open_map, slip=lambdas)
    engine = NavigationEngine(cfg)
    engine.reset_env(0, np.random.default_rng(12345))
    v, w, dt, n = 0.6, 0.5, 0.1, 4000
    command = np.tile([v, w], (1, 3, 1))
    start = engine.poses.copy()
    start[..., 2] = 0.0
    samples = np.zeros((n, 3, 3))
    for k in range(n):
        engine.poses = start.copy()
        engine.step(command)
        x, y, th = engine.poses[0].T
        gamma = th / (w * dt) - 1.0
        # exact per-period motion with heading rate w(1+gamma): integrate the rotation analytically
        rate = w * (1 + gamma)
        sinc = np.sin(rate * dt) / (rate * dt)
        cosc = (1 - np.cos(rate * dt)) / (rate * dt)
        dx, dy = x - start[0, :, 0], y - start[0, :, 1]
        # [dx, dy] = v dt [[sinc, cosc], [cosc, -sinc]] @ [1 + beta, alpha]
        det = -(sinc**2) - cosc**2
        fwd = (-sinc * dx - cosc * dy) / det / (v * dt)
        side = (-cosc * dx + sinc * dy) / det / (v * dt)
        samples[k] = np.stack([side, fwd - 1.0, gamma], axis=-1)
    means = samples.mean(axis=0)  # (robot, coefficient)
    np.testing.assert_allclose(samples[:, 0], 0.0, atol=1e-7)  # robot 1 is slip-free
    for i, lam in enumerate(lambdas[1:], start=1):
        # RK4 vs the exact flow differs by O(dt^5): far below the statistical tolerance
        se = lam / np.sqrt(n)  # an exponential's SD equals its mean
        assert np.all(np.abs(means[i] - lam) < 4 * se), (i, means[i], lam)
        assert np.all(np.abs(samples[:, i].std(axis=0) - lam) < 0.1 * lam)
        assert samples[:, i].min() > -1e-6  # one-sided: slip only adds


def test_nominal_robot_has_no_slip(open_map: MapSpec) -> None:
    env = gym.make("KoopNav-TargetReaching-v0", map=open_map, slip=[0.0, 0.0, 0.0])
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([0.6, 0.0] * 3))
    expected = rk4_step(np.array(open_map.starts), np.tile([0.6, 0.0], (3, 1)), np.zeros((3, 3)))
    np.testing.assert_array_equal(info["poses"], expected)


def test_collision_kinds_are_detected() -> None:
    radius = np.full(2, 0.2)
    obstacle = np.array([[0.0, 0.0, 0.5]])
    ws = (-10.0, 10.0, -10.0, 10.0)
    assert check_collisions([[0.69, 0.0], [3.0, 0.0]], obstacle, radius, ws) == CollisionKind.OBSTACLE
    assert check_collisions([[0.71, 0.0], [3.0, 0.0]], obstacle, radius, ws) == CollisionKind.NONE
    assert check_collisions([[2.0, 2.0], [2.39, 2.0]], obstacle, radius, ws) == CollisionKind.ROBOT
    assert check_collisions([[2.0, 2.0], [2.41, 2.0]], obstacle, radius, ws) == CollisionKind.NONE
    assert check_collisions([[10.01, 2.0], [3.0, 0.0]], obstacle, radius, ws) == CollisionKind.WORKSPACE
    both = check_collisions([[0.6, 0.0], [0.9, 0.0]], obstacle, radius, ws)
    assert both == CollisionKind.OBSTACLE | CollisionKind.ROBOT
    assert CollisionKind.describe(both) == "obstacle+robot"


@pytest.mark.parametrize(
    "starts, command, kind",
    [
        ([[0.0, 0.0, 0.0], [0.0, 3.0, 0.0]], [0.6, 0.0, 0.0, 0.0], "obstacle"),
        ([[-1.0, -3.0, 0.0], [1.0, -3.0, np.pi]], [0.6, 0.0, 0.6, 0.0], "robot"),
        ([[9.0, -3.0, 0.0], [0.0, 3.0, 0.0]], [0.6, 0.0, 0.0, 0.0], "workspace"),
    ],
)
def test_env_terminates_on_each_collision_kind(starts, command, kind) -> None:
    spec = MapSpec("crash", obstacles=[[1.5, 0.0, 0.5]], starts=starts, targets=[[0, -6, 0], [0, 6, 0]])
    env = gym.make("KoopNav-TargetReaching-v0", map=spec, n_robots=2)
    env.reset(seed=0)
    for _ in range(100):
        _, reward, terminated, truncated, info = env.step(np.array(command))
        if terminated:
            break
    assert terminated and not truncated
    assert (
        info["collision"]
        and CollisionKind.describe(info["collision_code"]) == kind
        and not info["is_success"]
    )
    assert reward < -5  # the collision penalty


def test_compiled_rk4_matches_numpy_arithmetic_bit_for_bit() -> None:
    """The compiled kernel does numpy's operations in numpy's order (no fused multiply-add)."""
    rng = np.random.default_rng(3)
    pose = rng.uniform([-9, -9, -np.pi], [9, 9, np.pi], (4000, 3))
    command = rng.uniform([-0.5, -0.8], [0.5, 0.8], (4000, 2))
    slip = rng.exponential(0.2, (4000, 3))
    dt = 0.1
    x, y, th = pose.T
    forward = (slip[:, 1] + 1.0) * command[:, 0]
    side = slip[:, 0] * command[:, 0]
    turn = (slip[:, 2] + 1.0) * command[:, 1]
    stages = np.stack([th, turn * (0.5 * dt) + th, turn * dt + th])
    weights = (np.array([1.0, 4.0, 1.0]) * (dt / 6.0))[:, None]
    cw = (np.cos(stages[0]) * weights[0] + np.cos(stages[1]) * weights[1]) + np.cos(stages[2]) * weights[2]
    sw = (np.sin(stages[0]) * weights[0] + np.sin(stages[1]) * weights[1]) + np.sin(stages[2]) * weights[2]
    expected = np.stack([forward * cw + side * sw + x, forward * sw - side * cw + y, stages[2]], axis=-1)
    np.testing.assert_array_equal(rk4_step(pose, command, slip, dt), expected)
