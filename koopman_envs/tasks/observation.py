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
from enum import IntEnum
from types import SimpleNamespace

import numpy as np
from numba import njit
from numpy.typing import NDArray

from koopman_envs.layout import (
    FAR,
    PART_WIDTH,
    MessageEntry,
    MoverEntry,
    ObservationLayout,
    ObstacleEntry,
    TeamEntry,
)
from koopman_envs.scenario import Scenario
from koopman_envs.sim.geometry import TeamGeometry, clearance
from koopman_envs.sim.movers.field import mover_features
from koopman_envs.sim.nearest import nearest_first
from koopman_envs.sim.perception import Perception

__all__ = ["AGE_MAX", "FAR", "FeatureBuilder", "feature_bounds", "feature_size", "observation_from_beliefs"]

_POS = 20.0  # position bound [m]: twice the workspace half-width
_REL = 40.0  # relative offsets [m]
_DIST = 60.0  # distances and clearances [m]
_SPEED = 5.0  # mover velocities [m/s]: ten times a pedestrian's
#: Largest message age an observation reports [control periods] (ours: 10 s; older reads this).
AGE_MAX = 100

#: (lower, upper) bounds of one entry
_Bounds = tuple[float, float]
# entries per item, as module constants: what the compiled writer can read
_TEAM_WIDTH = PART_WIDTH["team"]
_OBSTACLE_WIDTH = PART_WIDTH["obstacles"]
_MESSAGE_WIDTH = PART_WIDTH["messages"]
#: what the robots believe, as the compiled writer takes it: ``known`` (K, N, N, 3) team-mates'
#: poses, ``age`` (K, N, N) int64 message ages, ``ranges`` (K, N, B) lidar readings; a plain
#: tuple, which numba types at a call almost as fast as loose arrays (a named tuple it types in
#: Python, microseconds a call)
Beliefs = tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]


def feature_size(
    n_robots: int, n_obstacle_obs: int, formation: bool, beams: int = 0, comm: bool = False, movers: int = 0
) -> int:
    """Length of one robot's observation block (``beams`` > 0: lidar readings replace the obstacle
    list; ``comm``: the message ages and flags are appended; ``movers``: that many listed movers
    after them)."""
    return ObservationLayout(n_robots, n_obstacle_obs, formation, beams, comm, movers).size


def _item(entries: dict[IntEnum, _Bounds]) -> list[_Bounds]:
    """An item's bounds in the order of its named entries (each entry named once)."""
    kind = type(next(iter(entries)))
    if set(entries) != set(kind):
        raise ValueError(f"bounds for {sorted(entries)}; {kind.__name__} has {list(kind)}")
    return [entries[entry] for entry in kind]


def _part_bounds(lidar_range: float) -> dict[str, list[_Bounds]]:
    """The bounds of one item of every part, by part name (a part of one item: the part's)."""
    rel, dist, unit = (-_REL, _REL), (-_DIST, _DIST), (-1.0, 1.0)
    speed = (-_SPEED, _SPEED)
    return {
        "position": [(-_POS, _POS)] * 2,
        "heading": [unit] * 2,
        "target": [rel] * 2,
        "target_distance": [(0.0, _DIST)],
        "target_heading": [unit] * 2,
        "team": _item({TeamEntry.DX: rel, TeamEntry.DY: rel, TeamEntry.CLEARANCE: dist}),
        "obstacles": _item({ObstacleEntry.DX: rel, ObstacleEntry.DY: rel, ObstacleEntry.CLEARANCE: dist}),
        "beams": [(0.0, lidar_range)],
        "formation_error": [rel] * 2,
        "messages": _item({MessageEntry.AGE: (0.0, AGE_MAX), MessageEntry.HEARD: (0.0, 1.0)}),
        "movers": _item(
            {
                MoverEntry.DX: rel,
                MoverEntry.DY: rel,
                MoverEntry.VX: speed,
                MoverEntry.VY: speed,
                MoverEntry.CLEARANCE: dist,
            }
        ),
    }


