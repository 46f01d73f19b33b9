"""What a controller sees through its team's lidars: the perception front in front of ``_act``.

Each period, for every robot's scan (``lidar_ranges``; the pose each scan is placed by is the
robot's estimate as the controller has it, so localization error moves what it sees):

1. **Known returns removed.** A return within a margin of something the team already knows is
   that thing and is dropped before clustering: the workspace walls, the map's obstacles (with
   ``lidar.map_known``), and the team-mates at their
   communicated positions (``known_poses``; a team-mate never heard of is not removed). The
   margin is ``explained_margin`` plus three standard deviations of the range noise and of the
   point's position through the pose estimate (its ``pose_covariance`` when an estimator hands
   one on: position, and heading times the range).
2. **Objects.** The remaining returns are cut into discs and wall segments
   (:mod:`controllers.perception.scan`); a wall segment not on the workspace boundary is covered
   by discs along it (spacing one radius, radius ``scan.default_radius``).
3. **Tracks.** The discs of the whole team feed one tracker (:mod:`controllers.perception.tracker`):
   the team shares its detections as it shares its poses.
4. **Map unknown** (``lidar.map_known=False``): the planner knows only what the beams have shown,
   accumulated in a local map for the episode. A confirmed track slower than ``static_speed``
   (judged by its displacement over ``static_window`` periods) is a static obstacle: its disc in the local map follows the track's estimate while it is seen
   and stays when the track ends (out of view, or hidden). A remembered disc is cleared when two
   beams of one scan pass through it (they read beyond it), so a mover that paused and walked
   on leaves no ghost; a track that speeds up leaves the map for the movers.

The controller's :class:`koopman_envs.Observed` then holds ``observed_movers`` (the moving tracks:
x, y, vx, vy), ``mover_covariance`` (their 4x4 covariances), ``mover_radii`` and, with the map
unknown, ``perceived_obstacles`` (the local map, x, y, r) and ``obstacle_covariance``; it is
marked ``perceived``.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controllers.perception.scan import ScanSettings, scan_objects
from controllers.perception.tracker import MoverTracks, Tracker, TrackerSettings
from koopman_envs import Observed, beam_angles
from koopman_envs.checks import check_int, check_number
from koopman_envs.scenario import Scenario

__all__ = ["LidarPerception", "PerceptionSettings"]


@dataclass(frozen=True)
class PerceptionSettings:
    """The perception front's settings (module docstring).

    Attributes
    ----------
    scan : ScanSettings
        Clustering and fitting (:mod:`controllers.perception.scan`).
    tracker : TrackerSettings
        Association, filtering and track rules (:mod:`controllers.perception.tracker`).
    explained_margin : float
        Fixed part of the margin within which a return is a known surface [m].
    static_speed : float
        Map unknown: speed below which a confirmed track is a static obstacle [m/s] (its
        displacement over ``static_window`` periods, divided by their duration).
    static_window : int
        Periods over which a track's speed is judged (10: one second at KoopNav's period).
    """

    scan: ScanSettings = field(default_factory=ScanSettings)
    tracker: TrackerSettings = field(default_factory=TrackerSettings)
    explained_margin: float = 0.1
    static_speed: float = 0.1
    static_window: int = 30

    def __post_init__(self) -> None:
        check_number("perception.explained_margin", self.explained_margin, at_least=0, note="metres")
        check_number("perception.static_speed", self.static_speed, at_least=0, note="m/s")
        check_int("perception.static_window", self.static_window, 2, note="periods")


class LidarPerception:
    """Scans to known-free returns, objects and tracks, for one team (module docstring).

    Parameters
    ----------
    settings : PerceptionSettings, optional
    """

    def __init__(self, settings: PerceptionSettings | None = None) -> None:
        self.settings = settings or PerceptionSettings()
        self.times: list[float] = []
        #: every confirmed track of the last period, static ones included
        self.tracks: MoverTracks | None = None
        self._scenario: Scenario | None = None
        self._tracker: Tracker | None = None
        self._map: dict[int, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}
        self._alive: set[int] = set()
        #: each track's recent positions (static_window periods), for _static
        self._history: dict[int, list[NDArray[np.float64]]] = {}
        self._dt = 0.1

    def reset(self, scenario: Scenario) -> None:
        """Start an episode on ``scenario`` (its lidar and, with the map known, its obstacles)."""
        if scenario.lidar_beams < 1:
            raise ValueError(
                f"perception needs the lidar (sensing='lidar'); the scenario of {scenario.map_name!r} has none"
            )
        settings = self.settings
        if scenario.mover_radius > 0:  # the prior radius of a short cluster: a mover's, if known
            settings = dataclasses.replace(
                settings, scan=dataclasses.replace(settings.scan, default_radius=scenario.mover_radius)
            )
        self._scan_settings = settings.scan
        self._scenario = scenario
        self._angles = beam_angles(scenario.lidar_beams, scenario.lidar_fov)
        self._tracker = Tracker(scenario.dt, settings.tracker)
        self._map = {}
        self._alive = set()
        self._history = {}
        self._dt = scenario.dt
        self.times = []
        self.tracks = None

    # ------------------------------------------------------------------ one period
    def view(self, observed: Observed) -> Observed:
        """``observed`` with what the team sees added (module docstring), a new value marked
        ``perceived``; needs ``lidar_ranges``."""
        if self._scenario is None or self._tracker is None:
            raise RuntimeError("LidarPerception: call reset(scenario) before view()")
        if observed.lidar_ranges is None:
            raise ValueError(
                "LidarPerception.view needs lidar_ranges (sensing='lidar'); this Observed has none"
            )
        start = time.perf_counter()
        sc = self._scenario
        ranges = observed.lidar_ranges
        poses = observed.observed_poses
        known = observed.known_poses
        ages = observed.message_age
        covariance = observed.pose_covariance
        discs, disc_cov = [], []
        for i in range(sc.n_robots):
            kept = self._unexplained(i, ranges[i], poses, known[i], ages[i], covariance)
            objects = scan_objects(kept, self._angles, sc.lidar_range, poses[i], self._scan_settings)
            discs.append(objects.discs)
            disc_cov.append(objects.disc_covariance)
            wall_discs = self._wall_discs(objects.segments)
            discs.append(wall_discs)
            disc_cov.append(
                np.broadcast_to(
                    np.eye(2) * (0.5 * self._scan_settings.default_radius) ** 2, (len(wall_discs), 2, 2)
                )
            )
            if not sc.map_known:
                self._carve(ranges[i], poses[i])
        tracks = self._tracker.step(np.vstack(discs), np.concatenate(disc_cov))
        self.tracks = tracks
        moving = self._split_static(tracks)
        out = dataclasses.replace(
            observed,
            observed_movers=tracks.states[moving],
            mover_covariance=tracks.covariances[moving],
            mover_radii=tracks.radii[moving],
            perceived=True,
        )
        if not sc.map_known:
            self._free_robots(poses)
            out = dataclasses.replace(
                out,
                perceived_obstacles=self.local_map.copy(),
                obstacle_covariance=self.local_map_covariance.copy(),
            )
        self.times.append(time.perf_counter() - start)
        return out

    def _unexplained(
        self,
        i: int,
        ranges: NDArray[np.float64],
        poses: NDArray[np.float64],
        known: NDArray[np.float64],
        ages: NDArray[np.int64],
        covariance: Any,
    ) -> NDArray[np.float64]:
        """Robot ``i``'s readings with every return of a known surface set to no return (step 1)."""
        sc = self._scenario
        assert sc is not None
        direction = poses[i, 2] + self._angles
        points = poses[i, :2] + ranges[:, None] * np.column_stack([np.cos(direction), np.sin(direction)])
        margin = np.full(len(ranges), self.settings.explained_margin + 3.0 * sc.lidar_noise)
        if covariance is not None:
            pose_cov = np.asarray(covariance, dtype=np.float64)[i]
            position_sd = math.sqrt(max(pose_cov[0, 0] + pose_cov[1, 1], 0.0))
            margin += 3.0 * (position_sd + ranges * math.sqrt(max(pose_cov[2, 2], 0.0)))
        x_min, x_max, y_min, y_max = sc.workspace
        explained = (
            (points[:, 0] < x_min + margin)
            | (points[:, 0] > x_max - margin)
            | (points[:, 1] < y_min + margin)
            | (points[:, 1] > y_max - margin)
        )
        discs = [
            np.asarray(sc.obstacles, dtype=np.float64).reshape(-1, 3) if sc.map_known else np.zeros((0, 3))
        ]
        mates = [j for j in range(sc.n_robots) if j != i and ages[j] >= 0]
        if mates:
            discs.append(np.column_stack([known[mates, :2], sc.robot_radius[mates]]))
        every = np.vstack(discs)
        if len(every):
            gap = np.hypot(points[:, None, 0] - every[None, :, 0], points[:, None, 1] - every[None, :, 1])
            explained |= np.any(gap < every[None, :, 2] + margin[:, None], axis=1)
        return np.where(explained, sc.lidar_range, ranges)

    def _wall_discs(self, segments: NDArray[np.float64]) -> NDArray[np.float64]:
        """Discs of radius ``default_radius`` one radius apart along each segment (step 2)."""
        radius = self._scan_settings.default_radius
        out = []
        for x0, y0, x1, y1 in segments:
            count = max(2, int(math.ceil(math.hypot(x1 - x0, y1 - y0) / radius)) + 1)
            s = np.linspace(0.0, 1.0, count)[:, None]
            out.append(np.column_stack([x0 + s * (x1 - x0), y0 + s * (y1 - y0), np.full(count, radius)]))
        return np.vstack(out) if out else np.zeros((0, 3))

    def _split_static(self, tracks: MoverTracks) -> NDArray[np.bool_]:
        """Which tracks are movers; with the map unknown, the slow ones are the local map's
        (step 4): a static track's disc follows its estimate and stays after the track ends."""
        sc = self._scenario
        assert sc is not None
        if sc.map_known:
            return np.ones(len(tracks.ids), dtype=bool)
        static = self._static(tracks)
        self._alive = set(tracks.ids.tolist())
        for track in tracks.ids[~static].tolist():
            self._map.pop(track, None)
        discs = np.column_stack([tracks.states[static, :2], tracks.radii[static]])
        # an obstacle seen again after its track ended starts a new track: it replaces the
        # remembered disc it overlaps instead of doubling it
        remembered = [t for t in self._map if t not in self._alive]
        if remembered and len(discs):
            old = np.array([self._map[t][0] for t in remembered])
            gap = np.hypot(old[:, None, 0] - discs[None, :, 0], old[:, None, 1] - discs[None, :, 1])
            overlap = (gap < np.maximum(old[:, None, 2], discs[None, :, 2])).any(axis=1)
            for t in np.asarray(remembered)[overlap].tolist():
                del self._map[t]
        for k, track in zip(np.flatnonzero(static).tolist(), tracks.ids[static].tolist(), strict=True):
            self._map[track] = (
                np.array([*tracks.states[k, :2], tracks.radii[k]]),
                tracks.covariances[k, :2, :2],
            )
        return ~static

    def _static(self, tracks: MoverTracks) -> NDArray[np.bool_]:
        """Which tracks stand still. A track moves when both its displacement over the last
        ``static_window`` periods (or its life, if shorter) exceeds ``static_speed`` times their
        duration plus three standard deviations of its position, and its filtered speed
        exceeds twice ``static_speed``. Either alone is fooled by a static obstacle seen through
        a few beams of a coarse scan: its fitted centre jumps as the returns change (so the
        filter's velocity flickers), and one early jump stays in the window."""
        window = self.settings.static_window
        history = {}
        static = np.zeros(len(tracks.ids), dtype=bool)
        for k, track in enumerate(tracks.ids.tolist()):
            past = self._history.get(track, [])[-(window - 1) :] + [tracks.states[k, :2].copy()]
            history[track] = past
            elapsed = (len(past) - 1) * self._dt
            moved = math.hypot(*(past[-1] - past[0]))
            # what the track's own position uncertainty explains is no evidence of motion
            cov = tracks.covariances[k]
            spread = 3.0 * math.sqrt(max(float(cov[0, 0] + cov[1, 1]), 0.0))
            speed = math.hypot(tracks.states[k, 2], tracks.states[k, 3])
            # moving: displaced beyond its own noise over the window, and moving now
            static[k] = moved <= self.settings.static_speed * max(elapsed, self._dt) + spread or (
                speed <= 2.0 * self.settings.static_speed
            )
        self._history = history
        return static

    def _free_robots(self, poses: NDArray[np.float64]) -> None:
        """Shrink every local map disc that overlaps a robot's estimated disc to touch it: where
        a robot stands is free space, whatever a coarse scan's fit made of the returns near it."""
        sc = self._scenario
        assert sc is not None
        for track, (disc, covariance) in list(self._map.items()):
            gap = np.hypot(poses[:, 0] - disc[0], poses[:, 1] - disc[1]) - sc.robot_radius
            if gap.min() < disc[2]:
                self._map[track] = (np.array([disc[0], disc[1], max(float(gap.min()), 0.0)]), covariance)

    @property
    def local_map(self) -> NDArray[np.float64]:
        """The accumulated static discs (x, y, r), shape (M, 3) (map unknown; step 4)."""
        return np.array([disc for disc, _ in self._map.values()], dtype=np.float64).reshape(-1, 3)

    @property
    def local_map_covariance(self) -> NDArray[np.float64]:
        """Their centres' covariances, shape (M, 2, 2)."""
        return np.array([cov for _, cov in self._map.values()], dtype=np.float64).reshape(-1, 2, 2)

    def _carve(self, ranges: NDArray[np.float64], pose: NDArray[np.float64]) -> None:
        """Clear the remembered discs (their track ended) that two beams of this scan pass
        through (step 4)."""
        remembered = [t for t in self._map if t not in self._alive]
        if not remembered:
            return
        discs = np.array([self._map[t][0] for t in remembered])  # (R, 3)
        rel = discs[:, :2] - pose[:2]
        distance = np.hypot(rel[:, 0], rel[:, 1])
        bearing = np.arctan2(rel[:, 1], rel[:, 0]) - pose[2]
        offset = np.remainder(self._angles[None, :] - bearing[:, None] + np.pi, 2 * np.pi) - np.pi
        half = np.arcsin(np.minimum(0.5 * discs[:, 2] / np.maximum(distance, 1e-12), 1.0))
        through = (np.abs(offset) <= half[:, None]) & (ranges[None, :] > (distance + discs[:, 2])[:, None])
        cleared = (through.sum(axis=1) >= 2) & (distance > discs[:, 2])
        for t in np.asarray(remembered)[cleared].tolist():
            del self._map[t]
