"""Movers tracked from the discs the team's scans show: data association and a constant-velocity
Kalman filter per track, with the rules by which tracks are born, confirmed and dropped.

Each period the tracker takes the discs of every robot's scan in the world frame (already
stripped of team-mates, known obstacles and walls by :mod:`controllers.perception.front`):

1. **Fusion across robots.** Two robots may see the same mover: discs of one scan period whose
   centres lie closer than the larger radius are one detection, their centres fused by inverse
   covariance (information) weighting.
2. **Prediction.** Every track moves one period under the constant-velocity model with white-noise
   acceleration of standard deviation ``accel_sigma`` (the process noise of filterpy's
   ``Q_discrete_white_noise``).
3. **Association.** The globally cheapest one-to-one assignment of detections to tracks
   (Hungarian, ``scipy.optimize.linear_sum_assignment``) on the squared Mahalanobis distance
   of each detection from each track's predicted position, gated at the chi-square quantile
   ``gate_probability`` with 2 degrees of freedom (9.21 at 0.99): a pair beyond the gate is never
   assigned.
4. **Update.** Each assigned track takes its detection through the Kalman update in the Joseph
   form; its radius is that of its most precise detection so far (smallest covariance
   trace: a disc seen from afar by one beam gets the prior radius, a closer view fits the true one).
5. **Birth, confirmation, drop.** An unassigned detection starts a tentative track at rest with
   velocity standard deviation ``birth_speed_sigma``. A tentative track is confirmed after
   ``confirm_hits`` detections and dropped at its second miss before that (a false detection
   from noise rarely repeats at the gated place). A confirmed track unseen for ``drop_after``
   seconds (it left every robot's view, or is hidden) is dropped; until then it is predicted
   forward and its covariance grows.

Only confirmed tracks are reported (:meth:`Tracker.tracks`). The filter is the env's people
tracker's, compiled (:func:`koopman_envs.sim.movers.tracking.cv_predict` and ``cv_update``, tested
equal to filterpy's ``predict`` and ``update``): one constant-velocity filter in the package, at a
fraction of filterpy's per-call cost (it was a third of the perception's time). The association
and the track rules, which no well-kept library packages at this size without a framework of its
own (Stone Soup), are here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

from koopman_envs import cv_model, cv_predict, cv_update
from koopman_envs.checks import check_int, check_number

__all__ = ["MoverTracks", "Tracker", "TrackerSettings", "fuse_detections"]


@dataclass(frozen=True)
class TrackerSettings:
    """The tracker's model and rules (module docstring).

    Attributes
    ----------
    accel_sigma : float
        White-noise acceleration of a mover [m/s^2] (1: a pedestrian's turns and stops).
    gate_probability : float
        Probability inside the association gate, in (0, 1).
    birth_speed_sigma : float
        Velocity standard deviation of a new track [m/s] (KoopNav's movers walk at most 2 m/s).
    confirm_hits : int
        Detections that confirm a track.
    drop_after : float
        Seconds a confirmed track survives unseen.
    """

    accel_sigma: float = 1.0
    gate_probability: float = 0.99
    birth_speed_sigma: float = 1.0
    confirm_hits: int = 3
    drop_after: float = 0.5

    def __post_init__(self) -> None:
        check_number("tracker.accel_sigma", self.accel_sigma, above=0, note="m/s^2")
        check_number("tracker.gate_probability", self.gate_probability, above=0, at_most=0.999999)
        check_number("tracker.birth_speed_sigma", self.birth_speed_sigma, above=0, note="m/s")
        check_int("tracker.confirm_hits", self.confirm_hits, 1)
        check_number("tracker.drop_after", self.drop_after, at_least=0, note="seconds")


@dataclass(frozen=True)
class MoverTracks:
    """The confirmed tracks of one period.

    Attributes
    ----------
    ids : ndarray, shape (C,)
        Each track's number, unique over the episode.
    states : ndarray, shape (C, 4)
        x, y [m], vx, vy [m/s].
    covariances : ndarray, shape (C, 4, 4)
        The states' covariances.
    radii : ndarray, shape (C,)
        Estimated disc radii [m].
    """

    ids: NDArray[np.int64]
    states: NDArray[np.float64]
    covariances: NDArray[np.float64]
    radii: NDArray[np.float64]


def fuse_detections(
    discs: NDArray[np.float64], covariances: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Discs of one period that are one object (centres closer than the larger radius) fused
    by information weighting (step 1 of the module docstring); returns (discs, covariances)."""
    count = len(discs)
    if count < 2:
        return discs, covariances
    gap = np.hypot(discs[:, None, 0] - discs[None, :, 0], discs[:, None, 1] - discs[None, :, 1])
    close = np.triu(gap < np.maximum(discs[:, None, 2], discs[None, :, 2]), k=1)
    if not close.any():  # the common case: every disc is its own object
        return discs, covariances
    group = np.arange(count)
    for i, j in zip(*np.nonzero(close), strict=True):
        group[group == group[j]] = group[i]
    fused, fused_cov = [], []
    for g in np.unique(group):
        members = np.flatnonzero(group == g)
        if len(members) == 1:
            fused.append(discs[members[0]])
            fused_cov.append(covariances[members[0]])
            continue
        information = np.linalg.inv(covariances[members])
        total = information.sum(axis=0)
        covariance = np.linalg.inv(total)
        centre = covariance @ np.einsum("kij,kj->i", information, discs[members, :2])
        fused.append([centre[0], centre[1], discs[members, 2].max()])
        fused_cov.append(covariance)
    return np.array(fused), np.array(fused_cov)


class Tracker:
    """Multi-target tracker of the movers a team sees (module docstring).

    Parameters
    ----------
    dt : float
        The scan period [s] (the control period).
    settings : TrackerSettings, optional
    """

    def __init__(self, dt: float, settings: TrackerSettings | None = None) -> None:
        self.dt = check_number("dt", dt, above=0, note="seconds")
        self.settings = settings or TrackerSettings()
        _, self._Q = cv_model(self.dt, self.settings.accel_sigma)
        self._work = np.empty((6, 4))  # the compiled update's scratch
        self._gate = float(chi2.ppf(self.settings.gate_probability, df=2))
        self._drop_misses = max(1, math.ceil(self.settings.drop_after / self.dt - 1e-9))
        self.reset()

    def reset(self) -> None:
        """Forget every track (a new episode)."""
        self._x: list[NDArray[np.float64]] = []
        self._P: list[NDArray[np.float64]] = []
        self._radius: list[float] = []
        self._spread: list[float] = []
        self._hits: list[int] = []
        self._misses: list[int] = []
        self._ids: list[int] = []
        self._next_id = 0

    def step(self, discs: NDArray[np.float64], covariances: NDArray[np.float64]) -> MoverTracks:
        """One period: predict, associate the detections, update, and apply the track rules.

        Parameters
        ----------
        discs : ndarray, shape (D, 3)
            Detected disc centres and radii this period (world frame) [m].
        covariances : ndarray, shape (D, 2, 2)
            Their centres' covariances [m^2].

        Returns
        -------
        MoverTracks
            The confirmed tracks after this period.
        """
        discs = np.asarray(discs, dtype=np.float64).reshape(-1, 3)
        covariances = np.asarray(covariances, dtype=np.float64).reshape(-1, 2, 2)
        discs, covariances = fuse_detections(discs, covariances)
        for k in range(len(self._x)):  # in place
            cv_predict(self._x[k], self._P[k], self.dt, self._Q)
        assigned = self._associate(discs, covariances)
        seen = set()
        for track, detection in assigned:
            R = covariances[detection]
            z = discs[detection]
            cv_update(self._x[track], self._P[track], z[0], z[1], R[0, 0], R[0, 1], R[1, 1], self._work)
            self._hits[track] += 1
            self._misses[track] = 0
            spread = float(covariances[detection, 0, 0] + covariances[detection, 1, 1])
            if spread <= self._spread[track]:  # the radius of the most precise detection so far
                self._radius[track], self._spread[track] = float(discs[detection, 2]), spread
            seen.add(track)
        for track in range(len(self._x)):
            if track not in seen:
                self._misses[track] += 1
        self._drop()
        detected = {d for _, d in assigned}
        for d in range(len(discs)):
            if d not in detected:
                self._birth(discs[d], covariances[d])
        return self.tracks()

    def tracks(self) -> MoverTracks:
        """The confirmed tracks."""
        confirmed = [k for k in range(len(self._x)) if self._hits[k] >= self.settings.confirm_hits]
        return MoverTracks(
            ids=np.array([self._ids[k] for k in confirmed], dtype=np.int64),
            states=np.array([self._x[k] for k in confirmed], dtype=np.float64).reshape(-1, 4),
            covariances=np.array([self._P[k] for k in confirmed], dtype=np.float64).reshape(-1, 4, 4),
            radii=np.array([self._radius[k] for k in confirmed], dtype=np.float64),
        )

    # ------------------------------------------------------------------ the rules
    def _associate(
        self, discs: NDArray[np.float64], covariances: NDArray[np.float64]
    ) -> list[tuple[int, int]]:
        """(track, detection) pairs of the cheapest gated one-to-one assignment."""
        if not self._x or not len(discs):
            return []
        positions = np.array([x[:2] for x in self._x])  # (T, 2)
        spread = np.array([P[:2, :2] for P in self._P])  # (T, 2, 2)
        innovation = discs[None, :, :2] - positions[:, None]  # (T, D, 2)
        S = spread[:, None] + covariances[None]  # (T, D, 2, 2): every pair in one inversion
        cost = np.einsum("tdi,tdij,tdj->td", innovation, np.linalg.inv(S), innovation)
        blocked = cost > self._gate
        rows, cols = linear_sum_assignment(np.where(blocked, 1e12, cost))
        return [(int(r), int(c)) for r, c in zip(rows, cols, strict=True) if not blocked[r, c]]

    def _drop(self) -> None:
        keep = [
            k
            for k in range(len(self._x))
            if (
                self._misses[k] < 2
                if self._hits[k] < self.settings.confirm_hits
                else self._misses[k] <= self._drop_misses
            )
        ]
        for name in ("_x", "_P", "_radius", "_spread", "_hits", "_misses", "_ids"):
            values = getattr(self, name)
            setattr(self, name, [values[k] for k in keep])

    def _birth(self, disc: NDArray[np.float64], covariance: NDArray[np.float64]) -> None:
        P = np.zeros((4, 4))
        P[:2, :2] = covariance
        P[2, 2] = P[3, 3] = self.settings.birth_speed_sigma**2
        self._x.append(np.array([disc[0], disc[1], 0.0, 0.0]))
        self._P.append(P)
        self._radius.append(float(disc[2]))
        self._spread.append(float(np.trace(covariance)))
        self._hits.append(1)
        self._misses.append(0)
        self._ids.append(self._next_id)
        self._next_id += 1
