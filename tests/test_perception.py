"""The lidar perception against scenes whose answer is known (controllers/perception): clusters
and circle fits on analytic scans, a wall, a mover tracked on a straight line, a track dropped
after it leaves the view, and false tracks from noise over many draws."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import koopman_envs  # noqa: F401 - registers the ids
from controllers.perception.front import LidarPerception
from controllers.perception.scan import ScanSettings, cluster_scan, fit_circle, scan_objects
from controllers.perception.tracker import Tracker, TrackerSettings
from koopman_envs import Observed
from koopman_envs.sim.lidar import beam_angles, cast_beams

SETTINGS = ScanSettings()
RANGE = 5.0


def _scan(
    discs: list[list[float]],
    pose: list[float],
    beams: int = 360,
    workspace: tuple[float, ...] = (-50.0, 50.0, -50.0, 50.0),
    noise: float = 0.0,
    rng: np.random.Generator | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The env's own beam caster on ``discs`` seen from ``pose`` (one robot, radius 0.2)."""
    obstacles = np.array(discs, dtype=np.float64).reshape(-1, 3)
    out = np.zeros((1, 1, beams))
    angles = beam_angles(beams, 2 * math.pi)
    cast_beams(
        np.array(pose, dtype=np.float64).reshape(1, 3, 1),
        np.ascontiguousarray(obstacles.T[None]),
        np.array([0.2]),
        angles,
        RANGE,
        np.array(workspace, dtype=np.float64),
        out,
    )
    ranges = out[0, 0]
    if noise:
        assert rng is not None
        hit = ranges < RANGE
        ranges = np.where(hit, np.clip(ranges + rng.normal(0.0, noise, beams), 0.0, RANGE), RANGE)
    return ranges, angles


def test_a_disc_of_known_radius_is_found_where_it_is() -> None:
    pose = np.array([0.0, 0.0, 0.3])
    ranges, angles = _scan([[2.0, 0.5, 0.4]], list(pose))
    found = scan_objects(ranges, angles, RANGE, pose, SETTINGS)
    assert found.discs.shape == (1, 3) and len(found.segments) == 0
    np.testing.assert_allclose(found.discs[0], [2.0, 0.5, 0.4], atol=1e-6)


def test_noisy_fits_are_within_their_stated_covariance() -> None:
    """Over 200 noisy scans (1 cm), the centre's error is inside the 99% ellipse of the fit's own
    covariance in at least 95% of them (the covariance is not overconfident)."""
    rng = np.random.default_rng(0)
    pose = np.array([0.0, 0.0, 0.0])
    inside = 0
    for _ in range(200):
        ranges, angles = _scan([[2.0, 0.5, 0.4]], list(pose), noise=0.01, rng=rng)
        found = scan_objects(ranges, angles, RANGE, pose, SETTINGS)
        assert found.discs.shape == (1, 3)
        error = found.discs[0, :2] - [2.0, 0.5]
        inside += error @ np.linalg.solve(found.disc_covariance[0], error) <= 9.21
        assert abs(found.discs[0, 2] - 0.4) < 0.05
    assert inside >= 190, inside


def test_two_touching_discs_are_two_objects() -> None:
    pose = np.array([0.0, 0.0, 0.0])
    truth = np.array([[2.0, 0.0, 0.4], [2.0, 0.8, 0.4]])
    ranges, angles = _scan(truth.tolist(), list(pose))
    found = scan_objects(ranges, angles, RANGE, pose, SETTINGS)
    assert found.discs.shape == (2, 3)
    for disc in truth:
        nearest = found.discs[np.argmin(np.hypot(*(found.discs[:, :2] - disc[:2]).T))]
        np.testing.assert_allclose(nearest, disc, atol=0.02)