def feature_bounds(
    layout: ObservationLayout, lidar_range: float = 0.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Lower and upper bounds of one robot's block of ``layout``, each shape (F,): every part's
    item bounds repeated over its items, in the layout's order (``lidar_range`` [m]: the beams'
    upper bound)."""
    table = _part_bounds(lidar_range)
    low: list[float] = []
    high: list[float] = []
    for name, width in layout.parts:
        item = table[name]
        count = width // len(item)
        low += [lower for lower, _ in item] * count
        high += [upper for _, upper in item] * count
    return np.array(low, dtype=np.float64), np.array(high, dtype=np.float64)


class FeatureBuilder:
    """Assembles the observation blocks of K environments (one compiled pass over robots and obstacles).

    Parameters
    ----------
    num_envs : int
        Batch size K.
    layout : ObservationLayout
        One robot's block (the engine's :attr:`~koopman_envs.engine.config.EngineConfig.observation_layout`):
        team size, listed obstacles or lidar beams, formation error, message ages, listed movers.
    n_obstacles : int
        Obstacles per environment M.
    lidar_range : float
        Largest lidar reading [m] (the beams' upper bound).
    mover_radius : float
        The movers' disc radius [m] (their clearances).
    """

    def __init__(
        self,
        num_envs: int,
        layout: ObservationLayout,
        n_obstacles: int,
        lidar_range: float = 0.0,
        mover_radius: float = 0.0,
    ) -> None:
        n, k = layout.n_robots, num_envs
        #: the block's named parts (koopman_envs.layout)
        self.layout = layout
        #: where each part begins (:class:`~koopman_envs.layout.PartOffsets`)
        self.offsets = layout.offsets
        self._at = self.offsets.as_record()  # the same, as the compiled writer takes them
        self.shape = (k, n, layout.size)
        #: rows lower and upper bound of every entry, (2, F) (what the compiled writer takes)
        self.bounds = np.array(feature_bounds(layout, lidar_range))
        self.low, self.high = self.bounds
        self.mover_slots = layout.movers
        self.mover_radius = mover_radius
        self.n_robots, self.n_obstacles = n, n_obstacles
        self._no_offsets = np.zeros((k, 2, n))  # the kernel's formation input when unused
        # the kernel's beliefs when the robots know the truth: an empty ``known`` is its sign,
        # every message fresh, no beams
        self._truth: Beliefs = (
            np.zeros((k, 0, 0, 3)),
            np.zeros((k, n, n), dtype=np.int64),
            np.zeros((k, n, 0)),
        )

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
            own, beliefs = state, self._truth
        else:
            own, beliefs = perception.observed, (perception.known, perception.age, perception.ranges)
        _build_features(
            own,
            beliefs,
            target,
            offsets,
            geometry.obstacles,
            geometry.radius_sum,
            self._at,
            self.bounds,
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
                self.offsets.movers,
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
    layout = ObservationLayout(
        n, n_obstacle_obs, scenario.is_formation, comm=scenario.message_ages, movers=mover_slots
    )
    builder = FeatureBuilder(1, layout, len(obstacles), mover_radius=scenario.mover_radius)
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
    beliefs: Beliefs,
    target: NDArray[np.float64],
    offsets: NDArray[np.float64],
    obstacles: NDArray[np.float64],
    radius_sum: NDArray[np.float64],
    offsets_record: NDArray[np.void],
    bounds: NDArray[np.float64],
    out: NDArray[np.float64],
    distances: NDArray[np.float64],
) -> None:  # pragma: no cover - compiled
    """Fill ``out`` (K, N, F) and ``distances`` (K, N) in the layout whose part offsets are
    ``offsets_record[0]`` (:meth:`PartOffsets.as_record <koopman_envs.layout.PartOffsets.as_record>`
    of :attr:`ObservationLayout.offsets <koopman_envs.layout.ObservationLayout.offsets>`: a part's
    width is the gap to the next part, so a part the layout lacks is written nowhere).

    ``own`` (K, 3, N) holds every robot's pose estimate; ``beliefs`` (:data:`Beliefs`) is
    ``known``, ``age``, ``ranges``: ``known[k, i, j]`` (K, N, N, 3) what robot i knows of robot j
    (an empty ``known``, (K, 0, 0, 3): every robot knows the truth, ``own``, without a
    (K, N, N, 3) copy or view made for it on every step), ``age`` (K, N, N) how old that is
    (-1: nothing yet), ``ranges`` (K, N, B) the lidar readings (the ``beams`` part);
    ``offsets`` (K, 2, N) the formation offsets (the ``formation_error`` part); ``bounds``
    (2, F) every entry's lower and upper bound, the clip.
    """
    known, age, ranges = beliefs
    low, high = bounds[0], bounds[1]
    at = offsets_record[0]
    n_envs, _, n_robots = own.shape
    n_obstacles = obstacles.shape[2]
    n_features = out.shape[2]
    beams = at.formation_error - at.beams
    n_obstacle_obs = (at.beams - at.obstacles) // _OBSTACLE_WIDTH
    formation = at.messages > at.formation_error
    comm = at.movers > at.messages
    truth = known.shape[1] == 0
    listed = min(n_obstacles, n_obstacle_obs)
    gap = np.empty(n_obstacles)
    order = np.empty(n_obstacles, dtype=np.int64)
    for k in range(n_envs):
        for i in range(n_robots):
            row = out[k, i]
            x, y, theta = own[k, 0, i], own[k, 1, i], own[k, 2, i]
            c, s = math.cos(theta), math.sin(theta)
            row[at.position], row[at.position + 1] = x, y
            row[at.heading], row[at.heading + 1] = c, s
            tdx = target[k, 0, i] - x
            tdy = target[k, 1, i] - y
            row[at.target] = c * tdx + s * tdy
            row[at.target + 1] = c * tdy - s * tdx
            distance = math.sqrt(tdx * tdx + tdy * tdy)
            row[at.target_distance] = distance
            distances[k, i] = distance
            dtheta = target[k, 2, i] - theta
            row[at.target_heading], row[at.target_heading + 1] = math.cos(dtheta), math.sin(dtheta)
            col = at.team
            for j in range(n_robots):
                if j != i:
                    if age[k, i, j] < 0:  # no message from j yet
                        row[col + TeamEntry.DX], row[col + TeamEntry.DY] = 0.0, 0.0
                        row[col + TeamEntry.CLEARANCE] = FAR
                    else:
                        if truth:
                            ox, oy = own[k, 0, j], own[k, 1, j]
                        else:
                            ox, oy = known[k, i, j, 0], known[k, i, j, 1]
                        dx, dy = ox - x, oy - y
                        row[col + TeamEntry.DX] = c * dx + s * dy
                        row[col + TeamEntry.DY] = c * dy - s * dx
                        row[col + TeamEntry.CLEARANCE] = clearance(x, y, ox, oy, radius_sum[k, i, j])
                    col += _TEAM_WIDTH
            for b in range(beams):
                row[at.beams + b] = ranges[k, i, b]
            if n_obstacle_obs:
                for m in range(n_obstacles):
                    gap[m] = clearance(
                        x, y, obstacles[k, 0, m], obstacles[k, 1, m], radius_sum[k, i, n_robots + m]
                    )
                nearest_first(gap, order, n_obstacles)  # equal clearances keep index order
                col = at.obstacles
                for q in range(listed):
                    m = order[q]
                    dx, dy = obstacles[k, 0, m] - x, obstacles[k, 1, m] - y
                    row[col + ObstacleEntry.DX] = c * dx + s * dy
                    row[col + ObstacleEntry.DY] = c * dy - s * dx
                    row[col + ObstacleEntry.CLEARANCE] = gap[m]
                    col += _OBSTACLE_WIDTH
                for _ in range(listed, n_obstacle_obs):
                    row[col + ObstacleEntry.DX], row[col + ObstacleEntry.DY] = 0.0, 0.0
                    row[col + ObstacleEntry.CLEARANCE] = FAR
                    col += _OBSTACLE_WIDTH
            if formation:
                # the leader's position as this robot knows it (its own estimate for the leader)
                if age[k, i, 0] < 0:  # nothing heard of the leader yet: no error to report
                    row[at.formation_error], row[at.formation_error + 1] = 0.0, 0.0
                else:
                    if truth:
                        lx, ly = own[k, 0, 0], own[k, 1, 0]
                    else:
                        lx, ly = known[k, i, 0, 0], known[k, i, 0, 1]
                    row[at.formation_error] = (x - lx) - offsets[k, 0, i]
                    row[at.formation_error + 1] = (y - ly) - offsets[k, 1, i]
            if comm:
                col = at.messages
                for j in range(n_robots):
                    if j != i:
                        heard = age[k, i, j] >= 0
                        row[col + MessageEntry.AGE] = min(age[k, i, j], AGE_MAX) if heard else AGE_MAX
                        row[col + MessageEntry.HEARD] = 1.0 if heard else 0.0
                        col += _MESSAGE_WIDTH
            for f in range(n_features):
                value = row[f]
                if value < low[f]:
                    value = low[f]
                if value > high[f]:
                    value = high[f]
                row[f] = value
