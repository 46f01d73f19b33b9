"""Movers observed through a tracker under sensing="state" (koopman_envs/sim/movers/tracking.py):
the batched filter equals filterpy's, tracks are born, reported and dropped by the stated rules,
the estimates are within stated bounds of the truth, the truth stays in info["movers"], and
turning tracking off gives the exact states (the earlier behaviour)."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import predict, update

import koopman_envs  # noqa: F401 - registers the ids
from koopman_envs.sim.movers.tracking import (
    CONFIRM_HITS,
    DROP_AFTER,
    MoverTracker,
    _cv_step_axes,
    _nearest_within,
    _rows_or,
    cv_model,
    cv_predict,
    cv_update,
)

ENV = "KoopNav-TargetReaching-v0"


def test_the_compiled_filter_is_filterpys() -> None:
    rng = np.random.default_rng(0)
    F, Q = cv_model(0.1)
    np.testing.assert_array_equal(
        Q, Q_discrete_white_noise(2, dt=0.1, var=1.0, block_size=2, order_by_dim=False)
    )
    H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
    for _ in range(6):
        x = rng.normal(size=4)
        A = rng.normal(size=(4, 4))
        P = A @ A.T + np.eye(4)
        z = rng.normal(size=2)
        a, b = predict(x, P, F, Q)
        R = np.array([[0.01, 0.004], [0.004, 0.02]])  # a fit's covariance is not isotropic
        c, d = update(a, b, z, R, H)
        x_, P_ = x.copy(), P.copy()
        cv_predict(x_, P_, 0.1, Q)
        np.testing.assert_allclose(x_, a, rtol=0, atol=1e-12)
        np.testing.assert_allclose(P_, b, rtol=0, atol=1e-12)
        cv_update(x_, P_, z[0], z[1], R[0, 0], R[0, 1], R[1, 1], np.empty((6, 4)))
        np.testing.assert_allclose(x_, c, rtol=0, atol=1e-12)
        np.testing.assert_allclose(P_, d, rtol=0, atol=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_the_per_axis_filter_equals_the_4x4_one_bit_for_bit(seed: int) -> None:
    """The env's tracker filters each axis as a 2 x 2 block (_cv_step_axes); over a track's
    life of predictions with and without detections, every entry of x and of P's blocks is
    the 4 x 4 code's (cv_predict, cv_update with R = r I), and the off-block entries stay zero."""
    rng = np.random.default_rng(seed)
    dt, r = 0.1, 0.05**2
    _, Q = cv_model(dt)
    x = np.array([rng.normal(), rng.normal(), 0.0, 0.0])
    P = np.diag([r, r, 4.0, 4.0])  # born as the tracker births a track
    x4, P4 = x.copy(), P.copy()
    blocks = np.zeros((4, 4), dtype=bool)
    blocks[np.ix_([0, 2], [0, 2])] = blocks[np.ix_([1, 3], [1, 3])] = True
    for t in range(300):
        detected = bool(rng.random() < 0.8)
        z0, z1 = rng.normal(size=2) * (1.0 + t / 10)
        _cv_step_axes(x, P, dt, Q, detected, z0, z1, r)
        cv_predict(x4, P4, dt, Q)
        if detected:
            cv_update(x4, P4, z0, z1, r, 0.0, r, np.empty((6, 4)))
        np.testing.assert_array_equal(x, x4, strict=True, err_msg=f"period {t}")
        np.testing.assert_array_equal(P[blocks], P4[blocks], strict=True, err_msg=f"period {t}")
        assert (P[~blocks] == 0).all() and (P4[~blocks] == 0).all()


def _walk(
    tracker: MoverTracker, start: np.ndarray, velocity: np.ndarray, steps: int, robot: np.ndarray
) -> np.ndarray:
    poses = robot.reshape(1, 3, 1)
    for t in range(steps):
        position = start + 0.1 * (t + 1) * velocity
        tracker.step(np.concatenate([position, velocity])[None, None], poses, poses)
    return np.concatenate([position, velocity])


def test_a_track_is_reported_after_its_confirmations_and_dropped_after_drop_after() -> None:
    tracker = MoverTracker(1, 1, 0.1, detection_range=5.0, detection_noise=0.05)
    tracker.reset_env(0, np.random.default_rng(0))
    robot = np.array([0.0, 0.0, 0.0])
    for _ in range(CONFIRM_HITS):
        assert not tracker.observed()[1].any()
        _walk(tracker, np.array([2.0, 0.0]), np.zeros(2), 1, robot)
    assert tracker.observed()[1].all()
    far = np.array([[[20.0, 0.0, 0.0, 0.0]]])  # out of range: unseen
    for _ in range(round(DROP_AFTER / 0.1)):
        tracker.step(far, robot.reshape(1, 3, 1), robot.reshape(1, 3, 1))
        assert tracker.observed()[1].all()  # predicted on
    tracker.step(far, robot.reshape(1, 3, 1), robot.reshape(1, 3, 1))
    assert not tracker.observed()[1].any()


@pytest.mark.parametrize("seed", range(5))
def test_a_mover_on_a_straight_line_is_tracked_within_bounds(seed: int) -> None:
    """5 cm detections: after 2 s, within 10 cm and 0.2 m/s of the truth."""
    tracker = MoverTracker(1, 1, 0.1, detection_range=5.0, detection_noise=0.05)
    tracker.reset_env(0, np.random.default_rng(seed))
    truth = _walk(tracker, np.array([-2.0, 1.0]), np.array([0.5, -0.2]), 20, np.zeros(3))
    estimate = tracker.observed()[0][0, 0]
    assert np.hypot(*(estimate[:2] - truth[:2])) < 0.1
    assert np.hypot(*(estimate[2:] - truth[2:])) < 0.2


