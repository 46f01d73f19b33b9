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

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from koopman_envs.sim.geometry import TeamGeometry, clearance
from koopman_envs.sim.nearest import nearest_first

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
    """Assembles the observation blocks of K environments (one compiled pass over robots and obstacles).

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
        self._no_offsets = np.zeros((k, 2, n))  # the kernel's formation input when unused
        #: positions in a block of the surface clearances (other robots, then listed obstacles)
        self.clearance_index = np.arange(9 + 2, 9 + 3 * (n - 1 + n_obstacle_obs), 3)

    def build(
        self,
        state: NDArray[np.float64],
        target: NDArray[np.float64],
        geometry: TeamGeometry,
        formation_offsets: NDArray[np.float64] | None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Observation blocks and target distances.

        Parameters
        ----------
        state, target : ndarray, shape (K, 3, N)
            Current and target poses as rows x [m], y [m], theta [rad].
        geometry : TeamGeometry
            Obstacle layouts and radius sums of the K environments.
        formation_offsets : ndarray, shape (K, 2, N), optional
            Rows dx, dy [m]; used when the builder was made with ``formation=True``.

        Returns
        -------
        features : ndarray, shape (K, N, F)
            Clipped into the bounds of :func:`feature_bounds`.
        distances : ndarray, shape (K, N)
            Distance of every robot to its target [m] (unclipped).
        """
        out = np.empty(self.shape)
        distances = np.empty(self.shape[:2])
        offsets = self._no_offsets if formation_offsets is None else formation_offsets
        _build_features(
            state,
            target,
            offsets,
            self.formation,
            geometry.obstacle_x,
            geometry.obstacle_y,
            geometry.radius_sum,
            self.n_obstacle_obs,
            self.low,
            self.high,
            out,
            distances,
        )
        return out, distances


@njit(cache=True)
def _build_features(
    state: NDArray[np.float64],
    target: NDArray[np.float64],
    offsets: NDArray[np.float64],
    formation: bool,
    obstacle_x: NDArray[np.float64],
    obstacle_y: NDArray[np.float64],
    radius_sum: NDArray[np.float64],
    n_obstacle_obs: int,
    low: NDArray[np.float64],
    high: NDArray[np.float64],
    out: NDArray[np.float64],
    distances: NDArray[np.float64],
) -> None:  # pragma: no cover - compiled
    """Fill ``out`` (K, N, F) and ``distances`` (K, N) in the layout of the module docstring."""
    n_envs, _, n_robots = state.shape
    n_obstacles = obstacle_x.shape[1]
    n_features = out.shape[2]
    listed = min(n_obstacles, n_obstacle_obs)
    obstacles_at = 9 + 3 * (n_robots - 1)
    formation_at = obstacles_at + 3 * n_obstacle_obs
    gap = np.empty(n_obstacles)
    order = np.empty(n_obstacles, dtype=np.int64)
    for k in range(n_envs):
        for i in range(n_robots):
            row = out[k, i]
            x, y, theta = state[k, 0, i], state[k, 1, i], state[k, 2, i]
            c, s = math.cos(theta), math.sin(theta)
            row[0], row[1], row[2], row[3] = x, y, c, s
            tdx = target[k, 0, i] - x
            tdy = target[k, 1, i] - y
            row[4] = c * tdx + s * tdy
            row[5] = c * tdy - s * tdx
            distance = math.sqrt(tdx * tdx + tdy * tdy)
            row[6] = distance
            distances[k, i] = distance
            dtheta = target[k, 2, i] - theta
            row[7], row[8] = math.cos(dtheta), math.sin(dtheta)
            at = 9
            for j in range(n_robots):
                if j != i:
                    ox, oy = state[k, 0, j], state[k, 1, j]
                    dx, dy = ox - x, oy - y
                    row[at] = c * dx + s * dy
                    row[at + 1] = c * dy - s * dx
                    row[at + 2] = clearance(x, y, ox, oy, radius_sum[k, i, j])
                    at += 3
            if n_obstacle_obs:
                for m in range(n_obstacles):
                    gap[m] = clearance(
                        x, y, obstacle_x[k, m], obstacle_y[k, m], radius_sum[k, i, n_robots + m]
                    )
                nearest_first(gap, order, n_obstacles)  # equal clearances keep index order
                for q in range(listed):
                    m = order[q]
                    dx, dy = obstacle_x[k, m] - x, obstacle_y[k, m] - y
                    row[at] = c * dx + s * dy
                    row[at + 1] = c * dy - s * dx
                    row[at + 2] = gap[m]
                    at += 3
                for _ in range(listed, n_obstacle_obs):
                    row[at], row[at + 1], row[at + 2] = 0.0, 0.0, FAR
                    at += 3
            if formation:
                row[formation_at] = (x - state[k, 0, 0]) - offsets[k, 0, i]
                row[formation_at + 1] = (y - state[k, 1, 0]) - offsets[k, 1, i]
            for f in range(n_features):
                value = row[f]
                if value < low[f]:
                    value = low[f]
                if value > high[f]:
                    value = high[f]
                row[f] = value