def test_a_wall_is_a_segment_on_its_line() -> None:
    """A robot 1 m from the workspace's east wall: the returns from the wall are segments on
    x = 5 (to rounding) that cover at least y in [-2, 2]; the returns at grazing incidence,
    too far apart to join them, are discs behind the wall."""
    pose = np.array([4.0, 0.0, 0.0])
    ranges, angles = _scan([], list(pose), beams=180, workspace=(-5.0, 5.0, -5.0, 5.0))
    found = scan_objects(ranges, angles, RANGE, pose, SETTINGS)
    assert len(found.segments) >= 1 and np.all(found.discs[:, 0] > 5.0)
    np.testing.assert_allclose(found.segments[:, [0, 2]], 5.0, atol=1e-6)
    low, high = found.segments[:, [1, 3]].min(), found.segments[:, [1, 3]].max()
    assert low <= -2.0 and high >= 2.0


def test_a_cluster_across_the_seam_of_a_full_scan_stays_whole() -> None:
    """Beam 0 looks straight ahead: an object there has returns at the last beams and the first."""
    ranges, angles = _scan([[2.0, 0.0, 0.4]], [0.0, 0.0, 0.0])
    clusters = cluster_scan(ranges, angles, RANGE, SETTINGS)
    assert len(clusters) == 1
    assert 0 in clusters[0] and len(ranges) - 1 in clusters[0]


