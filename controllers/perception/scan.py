"""From one robot's lidar scan to the objects it shows: clusters of returns, fitted discs and
wall segments, each with its uncertainty.

The pipeline a mobile robot runs between its laser and its planner (as ROS's
``laser_line_extraction`` and ``obstacle_detector`` do), per robot and scan:

1. **Returns to points.** A beam that reads less than the sensor's range hit something; its
   point is placed in the world through the robot's *estimated* pose, so localization error
   moves every point (as on a real robot).
2. **Clusters.** Adjacent returns belong to one object when the distance between their points
   is at most ``gap + gap_per_beam * r * spacing`` (``r`` the nearer range, ``spacing`` the
   angle between beams): the fixed part absorbs range noise, the part proportional to
   ``r * spacing`` (the arc between two beams at that range) lets a surface seen at a slant
   stay one object. A full-circle scan wraps around. This is the adaptive breakpoint detector of
   Borges and Aldon (2004) in its linear form; DBSCAN (scikit-learn) would cluster the same
   points without using their order along the scan, which is what makes this one pass of O(B).
3. **Splitting.** A cluster that a single disc fits badly (RMS residual above
   ``split_tolerance``) is split at its most prominent interior local maximum of range: a disc
   seen from outside shows one minimum of range, two touching discs show two, with a maximum
   between them.
4. **Fitting.** A cluster of three or more points on a line (perpendicular RMS at most
   ``wall_tolerance`` and no disc of radius up to ``max_radius`` fits) is a wall segment.
   Otherwise it is a disc: Kasa's algebraic fit refined by Gauss-Newton on the geometric
   distance, accepted if the radius lies in [``min_radius``, ``max_radius``] and the centre lies
   behind the points as seen from the robot. The centre's covariance is the Gauss-Newton
   estimate ``sigma^2 (J^T J)^-1`` (``sigma``: the residual RMS, at least ``point_sigma``). A
   cluster too short for that (one or two returns, or a rejected fit) gets discs of the prior
   radius ``default_radius``, centred that far behind a return along its beam: one behind its
   nearest return when the cluster spans no more than that disc, else one behind each return
   (two far returns of a coarse scan may be two objects; one large disc over both would fill
   the free space between them). Their covariance is isotropic with standard deviation
   ``radius / 2``. A closer view fits the object's true size, and the tracker keeps the radius
   of its most precise detection.

Team-mates, the map's known obstacles and the workspace walls are recognised and removed in
:mod:`controllers.perception.front`; this module only measures.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from koopman_envs.checks import check_number

__all__ = ["ScanObjects", "ScanSettings", "cluster_scan", "fit_circle", "scan_objects", "scan_points"]


@dataclass(frozen=True)
class ScanSettings:
    """How a scan is cut into objects and fitted (module docstring).

    Attributes
    ----------
    gap : float
        Fixed part of the break distance between adjacent returns [m].
    gap_per_beam : float
        Part of the break distance per arc between two beams at the nearer range (``r * spacing``).
    split_tolerance : float
        RMS residual of a disc fit above which a cluster is split [m].
    wall_tolerance : float
        Perpendicular RMS of a line fit at most which a cluster that no disc fits is a wall [m].
    min_radius, max_radius : float
        Radii a fitted disc may have [m].
    default_radius : float
        Prior radius of a cluster too short to fit [m] (KoopNav's movers and robots: 0.2).
    point_sigma : float
        Smallest standard deviation assumed of a point [m] (the fit's covariance floor).
    """

    gap: float = 0.1
    gap_per_beam: float = 1.5
    split_tolerance: float = 0.03
    wall_tolerance: float = 0.02
    min_radius: float = 0.05
    max_radius: float = 1.5
    default_radius: float = 0.2
    point_sigma: float = 0.01

    def __post_init__(self) -> None:
        for name in ("gap", "gap_per_beam", "split_tolerance", "wall_tolerance", "min_radius", "point_sigma"):
            check_number(f"perception.{name}", getattr(self, name), above=0)
        check_number("perception.max_radius", self.max_radius, above=self.min_radius, note="above min_radius")
        check_number("perception.default_radius", self.default_radius, above=0, note="metres")


@dataclass(frozen=True)
class ScanObjects:
    """The objects of one scan (world frame).

    Attributes
    ----------
    discs : ndarray, shape (D, 3)
        Centre x, y and radius [m].
    disc_covariance : ndarray, shape (D, 2, 2)
        Covariance of each centre [m^2].
    disc_beams : list of ndarray
        The beam indices of each disc.
    segments : ndarray, shape (S, 4)
        Wall segments, end points x0, y0, x1, y1 [m].
    segment_beams : list of ndarray
        The beam indices of each segment.
    """

    discs: NDArray[np.float64]
    disc_covariance: NDArray[np.float64]
    disc_beams: list[NDArray[np.intp]]
    segments: NDArray[np.float64]
    segment_beams: list[NDArray[np.intp]]


def scan_points(
    ranges: NDArray[np.float64], angles: NDArray[np.float64], pose: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The world point of every beam, shape (B, 2), through ``pose`` (x, y, theta)."""
    direction = pose[2] + angles
    return np.column_stack([pose[0] + ranges * np.cos(direction), pose[1] + ranges * np.sin(direction)])


def cluster_scan(
    ranges: NDArray[np.float64],
    angles: NDArray[np.float64],
    max_range: float,
    settings: ScanSettings,
) -> list[NDArray[np.intp]]:
    """The clusters of adjacent returns of one scan (step 2 of the module docstring).

    Parameters
    ----------
    ranges : ndarray, shape (B,)
        The readings [m]; a reading at ``max_range`` (or 0: inside an object) returned nothing.
    angles : ndarray, shape (B,)
        Beam directions relative to the heading, evenly spaced (``koopman_envs.sim.lidar.beam_angles``).
    max_range : float
        The sensor's range [m].
    settings : ScanSettings

    Returns
    -------
    list of ndarray
        Each cluster's beam indices in scan order (a cluster across the seam of a full-circle
        scan runs from the last beams to the first).
    """
    beams = len(ranges)
    valid = (ranges > 0.0) & (ranges < max_range * (1.0 - 1e-9))
    if not valid.any():
        return []
    spacing = float(angles[1] - angles[0]) if beams > 1 else 2 * math.pi
    full_circle = beams * spacing >= 2 * math.pi - 1e-9
    local_x, local_y = ranges * np.cos(angles), ranges * np.sin(angles)
    after, before = _neighbours(beams)
    step = np.hypot(local_x[after] - local_x, local_y[after] - local_y)
    limit = settings.gap + settings.gap_per_beam * np.minimum(ranges, ranges[after]) * spacing
    linked = valid & valid[after] & (step <= limit)
    # a single beam that returned nothing between two returns close enough to be one surface
    # two beams apart is a dropout, not a gap: the run goes on across it (the beam itself is left
    # out of the cluster)
    across = np.hypot(local_x[after] - local_x[before], local_y[after] - local_y[before])
    bridged = (
        ~valid
        & valid[before]
        & valid[after]
        & (
            across
            <= settings.gap + settings.gap_per_beam * np.minimum(ranges[before], ranges[after]) * 2 * spacing
        )
    )
    if not full_circle:
        bridged[[0, -1]] = False
    linked |= bridged | bridged[after]
    if not full_circle:
        linked[-1] = False
    if linked.all():  # one object all around the robot
        return [np.arange(beams)[valid]]
    ends = np.flatnonzero(~linked)  # beam b ends a run when it is not linked to b + 1
    # start after a run's end, so that a run across the seam stays whole
    shift = int(ends[0]) + 1
    order = np.concatenate((np.arange(shift, beams), np.arange(shift)))
    bounds = [0, *(np.flatnonzero(~linked[order]) + 1).tolist()]
    runs = (order[a:b] for a, b in zip(bounds[:-1], bounds[1:], strict=True))
    return [run[valid[run]] for run in runs if valid[run[0]]]


@functools.lru_cache(maxsize=16)
def _neighbours(beams: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """The index of the next and of the previous beam around the scan (cached per beam count)."""
    index = np.arange(beams)
    return (index + 1) % beams, (index - 1) % beams


def fit_circle(
    points: NDArray[np.float64], viewpoint: NDArray[np.float64], settings: ScanSettings
) -> tuple[NDArray[np.float64], float, NDArray[np.float64], float] | None:
    """The disc through ``points`` seen from ``viewpoint`` (step 4 of the module docstring).

    Returns
    -------
    tuple or None
        ``(centre (2,), radius, centre covariance (2, 2), RMS residual)``, or None when fewer
        than three points, or the fit is degenerate, out of the radius bounds or in front of
        the points.
    """
    if len(points) < 3:
        return None
    cx, cy, radius, rms, c00, c01, c11, ok = _circle_fit(np.ascontiguousarray(points, dtype=np.float64))
    if not ok:
        return None
    centre = np.array([cx, cy])
    behind = np.hypot(*(centre - viewpoint)) > np.hypot(*(points.mean(axis=0) - viewpoint))
    if not (settings.min_radius <= radius <= settings.max_radius) or not behind:
        return None
    sigma = max(rms, settings.point_sigma)
    covariance = sigma * sigma * np.array([[c00, c01], [c01, c11]])
    return centre, float(radius), covariance, float(rms)


@njit(cache=True)
def _circle_fit(
    points: NDArray[np.float64],
) -> tuple[float, float, float, float, float, float, float, bool]:  # pragma: no cover - compiled
    """Kasa's fit refined by Gauss-Newton (module docstring, step 4), on the points relative to
    their mean (for conditioning). Returns centre x, y, radius, RMS residual, the centre's
    unscaled covariance (J^T J)^-1 entries 00, 01, 11, and whether the fit is sound (not
    degenerate, finite, its normal matrix conditioned below 1e12)."""
    count = points.shape[0]
    mx, my = points[:, 0].mean(), points[:, 1].mean()
    x, y = points[:, 0] - mx, points[:, 1] - my
    # Kasa: x^2 + y^2 + D x + E y + F = 0 is linear in (D, E, F): its normal equations
    design = np.empty((count, 3))
    design[:, 0], design[:, 1], design[:, 2] = x, y, 1.0
    normal = design.T @ design
    if abs(np.linalg.det(normal)) < 1e-18:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    solution = np.linalg.solve(normal, design.T @ (-(x * x + y * y)))
    cx, cy = -0.5 * solution[0], -0.5 * solution[1]
    radius_sq = cx * cx + cy * cy - solution[2]
    if not np.isfinite(radius_sq) or radius_sq <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    radius = math.sqrt(radius_sq)
    jacobian = np.empty((count, 3))
    residual = np.empty(count)
    for iteration in range(6):  # Gauss-Newton on |p - c| - r: 5 steps at most, then evaluated
        for k in range(count):
            dx, dy = x[k] - cx, y[k] - cy
            distance = math.sqrt(dx * dx + dy * dy)
            if distance < 1e-12:
                return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
            jacobian[k, 0], jacobian[k, 1], jacobian[k, 2] = -dx / distance, -dy / distance, -1.0
            residual[k] = distance - radius
        normal = jacobian.T @ jacobian
        if iteration == 5 or abs(np.linalg.det(normal)) < 1e-18:
            break
        delta = np.linalg.solve(normal, jacobian.T @ (-residual))
        cx, cy, radius = cx + delta[0], cy + delta[1], radius + delta[2]
    singular = np.linalg.svd(normal)[1]
    rms = math.sqrt((residual * residual).mean())
    if not np.isfinite(rms) or singular[2] <= 0.0 or singular[0] / singular[2] > 1e12:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    inverse = np.linalg.inv(normal)
    return cx + mx, cy + my, radius, rms, inverse[0, 0], inverse[0, 1], inverse[1, 1], True


def _prior_discs(
    points: NDArray[np.float64], viewpoint: NDArray[np.float64], settings: ScanSettings
) -> list[tuple[NDArray[np.float64], float, NDArray[np.float64]]]:
    """Discs for a cluster no disc fits: one of the prior radius behind its nearest return
    along the beam when its chord spans at most that disc, else one behind every return (far
    returns of a coarse scan, one beam apart, are as likely two objects as one large one: a
    disc spanning both would fill the free space between them). Isotropic covariance of
    standard deviation radius / 2."""
    radius = settings.default_radius
    covariance = (0.5 * radius) ** 2 * np.eye(2)  # read only: shared by the cluster's discs
    chord = math.hypot(points[-1, 0] - points[0, 0], points[-1, 1] - points[0, 1]) if len(points) > 1 else 0.0
    offsets = points - viewpoint
    distances = np.maximum(np.hypot(offsets[:, 0], offsets[:, 1]), 1e-12)
    if chord <= 2.0 * radius:
        nearest = int(np.argmin(distances))
        points, offsets, distances = (
            points[nearest : nearest + 1],
            offsets[nearest : nearest + 1],
            distances[nearest : nearest + 1],
        )
    centres = points + radius * offsets / distances[:, None]
    return [(centre, radius, covariance) for centre in centres]


def _wall(points: NDArray[np.float64], settings: ScanSettings) -> NDArray[np.float64] | None:
    """The end points (4,) of the line through ``points`` if they lie on one, else None."""
    if len(points) < 3:
        return None
    mean = points.mean(axis=0)
    _, singular, axes = np.linalg.svd(points - mean, full_matrices=False)
    if singular[-1] / math.sqrt(len(points)) > settings.wall_tolerance:
        return None
    along = (points - mean) @ axes[0]
    return np.concatenate([mean + along.min() * axes[0], mean + along.max() * axes[0]])


def _split(run: NDArray[np.intp], ranges: NDArray[np.float64]) -> list[NDArray[np.intp]]:
    """``run`` cut at its most prominent interior local maximum of range (step 3), or whole."""
    r = ranges[run]
    if len(r) < 5:
        return [run]
    inner = np.arange(1, len(r) - 1)
    peaks = inner[(r[inner] > r[inner - 1]) & (r[inner] >= r[inner + 1])]
    if len(peaks) == 0:
        return [run]
    # prominence: how far the peak stands above the lower of the two minima on its sides
    prominence = [r[p] - max(r[:p].min(), r[p + 1 :].min()) for p in peaks]
    best = int(peaks[int(np.argmax(prominence))])
    if best < 2 or best > len(r) - 3:
        return [run]
    return [run[: best + 1], run[best:]]  # the peak return touches both objects


def scan_objects(
    ranges: NDArray[np.float64],
    angles: NDArray[np.float64],
    max_range: float,
    pose: NDArray[np.float64],
    settings: ScanSettings,
) -> ScanObjects:
    """Every disc and wall segment of one robot's scan, through its estimated ``pose`` (module
    docstring, steps 1-4).

    Parameters
    ----------
    ranges : ndarray, shape (B,)
        The readings [m].
    angles : ndarray, shape (B,)
        Beam directions relative to the heading [rad].
    max_range : float
        The sensor's range [m].
    pose : ndarray, shape (3,)
        The robot's pose estimate (x, y, theta).
    settings : ScanSettings
    """
    ranges = np.asarray(ranges, dtype=np.float64)
    points = scan_points(ranges, angles, pose)
    viewpoint = np.asarray(pose[:2], dtype=np.float64)
    discs, covariances, disc_beams, segments, segment_beams = [], [], [], [], []
    pending = cluster_scan(ranges, angles, max_range, settings)
    while pending:
        run = pending.pop()
        cluster = points[run]
        fit = fit_circle(cluster, viewpoint, settings)
        if fit is None or fit[3] > settings.split_tolerance:
            wall = _wall(cluster, settings)
            if wall is not None:
                segments.append(wall)
                segment_beams.append(run)
                continue
            parts = _split(run, ranges)
            if len(parts) > 1:
                pending.extend(parts)
                continue
        found = [fit[:3]] if fit is not None else _prior_discs(cluster, viewpoint, settings)
        for centre, radius, covariance in found:
            discs.append([centre[0], centre[1], radius])
            covariances.append(covariance)
            disc_beams.append(run)
    return ScanObjects(
        discs=np.array(discs, dtype=np.float64).reshape(-1, 3),
        disc_covariance=np.array(covariances, dtype=np.float64).reshape(-1, 2, 2),
        disc_beams=disc_beams,
        segments=np.array(segments, dtype=np.float64).reshape(-1, 4),
        segment_beams=segment_beams,
    )