def test_the_env_reports_tracks_and_keeps_the_truth() -> None:
    env = gym.make(ENV, map="map1", movers={"count": 6})
    _, info = env.reset(seed=0)
    assert not info["mover_tracked"].any() and not info["observed_movers"].any()  # none confirmed yet
    errors = []
    for _ in range(40):
        _, _, terminated, truncated, info = env.step(np.zeros(6))
        seen = info["mover_tracked"]
        errors += np.hypot(*(info["observed_movers"][seen, :2] - info["movers"][seen, :2]).T).tolist()
        if terminated or truncated:
            break
    assert len(errors) > 50 and np.median(errors) < 0.1
    assert not np.isnan(info["movers"]).any()


def test_tracking_off_gives_the_exact_states() -> None:
    env = gym.make(ENV, map="map1", movers={"count": 4, "tracking": False})
    _, info = env.reset(seed=0)
    for _ in range(5):
        _, _, _, _, info = env.step(np.zeros(6))
    np.testing.assert_array_equal(info["observed_movers"], info["movers"])
    assert info["mover_tracked"].all()


def test_tracking_leaves_the_movers_and_every_other_stream_alone() -> None:
    """The detection noise has its own stream: the movers move the same with tracking on or off,
    and so do the robots under the harsh preset's noise."""
    runs = []
    for tracking in (True, False):
        env = gym.make(ENV, map="map1", uncertainty="harsh", movers={"count": 4, "tracking": tracking})
        _, info = env.reset(seed=3)
        for _ in range(20):
            _, _, _, _, info = env.step(np.full(6, 0.2))
        runs.append((info["movers"], info["poses"], info["observed_poses"]))
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (
            {"movers": {"count": 2, "tracking": "yes"}},
            r"movers.tracking='yes' is not a flag; allowed: true or false",
        ),
        ({"movers": {"count": 2, "detection_range": -1.0}}, r"movers.detection_range"),
        ({"movers": {"count": 2, "detection_noise": float("nan")}}, r"movers.detection_noise"),
        ({"sensing": "lidar", "lidar": {"map_known": "no"}}, r"lidar.map_known='no' is not a flag"),
    ],
)
def test_bad_tracking_and_map_settings_are_refused_by_name(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        gym.make(ENV, **kwargs)


def test_masked_rows_equal_numpys_where() -> None:
    rng = np.random.default_rng(4)
    rows = rng.normal(size=(5, 7, 4))
    rows[0, 0] = -0.0  # a kept negative zero stays negative
    keep = rng.random((5, 7)) < 0.5
    keep[0, 0] = True
    for fill in (0.0, np.nan):
        ours = _rows_or(rows, keep, fill)
        np.testing.assert_array_equal(ours, np.where(keep[..., None], rows, fill), strict=True)
        assert np.signbit(ours[0, 0]).all() and ours is not rows


def _nearest_by_hypot(px: float, py: float, poses: np.ndarray, limit: float) -> tuple[int, bool]:
    best, nearest = math.inf, 0
    for i in range(poses.shape[1]):
        d = math.hypot(px - poses[0, i], py - poses[1, i])
        if d < best:
            best, nearest = d, i
    return nearest, best <= limit


def test_the_nearest_robot_and_the_detection_are_hypots() -> None:
    """Squared distances decide only where they are clearly apart: random teams, exact and
    near ties (one ulp apart), movers on and one ulp around the detection limit, NaN poses."""
    rng = np.random.default_rng(11)
    cases = []
    for _ in range(3000):
        poses = np.zeros((3, int(rng.integers(1, 5))))
        poses[:2] = rng.uniform(-6, 6, (2, poses.shape[1]))
        cases.append((*rng.uniform(-6, 6, 2), poses, 5.0))
    for scale in (1e-3, 1.0, 7.0):
        poses = np.zeros((3, 3))
        poses[:2, 0] = (scale, 0.0)
        poses[:2, 1] = (0.0, scale)  # an exact tie with robot 0 from the origin
        poses[:2, 2] = (np.nextafter(scale, 0.0), 0.0)  # one ulp nearer
        cases += [(0.0, 0.0, poses, 5.0), (0.0, 0.0, poses[:, :2], scale)]
        for limit in (np.nextafter(scale, 0.0), scale, np.nextafter(scale, 10.0)):
            cases.append((0.0, 0.0, poses[:, :1], limit))
    three_four = np.zeros((3, 2))
    three_four[:2, 0] = (3.0, 4.0)  # hypot exactly 5
    three_four[:2, 1] = (4.0, 3.0)
    cases += [(0.0, 0.0, three_four, 5.0), (0.0, 0.0, three_four, np.nextafter(5.0, 0.0))]
    nan = np.zeros((3, 2))
    nan[0, 0] = np.nan
    cases += [(1.0, 1.0, nan, 5.0), (np.nan, 0.0, three_four, 5.0)]
    for px, py, poses, limit in cases:
        assert _nearest_within(px, py, poses, limit) == _nearest_by_hypot(px, py, poses, limit), (
            px,
            py,
            poses,
            limit,
        )


def test_a_tracker_step_before_a_reset_is_refused_by_environment() -> None:
    tracker = MoverTracker(2, 1, 0.1, detection_range=5.0, detection_noise=0.05)
    tracker.reset_env(0, np.random.default_rng(0))
    poses = np.zeros((2, 3, 1))
    with pytest.raises(RuntimeError, match=r"^MoverTracker: environment 1 was stepped before reset\(\)$"):
        tracker.step(np.zeros((2, 1, 4)), poses, poses)
