"""Per-robot observation features shared by every front (centralized, vector, per-agent).

One robot's block is laid out by :class:`koopman_envs.layout.ObservationLayout` (its
module docstring has the table of named parts: position, heading, target, team-mates, obstacles
or lidar beams, formation error, message ages, movers).

Everything a robot's block says is what that robot believes: its own pose is its localization
estimate and a team-mate's is the last message it received (:mod:`koopman_envs.sim.perception`;
without uncertainty settings both are the truth). A team-mate from whom no message has arrived
reads (0, 0, ``FAR``). Every entry is clipped into the bounds of :func:`feature_bounds`, so
observations stay inside the observation space even after a robot has left the workspace.
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import TYPE_CHECKING

import numpy as np
from numba import njit
from numpy.typing import NDArray

from koopman_envs.layout import ObservationLayout
from koopman_envs.scenario import Scenario
from koopman_envs.sim.geometry import TeamGeometry, clearance
from koopman_envs.sim.movers import mover_features
from koopman_envs.sim.nearest import nearest_first

if TYPE_CHECKING:  # pragma: no cover - typing only
    from koopman_envs.sim.perception import Perception

__all__ = ["AGE_MAX", "FAR", "FeatureBuilder", "feature_bounds", "feature_size", "observation_from_beliefs"]

#: Clearance reported for an absent obstacle [m]: farther than anything in a 20 m workspace.
FAR = 30.0
_POS = 20.0  # position bound [m]: twice the workspace half-width
_REL = 40.0  # relative offsets [m]
_DIST = 60.0  # distances and clearances [m]
_SPEED = 5.0  # mover velocities [m/s]: ten times a pedestrian's
#: Largest message age an observation reports [control periods] (ours: 10 s; older reads this).
AGE_MAX = 100


def feature_size(
    n_robots: int, n_obstacle_obs: int, formation: bool, beams: int = 0, comm: bool = False, movers: int = 0
) -> int:
    """Length of one robot's observation block (``beams`` > 0: lidar readings replace the obstacle
    list; ``comm``: the message ages and flags are appended; ``movers``: that many listed movers
    after them)."""
    return ObservationLayout(n_robots, n_obstacle_obs, formation, beams, comm, movers).size


def feature_bounds(
    n_robots: int,
    n_obstacle_obs: int,
    formation: bool,
    beams: int = 0,
    comm: bool = False,
    lidar_range: float = 0.0,
    movers: int = 0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Lower and upper bounds of one robot's block, each shape (F,) (arguments as :func:`feature_size`)."""
    low = [-_POS, -_POS, -1, -1, -_REL, -_REL, 0, -1, -1] + [-_REL, -_REL, -_DIST] * (n_robots - 1)
    high = [_POS, _POS, 1, 1, _REL, _REL, _DIST, 1, 1] + [_REL, _REL, _DIST] * (n_robots - 1)
    if beams:
        low += [0.0] * beams
        high += [lidar_range] * beams
    else:
        low += [-_REL, -_REL, -_DIST] * n_obstacle_obs
        high += [_REL, _REL, _DIST] * n_obstacle_obs
    if formation:
        low += [-_REL, -_REL]
        high += [_REL, _REL]
    if comm:
        low += [0, 0] * (n_robots - 1)
        high += [AGE_MAX, 1] * (n_robots - 1)
    low += [-_REL, -_REL, -_SPEED, -_SPEED, -_DIST] * movers
    high += [_REL, _REL, _SPEED, _SPEED, _DIST] * movers
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
    beams : int
        Lidar beams replacing the obstacle list (0: the list).
    comm : bool
        Append each team-mate's message age and arrival flag.
    lidar_range : float
        Largest lidar reading [m] (the beams' upper bound).
    movers : int
        Nearest movers listed at the end of each block (0: none).
    mover_radius : float
        The movers' disc radius [m] (their clearances).
    """

    def __init__(
        self,
        num_envs: int,
        n_robots: int,
        n_obstacles: int,
        n_obstacle_obs: int,
        formation: bool,
        beams: int = 0,
        comm: bool = False,
        lidar_range: float = 0.0,
        movers: int = 0,
        mover_radius: float = 0.0,
    ) -> None:
        n, k = n_robots, num_envs
        #: the block's named parts (koopman_envs.layout)
        self.layout = ObservationLayout(n, n_obstacle_obs, formation, beams, comm, movers)
        self.shape = (k, n, self.layout.size)
        self.low, self.high = feature_bounds(n, n_obstacle_obs, formation, beams, comm, lidar_range, movers)
        self.mover_slots = movers
        self.mover_radius = mover_radius
        self.movers_at = self.layout["movers"].start if movers else self.shape[-1]
        self.n_robots, self.n_obstacles = n, n_obstacles
        self.n_obstacle_obs = 0 if beams else n_obstacle_obs
        self.formation, self.beams, self.comm = formation, beams, comm
        self._no_offsets = np.zeros((k, 2, n))  # the kernel's formation input when unused
        self._no_ranges = np.zeros((k, n, 0))
        self._same_age = np.zeros((k, n, n), dtype=np.int64)
        #: positions in a block of the surface clearances (other robots, then listed obstacles)
        listed = self.layout["team"].start, self.layout["team"].stop + 3 * self.n_obstacle_obs
        self.clearance_index = np.arange(listed[0] + 2, listed[1], 3)

    def build(
        self,
        state: NDArray[np.float64],
        target: NDArray[np.float64],
        geometry: TeamGeometry,
        formation_offsets: NDArray[np.float64] | None,
        perception: Perception | None = None,
        movers: NDArray[np.float64] | None = None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Observation blocks and target distances.

        Parameters
        ----------
        state, target : ndarray, shape (K, 3, N)
            Current (true) and target poses as rows x [m], y [m], theta [rad].
        geometry : TeamGeometry
            Obstacle layouts and radius sums of the K environments.
        formation_offsets : ndarray, shape (K, 2, N), optional
            Rows dx, dy [m]; used when the builder was made with ``formation=True``.
        perception : Perception, optional
            What the robots believe (own estimates, messages, lidar); None: the truth.
        movers : ndarray, shape (K, C, 4), optional
            The movers as observed (x, y, vx, vy; a NaN row: a mover not observed), listed at
            the end of each block (when the builder has slots).

        Returns
        -------
        features : ndarray, shape (K, N, F)
            Clipped into the bounds of :func:`feature_bounds`.
        distances : ndarray, shape (K, N)
            Distance of every robot to its target [m] (unclipped), as the robot believes it
            (the truth without ``perception``).
        """
        out = np.empty(self.shape)
        distances = np.empty(self.shape[:2])
        offsets = self._no_offsets if formation_offsets is None else formation_offsets
        if perception is None:
            k, _, n = state.shape
            own, ranges, age = state, self._no_ranges, self._same_age
            # everyone knows the truth: row i of robot i's view is every robot's true pose
            known = np.broadcast_to(state.transpose(0, 2, 1)[:, None], (k, n, n, 3))
        else:
            own, known, age, ranges = perception.observed, perception.known, perception.age, perception.ranges
        _build_features(
            own,
            known,
            age,
            self.comm,
            ranges,
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
        if self.mover_slots and movers is not None:
            mover_features(
                own,
                geometry.robot_radius,
                movers[..., :2],
                movers[..., 2:],
                self.mover_radius,
                self.mover_slots,
                self.movers_at,
                self.low,
                self.high,
                out,
            )
        return out, distances


def observation_from_beliefs(
    scenario: Scenario,
    poses: NDArray[np.float64],
    known: NDArray[np.float64],
    message_age: NDArray[np.int64],
    targets: NDArray[np.float64],
    movers: NDArray[np.float64],
    n_obstacle_obs: int,
    mover_slots: int,
) -> NDArray[np.float64]:
    """The team's observation blocks as a state-sensing env of ``scenario`` lists them, built by
    the env's own builder (:class:`FeatureBuilder`) from what the robots believe: for a policy
    that reads listed obstacles and movers when they come from perception instead of the env.

    Parameters
    ----------
    scenario : Scenario
        Its ``obstacles`` are the ones listed (the map's, or a local map's), its radii,
        ``formation_offsets``, ``message_ages`` and ``mover_radius`` those of the env.
    poses : ndarray, shape (N, 3)
        Each robot's own pose estimate: x [m], y [m], theta [rad].
    known : ndarray, shape (N, N, 3)
        Row i: the poses robot i believes its team-mates are at.
    message_age : ndarray of int64, shape (N, N)
        Periods since robot i last heard from robot j.
    targets : ndarray, shape (N, 3)
        Target poses.
    movers : ndarray, shape (C, 4)
        Movers as observed: x, y [m], vx, vy [m/s]; a NaN row is not listed.
    n_obstacle_obs, mover_slots : int
        Obstacles and movers listed per robot.

    Returns
    -------
    ndarray, shape (N, F)
        One block per robot, in the layout of :class:`koopman_envs.layout.ObservationLayout`.
    """
    n = scenario.n_robots
    obstacles = np.asarray(scenario.obstacles, dtype=np.float64).reshape(-1, 3)
    builder = FeatureBuilder(
        1,
        n,
        len(obstacles),
        n_obstacle_obs,
        scenario.is_formation,
        comm=scenario.message_ages,
        movers=mover_slots,
        mover_radius=scenario.mover_radius,
    )
    geometry = TeamGeometry(1, np.asarray(scenario.robot_radius, dtype=np.float64), len(obstacles))
    geometry.set_obstacles(0, obstacles)
    state = poses.T[None]  # (1, 3, N)
    perception = SimpleNamespace(
        observed=np.ascontiguousarray(state),
        known=np.ascontiguousarray(known.reshape(1, n, n, 3)),
        age=message_age.reshape(1, n, n),
        ranges=np.zeros((1, n, 0)),
    )
    target = np.ascontiguousarray(np.asarray(targets, dtype=np.float64).reshape(n, 3).T[None])
    offsets = np.ascontiguousarray(
        np.asarray(scenario.formation_offsets, dtype=np.float64).reshape(n, 2).T[None]
    )
    blocks, _ = builder.build(
        state,
        target,
        geometry,
        offsets if scenario.is_formation else None,
        perception,  # type: ignore[arg-type]  # the Perception fields the builder reads
        movers.reshape(1, -1, 4),
    )
    team: NDArray[np.float64] = blocks[0]
    return team


@njit(cache=True)
def _build_features(
    own: NDArray[np.float64],
    known: NDArray[np.float64],
    age: NDArray[np.int64],
    comm: bool,
    ranges: NDArray[np.float64],
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
    """Fill ``out`` (K, N, F) and ``distances`` (K, N) in the layout of the module docstring.

    ``own`` (K, 3, N) holds every robot's pose estimate, ``known[k, i, j]`` (K, N, N, 3) what
    robot i knows of robot j and ``age`` (K, N, N) how old that is (-1: nothing yet);
    ``ranges`` (K, N, B) the lidar readings (B = 0: list the obstacles instead).
    """
    n_envs, _, n_robots = own.shape
    n_obstacles = obstacle_x.shape[1]
    n_features = out.shape[2]
    beams = ranges.shape[2]
    listed = min(n_obstacles, n_obstacle_obs)
    obstacles_at = 9 + 3 * (n_robots - 1)
    formation_at = obstacles_at + (beams if beams else 3 * n_obstacle_obs)
    comm_at = formation_at + (2 if formation else 0)
    gap = np.empty(n_obstacles)
    order = np.empty(n_obstacles, dtype=np.int64)
    for k in range(n_envs):
        for i in range(n_robots):
            row = out[k, i]
            x, y, theta = own[k, 0, i], own[k, 1, i], own[k, 2, i]
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
                    if age[k, i, j] < 0:  # no message from j yet
                        row[at], row[at + 1], row[at + 2] = 0.0, 0.0, FAR
                    else:
                        ox, oy = known[k, i, j, 0], known[k, i, j, 1]
                        dx, dy = ox - x, oy - y
                        row[at] = c * dx + s * dy
                        row[at + 1] = c * dy - s * dx
                        row[at + 2] = clearance(x, y, ox, oy, radius_sum[k, i, j])
                    at += 3
            for b in range(beams):
                row[at] = ranges[k, i, b]
                at += 1
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
                # the leader's position as this robot knows it (its own estimate for the leader)
                if age[k, i, 0] < 0:  # nothing heard of the leader yet: no error to report
                    row[formation_at], row[formation_at + 1] = 0.0, 0.0
                else:
                    row[formation_at] = (x - known[k, i, 0, 0]) - offsets[k, 0, i]
                    row[formation_at + 1] = (y - known[k, i, 0, 1]) - offsets[k, 1, i]
            if comm:
                at = comm_at
                for j in range(n_robots):
                    if j != i:
                        heard = age[k, i, j] >= 0
                        row[at] = min(age[k, i, j], AGE_MAX) if heard else AGE_MAX
                        row[at + 1] = 1.0 if heard else 0.0
                        at += 2
            for f in range(n_features):
                value = row[f]
                if value < low[f]:
                    value = low[f]
                if value > high[f]:
                    value = high[f]
                row[f] = value
