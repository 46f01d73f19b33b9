"""Movers observed through a tracker under ``sensing="state"``: what a robot's people tracker
reports, not the movers' true states.

Each period, a mover within ``movers.detection_range`` of a robot is detected by the nearest
such robot. The detection is the mover's position relative to that robot, with Gaussian error
of standard deviation ``movers.detection_noise`` per axis, placed in the world through the
robot's *estimated* pose (so localization error moves it, as it moves a real robot's
detections). Every mover's track is a constant-velocity Kalman filter (white-noise
acceleration :data:`ACCEL_SIGMA`), with the association known (each detection carries its
mover's identity: the perfect data association of a tracker that never swaps people; the lidar
perception of ``controllers.perception`` does its own association). A track is born at rest on
a mover's first detection (velocity standard deviation :data:`BIRTH_SPEED_SIGMA`), reported
once it has :data:`CONFIRM_HITS` detections, predicted on while unseen and dropped after
:data:`DROP_AFTER` seconds unseen. The info's ``observed_movers`` holds the reported tracks
(zero rows for the movers without one) and ``mover_tracked`` which movers have one; each
robot's observation lists the nearest reported ones; ``info["movers"]`` keeps the true states for scoring.

The filter is written out here, batched over every environment and mover in a few array
operations (a vector env steps thousands of movers per call; filterpy filters one at a time),
and tested equal to filterpy's ``predict`` and ``update`` (tests/test_mover_tracking.py). The
detection noise comes from its own child of each env's generator, so the movers' motion and
every other noise stream are the same with tracking on or off.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from koopman_envs.movers import MoverConfig
from koopman_envs.sim.movers import MoverField
from koopman_envs.sim.perception import child_generator

__all__ = [
    "ACCEL_SIGMA",
    "listed_movers",
    "observed_movers",
    "BIRTH_SPEED_SIGMA",
    "CONFIRM_HITS",
    "DROP_AFTER",
    "MoverTracker",
    "cv_predict",
    "cv_update",
    "cv_model",
]

#: white-noise acceleration of a mover's constant-velocity model [m/s^2] (a pedestrian's turns
#: and stops); the lidar tracker's default too
ACCEL_SIGMA = 1.0
#: velocity standard deviation of a new track [m/s] (movers walk at most 2 m/s)
BIRTH_SPEED_SIGMA = 1.0
#: detections before a track is reported
CONFIRM_HITS = 3
#: seconds a track survives unseen
DROP_AFTER = 0.5


def cv_model(dt: float, accel_sigma: float = ACCEL_SIGMA) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The constant-velocity model of state (x, y, vx, vy): transition F (4, 4) and process
    noise Q (4, 4) of piecewise white acceleration (filterpy's ``Q_discrete_white_noise`` with
    ``block_size=2, order_by_dim=False``)."""
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt
    q = accel_sigma**2 * np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])
    Q = np.asarray(np.kron(q, np.eye(2)), dtype=np.float64)
    return F, Q


