"""Per-robot observation features shared by every front (centralized, vector, per-agent).

One robot's block, in this order (body frame = the robot's own x forward, y left):

==========  ==========================================================  ============
entries     meaning                                                      unit
==========  ==========================================================  ============
0, 1        x, y position                                                m
2, 3        cos(theta), sin(theta)                                       -
4, 5        target position in the body frame                            m
6           distance to the target                                       m
7, 8        cos, sin of (target heading - heading)                       -
9 ..        each other robot j (index order): body-frame dx, dy,         m
            surface clearance (3 entries per other robot)
..          the ``n_obstacle_obs`` nearest obstacles, nearest first:     m
            body-frame dx, dy to the centre, surface clearance;
            missing ones read (0, 0, ``FAR``)
last 2      formation error e_i = (p_i - p_0) - offset_i (world frame),  m
            formation task only
==========  ==========================================================  ============

Every entry is clipped into the bounds of :func:`feature_bounds`, so observations stay inside
the observation space even after a robot has left the workspace.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from koopman_envs.sim.geometry import Geometry

__all__ = ["FAR", "FeatureBuilder", "feature_bounds", "feature_size"]

#: Clearance reported for an absent obstacle [m]: farther than anything in a 20 m workspace.
FAR = 30.0
_POS = 20.0  # position bound [m]: twice the workspace half-width
_REL = 40.0  # relative offsets [m]
_DIST = 60.0  # distances and clearances [m]


def feature_size(n_robots: int, n_obstacle_obs: int, formation: bool) -> int:
    """Length of one robot's observation block."""
    return 9 + 3 * (n_robots - 1) + 3 * n_obstacle_obs + (2 if formation else 0)


def feature_bounds(
    n_robots: int, n_obstacle_obs: int, formation: bool
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Lower and upper bounds of one robot's block, each shape (F,)."""
    low = [-_POS, -_POS, -1, -1, -_REL, -_REL, 0, -1, -1]
    high = [_POS, _POS, 1, 1, _REL, _REL, _DIST, 1, 1]
    low += [-_REL, -_REL, -_DIST] * (n_robots - 1 + n_obstacle_obs)
    high += [_REL, _REL, _DIST] * (n_robots - 1 + n_obstacle_obs)
    if formation:
        low += [-_REL, -_REL]
        high += [_REL, _REL]
    return np.array(low, dtype=np.float64), np.array(high, dtype=np.float64)


class FeatureBuilder:
    """Assembles the observation blocks of K environments from the step's geometry.

    Parameters
    ----------
    num_envs : int
        Batch size K.
    n_robots : int
        Robots per environment N.
    n_obstacles : int
        Obstacles per environment M.
    n_obstacle_obs : int
        Obstacles listed per robot (nearest first).
    formation : bool
        Append the formation error.
    """

    def __init__(
        self, num_envs: int, n_robots: int, n_obstacles: int, n_obstacle_obs: int, formation: bool
    ) -> None:
        n, k = n_robots, num_envs
        self.shape = (k, n, feature_size(n, n_obstacle_obs, formation))
        self.low, self.high = feature_bounds(n, n_obstacle_obs, formation)
        self.n_robots, self.n_obstacles = n, n_obstacles
        self.n_obstacle_obs = n_obstacle_obs
        self.formation = formation
        self.listed = min(n_obstacles, n_obstacle_obs)
        # fancy-index helpers: row i lists every robot but i; env and robot index grids
        self._others = np.array([[j for j in range(n) if j != i] for i in range(n)], dtype=np.intp)
        self._robot_rows = np.arange(n)[:, None]
        self._env_grid = np.arange(k)[:, None, None]
        self._robot_grid = np.arange(n)[None, :, None]
        self._others_at = 9
        self._obstacles_at = 9 + 3 * (n - 1)
        self._formation_at = self._obstacles_at + 3 * n_obstacle_obs

    def build(
        self,
        poses: NDArray,
        targets: NDArray,
        geometry: Geometry,
        formation_offsets: NDArray | None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Observation blocks and target distances.

        Parameters
        ----------
        poses, targets : ndarray, shape (K, N, 3)
            Current and target poses.
        geometry : Geometry
            Pairwise geometry of ``poses`` (robots first, then obstacles).
        formation_offsets : ndarray, shape (K, N, 2), optional
            Used when the builder was made with ``formation=True``.

        Returns
        -------
        features : ndarray, shape (K, N, F)
            Clipped into the bounds of :func:`feature_bounds`.
        distances : ndarray, shape (K, N)
            Distance of every robot to its target [m] (unclipped).
        """
        n = self.n_robots
        out = np.empty(self.shape)
        x, y, th = poses[..., 0], poses[..., 1], poses[..., 2]
        c, s = np.cos(th), np.sin(th)
        out[..., 0] = x
        out[..., 1] = y
        out[..., 2] = c
        out[..., 3] = s
        tdx = targets[..., 0] - x
        tdy = targets[..., 1] - y
        out[..., 4] = c * tdx + s * tdy
        out[..., 5] = c * tdy - s * tdx
        distances = np.hypot(tdx, tdy)
        out[..., 6] = distances
        dth = targets[..., 2] - th
        out[..., 7] = np.cos(dth)
        out[..., 8] = np.sin(dth)
        if n > 1 or self.listed:
            # body-frame offsets and clearance to every entity, then pick the wanted ones
            c3, s3 = c[..., None], s[..., None]
            rel = np.empty(geometry.dx.shape + (3,))
            rel[..., 0] = c3 * geometry.dx + s3 * geometry.dy
            rel[..., 1] = c3 * geometry.dy - s3 * geometry.dx
            rel[..., 2] = geometry.clearance
            if n > 1:
                others = rel[:, self._robot_rows, self._others]
                out[..., self._others_at : self._obstacles_at] = others.reshape(self.shape[0], n, -1)
            if self.n_obstacle_obs:
                block = out[..., self._obstacles_at : self._formation_at]
                if self.listed:
                    order = np.argsort(geometry.clearance[..., n:], axis=-1)
                    nearest = rel[self._env_grid, self._robot_grid, n + order[..., : self.listed]]
                    block[..., : 3 * self.listed] = nearest.reshape(self.shape[0], n, -1)
                if self.listed < self.n_obstacle_obs:
                    pad = np.tile([0.0, 0.0, FAR], self.n_obstacle_obs - self.listed)
                    block[..., 3 * self.listed :] = pad
        if self.formation:
            out[..., -2] = x - x[:, :1] - formation_offsets[..., 0]
            out[..., -1] = y - y[:, :1] - formation_offsets[..., 1]
        np.maximum(out, self.low, out=out)
        np.minimum(out, self.high, out=out)
        return out, distances