def test_a_single_dropped_beam_does_not_cut_an_object() -> None:
    ranges, angles = _scan([[2.0, 0.0, 0.4]], [0.0, 0.0, 0.0])
    hit = np.flatnonzero(ranges < RANGE)
    ranges[hit[len(hit) // 2 + 1]] = RANGE  # one return lost (lidar.dropout)
    clusters = cluster_scan(ranges, angles, RANGE, SETTINGS)
    assert len(clusters) == 1 and len(clusters[0]) == len(hit) - 1


def test_a_cluster_too_short_to_fit_gets_the_prior_radius_behind_its_return() -> None:
    pose = np.array([0.0, 0.0, 0.0])
    ranges, angles = _scan([[3.0, 0.0, 0.1]], list(pose), beams=32)
    assert (ranges < RANGE).sum() == 1
    found = scan_objects(ranges, angles, RANGE, pose, SETTINGS)
    np.testing.assert_allclose(found.discs, [[2.9 + SETTINGS.default_radius, 0.0, SETTINGS.default_radius]])
    assert fit_circle(np.array([[2.9, 0.0]]), pose[:2], SETTINGS) is None


def _track_line(
    seed: int, scans: int, beams: int = 32, noise: float = 0.02
) -> tuple[Tracker, np.ndarray, np.ndarray]:
    """A mover of radius 0.2 walking (0.5, -0.3) m/s past a robot at rest, seen by its lidar."""
    rng = np.random.default_rng(seed)
    tracker = Tracker(0.1)
    velocity = np.array([0.5, -0.3])
    pose = np.array([0.0, 0.0, 0.0])
    for t in range(scans):
        position = np.array([-1.5, 2.0]) + 0.1 * t * velocity
        ranges, angles = _scan([[*position, 0.2]], list(pose), beams=beams, noise=noise, rng=rng)
        found = scan_objects(ranges, angles, RANGE, pose, SETTINGS)
        tracks = tracker.step(found.discs, found.disc_covariance)
    return tracker, tracks.states, np.concatenate([position, velocity])


@pytest.mark.parametrize("seed", range(8))
def test_a_mover_on_a_straight_line_is_tracked_with_its_velocity(seed: int) -> None:
    """32 beams, 2 cm range noise: after 20 scans (2 s) one track, within 15 cm and 0.3 m/s."""
    _, states, truth = _track_line(seed, 20)
    assert states.shape == (1, 4)
    assert np.hypot(*(states[0, :2] - truth[:2])) < 0.15
    assert np.hypot(*(states[0, 2:] - truth[2:])) < 0.3


def test_a_track_survives_drop_after_unseen_and_no_more() -> None:
    settings = TrackerSettings()
    tracker, states, _ = _track_line(0, 10)
    assert len(states) == 1
    empty = (np.zeros((0, 3)), np.zeros((0, 2, 2)))
    unseen = round(settings.drop_after / 0.1)
    for _ in range(unseen):
        assert len(tracker.step(*empty).ids) == 1  # predicted on, for drop_after seconds
    assert len(tracker.step(*empty).ids) == 0


def test_two_crossing_movers_keep_their_identities() -> None:
    tracker = Tracker(0.1)
    cov = np.tile(np.eye(2) * 0.02**2, (2, 1, 1))
    ids = None
    for t in range(40):
        a = [-2.0 + 0.1 * t, 0.05, 0.2]
        b = [2.0 - 0.1 * t, -0.05, 0.2]
        if 18 <= t <= 22:  # they pass each other: one disc hides the other
            tracks = tracker.step(np.array([a]), cov[:1])
        else:
            tracks = tracker.step(np.array([a, b]), cov)
        if len(tracks.ids) == 2 and ids is None:
            ids = dict(zip(tracks.ids.tolist(), np.sign(tracks.states[:, 2]).tolist(), strict=True))
    assert ids is not None and len(tracks.ids) == 2
    for track, vx in zip(tracks.ids.tolist(), tracks.states[:, 2], strict=True):
        assert np.sign(vx) == ids[track]  # each id still moves the way it did


@pytest.mark.parametrize("noise, dropout", [(0.0, 0.0), (0.02, 0.1), (0.05, 0.2)])
def test_no_false_mover_tracks_from_noise_with_the_map_known(noise: float, dropout: float) -> None:
    """10 seeds x 100 scans (100 s of a team at rest on Map 1, 3 robots x 32 beams): no mover
    track at all, however noisy the beams (stated rate: fewer than 1 per minute)."""
    tracks = set()
    for seed in range(10):
        env = gym.make(
            "KoopNav-TargetReaching-v0",
            map="map1",
            sensing="lidar",
            lidar={"noise": noise, "dropout": dropout},
        )
        _, info = env.reset(seed=seed)
        perception = LidarPerception()
        perception.reset(env.unwrapped.scenario.planner_view())
        for _ in range(100):
            view = perception.view(Observed.from_info(info))
            assert view.perceived and len(view.observed_movers) == len(view.mover_radii)
            assert perception.tracks is not None
            tracks |= {(seed, int(k)) for k in perception.tracks.ids}
            _, _, _, _, info = env.step(np.zeros(6))
    assert len(tracks) * 60.0 / 100.0 < 1.0, tracks


def test_movers_are_seen_where_they_are() -> None:
    """Map 1 with 4 movers (map known): over 6 seeds x 100 periods, at least 90% of the
    reported mover tracks lie within 0.5 m of a true mover, median position error under 15 cm
    and velocity error under 0.3 m/s."""
    matched, reported, position_error, velocity_error = 0, 0, [], []
    for seed in range(6):
        env = gym.make("KoopNav-TargetReaching-v0", map="map1", sensing="lidar", movers={"count": 4})
        _, info = env.reset(seed=seed)
        perception = LidarPerception()
        perception.reset(env.unwrapped.scenario.planner_view())
        for _ in range(100):
            view = perception.view(Observed.from_info(info))
            truth = info["movers"]
            for state in view.observed_movers:
                reported += 1
                gap = np.hypot(*(truth[:, :2] - state[:2]).T)
                if gap.min() < 0.5:
                    matched += 1
                    position_error.append(gap.min())
                    velocity_error.append(np.hypot(*(truth[np.argmin(gap), 2:4] - state[2:4])))
            _, _, _, _, info = env.step(np.zeros(6))
    assert reported > 500 and matched >= 0.9 * reported, (matched, reported)
    assert np.median(position_error) < 0.15 and np.median(velocity_error) < 0.3