def cv_predict(
    x: NDArray[np.float64], P: NDArray[np.float64], F: NDArray[np.float64], Q: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Kalman prediction of a batch of states (..., 4) and covariances (..., 4, 4)."""
    return x @ F.T, F @ P @ F.T + Q


def cv_update(
    x: NDArray[np.float64], P: NDArray[np.float64], z: NDArray[np.float64], R: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Kalman update (Joseph form, as filterpy's) of a batch by position measurements z (..., 2)
    of covariance R (..., 2, 2)."""
    S = P[..., :2, :2] + R
    # the 2x2 inverse in closed form, for the whole batch at once
    det = S[..., 0, 0] * S[..., 1, 1] - S[..., 0, 1] * S[..., 1, 0]
    inverse = np.stack(
        [np.stack([S[..., 1, 1], -S[..., 0, 1]], -1), np.stack([-S[..., 1, 0], S[..., 0, 0]], -1)], -2
    )
    inverse = inverse / det[..., None, None]
    gain = P[..., :, :2] @ inverse  # (..., 4, 2)
    x = x + (gain @ (z - x[..., :2])[..., None])[..., 0]
    I_KH = np.broadcast_to(np.eye(4), P.shape).copy()
    I_KH[..., :, :2] -= gain
    P = I_KH @ P @ np.swapaxes(I_KH, -1, -2) + gain @ R @ np.swapaxes(gain, -1, -2)
    return x, P


class MoverTracker:
    """Tracks of every mover of ``num_envs`` environments (module docstring).

    Parameters
    ----------
    num_envs, count : int
        Environments and movers per environment.
    dt : float
        The control period [s].
    detection_range : float
        Largest robot-mover distance at which a mover is detected [m].
    detection_noise : float
        Standard deviation of a detection's position error per axis [m].
    """

    def __init__(
        self, num_envs: int, count: int, dt: float, detection_range: float, detection_noise: float
    ) -> None:
        self.num_envs, self.count, self.dt = num_envs, count, dt
        self.detection_range, self.detection_noise = detection_range, detection_noise
        self._F, self._Q = cv_model(dt)
        self._R = np.eye(2) * max(detection_noise, 1e-6) ** 2  # exact detections: a tiny floor
        self._drop_misses = max(1, math.ceil(DROP_AFTER / dt - 1e-9))
        self.x = np.zeros((num_envs, count, 4))
        self.P = np.tile(np.eye(4), (num_envs, count, 1, 1))
        self.hits = np.zeros((num_envs, count), dtype=np.int64)
        self.misses = np.zeros((num_envs, count), dtype=np.int64)
        self.rngs: list[np.random.Generator | None] = [None] * num_envs
        self._parents: list[np.random.Generator | None] = [None] * num_envs

    @classmethod
    def for_movers(cls, movers: MoverConfig, num_envs: int, listed: int, dt: float) -> MoverTracker | None:
        """The tracker of ``movers`` when the robots observe them through one (movers, their
        ``tracking`` on, and ``listed`` > 0 slots in the observation: ``sensing="state"``), else None."""
        if not movers.active or not listed or not movers.tracking:
            return None
        return cls(num_envs, movers.count, dt, movers.detection_range, movers.detection_noise)

    def reset_env(self, index: int, rng: np.random.Generator) -> None:
        """Forget environment ``index``'s tracks; its detection noise comes from a child of
        ``rng`` (spawned when ``rng`` is a new generator, as every other noise stream)."""
        if self._parents[index] is not rng:
            self._parents[index] = rng
            self.rngs[index] = child_generator(rng)
        self.hits[index] = 0
        self.misses[index] = 0

    def step(
        self,
        movers: NDArray[np.float64],
        true_poses: NDArray[np.float64],
        estimated_poses: NDArray[np.float64],
        rows: NDArray[np.int64] | None = None,
    ) -> None:
        """One period of the environments ``rows`` (default all): detect, predict every track,
        update the detected ones, birth and drop.

        Parameters
        ----------
        movers : ndarray, shape (K, C, 4)
            True mover states.
        true_poses, estimated_poses : ndarray, shape (K, 3, N)
            The robots' true poses (who sees what) and estimates (where they place it).
        rows : ndarray of int, optional
            The environments that stepped.
        """
        rows = np.arange(self.num_envs) if rows is None else np.asarray(rows, dtype=np.int64)
        if not len(rows):
            return
        detected, z = self._detections(movers[rows], true_poses[rows], estimated_poses[rows], rows)
        hits, misses = self.hits[rows], self.misses[rows]
        alive = hits > 0
        x, P = cv_predict(self.x[rows], self.P[rows], self._F, self._Q)
        update = detected & alive
        if update.any():
            x[update], P[update] = cv_update(x[update], P[update], z[update], self._R)
        born = detected & ~alive
        if born.any():
            x[born] = np.concatenate([z[born], np.zeros((int(born.sum()), 2))], axis=1)
            birth = np.zeros((int(born.sum()), 4, 4))
            birth[:, :2, :2] = self._R
            birth[:, 2, 2] = birth[:, 3, 3] = BIRTH_SPEED_SIGMA**2
            P[born] = birth
        hits[detected] += 1
        misses[detected] = 0
        misses[alive & ~detected] += 1
        dropped = misses > self._drop_misses
        hits[dropped] = 0
        misses[dropped] = 0
        self.x[rows], self.P[rows], self.hits[rows], self.misses[rows] = x, P, hits, misses

    def observed(self) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """The reported tracks (x, y, vx, vy), shape (K, C, 4), zero for a mover without one,
        and which movers have one (K, C)."""
        reported = self.hits >= CONFIRM_HITS
        return np.where(reported[..., None], self.x, 0.0), reported

    def _detections(
        self,
        movers: NDArray[np.float64],
        true_poses: NDArray[np.float64],
        estimated_poses: NDArray[np.float64],
        rows: NDArray[np.int64],
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
        """Which movers of the environments ``rows`` are detected (R, C), and where (R, C, 2): by
        the nearest robot in range, relative to it, with noise, through its estimated pose."""
        noise = np.stack([self._draw(k) for k in rows.tolist()])  # (R, C, 2), drawn every period
        offset = movers[:, :, None, :2] - np.swapaxes(true_poses[:, :2], 1, 2)[:, None]  # (K, C, N, 2)
        distance = np.hypot(offset[..., 0], offset[..., 1])
        nearest = np.argmin(distance, axis=2)  # (K, C)
        detected = np.take_along_axis(distance, nearest[..., None], axis=2)[..., 0] <= self.detection_range
        rel = (
            np.take_along_axis(offset, nearest[..., None, None], axis=2)[:, :, 0]
            + self.detection_noise * noise
        )
        true_heading = np.take_along_axis(true_poses[:, 2], nearest, axis=1)
        estimate = np.take_along_axis(
            estimated_poses, np.broadcast_to(nearest[:, None], (len(nearest), 3, self.count)), 2
        )
        turn = estimate[:, 2] - true_heading  # the robot's heading error turns what it sees
        c, s = np.cos(turn), np.sin(turn)
        z = np.stack(
            [
                estimate[:, 0] + c * rel[..., 0] - s * rel[..., 1],
                estimate[:, 1] + s * rel[..., 0] + c * rel[..., 1],
            ],
            -1,
        )
        return detected, z

    def _draw(self, index: int) -> NDArray[np.float64]:
        rng = self.rngs[index]
        if rng is None:
            raise RuntimeError("MoverTracker: reset_env() every environment before step()")
        return rng.standard_normal((self.count, 2))


def observed_movers(
    field: MoverField | None, tracker: MoverTracker | None, listed: int
) -> tuple[NDArray[np.float64], NDArray[np.bool_]] | None:
    """The movers as the robots observe them with ``sensing="state"`` (``listed`` > 0 slots):
    their states (K, C, 4) and which are observed (K, C); the tracker's reports (zero rows for
    movers without a track), or the exact states without a tracker (``movers.tracking=False``);
    None with lidar or without movers (copies)."""
    if field is None or not listed:
        return None
    if tracker is None:
        return field.states(), np.ones((field.num_envs, field.count), dtype=bool)
    return tracker.observed()


def listed_movers(
    observed: tuple[NDArray[np.float64], NDArray[np.bool_]] | None,
) -> NDArray[np.float64] | None:
    """:func:`observed_movers` as the observation's features list them: a NaN row for a mover
    not observed (the feature kernel leaves it out)."""
    return None if observed is None else np.where(observed[1][..., None], observed[0], np.nan)
