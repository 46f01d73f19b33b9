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
        # flat row index of (env k, robot i, entity 0) in a (K * N * E, 3) view of the entities
        n_entities = n + n_obstacles
        row_base = (np.arange(k)[:, None] * n + np.arange(n)[None, :]) * n_entities
        self._others_flat = (row_base[:, :, None] + self._others[None]).astype(np.intp)
        self._obstacle_base = (row_base[:, :, None] + n).astype(np.intp)
        self._others_at = 9
        self._obstacles_at = 9 + 3 * (n - 1)
        self._formation_at = self._obstacles_at + 3 * n_obstacle_obs
        self._padding = np.tile([0.0, 0.0, FAR], max(n_obstacle_obs - self.listed, 0))
        #: positions in a block of the surface clearances (other robots, then listed obstacles)
        self.clearance_index = np.arange(self._others_at + 2, self._formation_at, 3)

    def build(
        self,
        state: NDArray,
        target: NDArray,
        geometry: Geometry,
        formation_offsets: NDArray | None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Observation blocks and target distances.

        Parameters
        ----------
        state, target : ndarray, shape (K, 3, N)
            Current and target poses as rows x [m], y [m], theta [rad].
        geometry : Geometry
            Pairwise geometry of ``state`` (robots first, then obstacles).
        formation_offsets : ndarray, shape (K, 2, N), optional
            Rows dx, dy [m]; used when the builder was made with ``formation=True``.

        Returns
        -------
        features : ndarray, shape (K, N, F)
            Clipped into the bounds of :func:`feature_bounds`.
        distances : ndarray, shape (K, N)
            Distance of every robot to its target [m] (unclipped).
        """
        n = self.n_robots
        out = np.empty(self.shape)
        x, y, th = state[:, 0], state[:, 1], state[:, 2]
        c, s = np.cos(th), np.sin(th)
        out[..., 0] = x
        out[..., 1] = y
        out[..., 2] = c
        out[..., 3] = s
        tdx = target[:, 0] - x
        tdy = target[:, 1] - y
        body = c * tdx
        body += s * tdy
        out[..., 4] = body
        body = c * tdy
        body -= s * tdx
        out[..., 5] = body
        distances = tdx * tdx
        distances += tdy * tdy
        np.sqrt(distances, out=distances)
        out[..., 6] = distances
        dth = target[:, 2] - th
        out[..., 7] = np.cos(dth)
        out[..., 8] = np.sin(dth)
        if n > 1 or self.listed:
            # body-frame offsets and clearance to every entity, then pick the wanted ones
            c3, s3 = c[..., None], s[..., None]
            rel = np.empty(geometry.dx.shape + (3,))
            body = c3 * geometry.dx
            body += s3 * geometry.dy
            rel[..., 0] = body
            body = c3 * geometry.dy
            body -= s3 * geometry.dx
            rel[..., 1] = body
            rel[..., 2] = geometry.clearance
            flat = rel.reshape(-1, 3)
            if n > 1:
                others = flat.take(self._others_flat, axis=0)
                out[..., self._others_at : self._obstacles_at] = others.reshape(self.shape[0], n, -1)
            if self.n_obstacle_obs:
                block = out[..., self._obstacles_at : self._formation_at]
                if self.listed:
                    order = geometry.clearance[..., n:].argsort(axis=-1)
                    if self.listed < self.n_obstacles:
                        order = order[..., : self.listed]
                    order += self._obstacle_base
                    nearest = flat.take(order, axis=0)
                    block[..., : 3 * self.listed] = nearest.reshape(self.shape[0], n, -1)
                if self.listed < self.n_obstacle_obs:
                    block[..., 3 * self.listed :] = self._padding
        if self.formation:
            ex = x - x[:, :1]
            ex -= formation_offsets[:, 0]
            out[..., -2] = ex
            ey = y - y[:, :1]
            ey -= formation_offsets[:, 1]
            out[..., -1] = ey
        np.maximum(out, self.low, out=out)  # two ufuncs: cheaper than np.clip on small arrays
        np.minimum(out, self.high, out=out)
        return out, distances
