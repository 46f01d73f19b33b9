"""Per-robot observations as sets: what a policy for any team size and layout reads.

A robot's block in the env's observation (:mod:`koopman_envs.tasks.observation`) lists every
other robot in index order, so its length and meaning change with the team size. A set policy
reads instead, for every robot i, a fixed-size vector built from the team's blocks:

``ego`` (:data:`EGO_SIZE` entries)
    target in the body frame (scaled and clipped), distance, unit bearing, log distance, cos and
    sin of the target heading error, the formation error rotated into the body frame, and a
    leader flag (formation task: robot 0 leads).
``neighbours`` (``neighbours`` slots of :data:`NEIGHBOUR_SIZE` + 1 entries)
    the team-mates within ``sensing_radius`` (surface clearance), nearest first, at most
    ``neighbours`` of them: body-frame offset, clearance, relative heading (cos, sin), the
    team-mate's own target offset seen in robot i's body frame (where it is going), its leader
    flag, then a mask entry (1 present, 0 absent).
``obstacles`` (``obstacles`` slots of :data:`OBSTACLE_SIZE` + 1 entries)
    the listed obstacles of the block within ``sensing_radius``: body-frame offset of the centre,
    clearance, then a mask entry.
``movers`` (``movers`` slots of :data:`MOVER_SIZE` + 1 entries; none unless ``movers`` > 0)
    the listed moving obstacles (``movers`` keyword) within ``sensing_radius``: body-frame offset
    of the centre, body-frame velocity, clearance, then a mask entry. A policy without mover
    slots runs in an env with movers too: it does not see them.

Absent slots hold zeros and mask 0; the set encoder (:mod:`baselines.sb3.set_encoder`) multiplies
every slot's encoding by its mask before pooling, so an absent slot's values change nothing.
Every entry is scaled by hand to order one, so the features need no running normalization
(which would also move the masks).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from koopman_envs import FAR, MoverEntry, ObstacleEntry, TeamEntry, nearest_order
from koopman_envs.checks import check_int, check_number
from koopman_envs.layout import PART_WIDTH, ObservationLayout

__all__ = [
    "EGO_SIZE",
    "MAX_TEAM",
    "NEIGHBOUR_SIZE",
    "MOVER_SIZE",
    "OBSTACLE_SIZE",
    "SetFeatureConfig",
    "set_feature_size",
    "set_features",
    "split_movers",
    "state_layout",
    "without_message_ages",
]

EGO_SIZE = 11
NEIGHBOUR_SIZE = 8
OBSTACLE_SIZE = 3
#: one feature per entry of a listed mover (:class:`koopman_envs.MoverEntry`, in its order)
MOVER_SIZE = PART_WIDTH["movers"]
#: largest team a set policy is run with (the evaluator's random maps place up to this many)
MAX_TEAM = 64
_TARGET_SCALE = 5.0  # [m]: target offsets enter as offset / 5, clipped to [-2, 2]
_NEAR_SCALE = 3.0  # [m]: neighbour and obstacle offsets, clearances
_FORMATION_SCALE = 2.0  # [m]
_SPEED_SCALE = 0.5  # [m/s]: mover velocities, the robots' speed limit
_EPS = 0.05  # [m]: the log distance's floor, half the default goal tolerance


@dataclass(frozen=True)
class SetFeatureConfig:
    """How many team-mates and obstacles a set policy reads, and within which radius.

    Parameters
    ----------
    neighbours : int
        Team-mate slots K >= 1 (the nearest K within ``sensing_radius``).
    obstacles : int
        Obstacle slots >= 1 (the block lists the env's ``n_obstacle_obs`` nearest; more slots
        than that stay masked).
    sensing_radius : float
        Surface clearance [m] > 0 beyond which a team-mate, obstacle or mover is not read.
    movers : int
        Mover slots >= 0 (0: the policy does not see movers; the policies before movers).
    """

    neighbours: int = 6
    obstacles: int = 6
    sensing_radius: float = 3.0
    movers: int = 0

    def __post_init__(self) -> None:
        check_int("neighbours", self.neighbours, 1)
        check_int("obstacles", self.obstacles, 1)
        check_number("sensing_radius", self.sensing_radius, above=0)
        check_int("movers", self.movers, 0)

    def as_dict(self) -> dict[str, Any]:
        """The fields, for a policy's metadata."""
        return asdict(self)

    @property
    def size(self) -> int:
        """Length of one robot's set observation."""
        return set_feature_size(self)


def set_feature_size(config: SetFeatureConfig) -> int:
    """Length of one robot's set observation for ``config``."""
    return (
        EGO_SIZE
        + config.neighbours * (NEIGHBOUR_SIZE + 1)
        + config.obstacles * (OBSTACLE_SIZE + 1)
        + config.movers * (MOVER_SIZE + 1)
    )


def _rotate_into_body(c: NDArray, s: NDArray, x: NDArray, y: NDArray) -> tuple[NDArray, NDArray]:
    """World-frame vector (x, y) in the body frame of a robot with heading (cos c, sin s)."""
    return c * x + s * y, -s * x + c * y


def set_features(
    team_blocks: NDArray,
    n_obstacle_obs: int,
    formation: bool,
    config: SetFeatureConfig = SetFeatureConfig(),
    movers: NDArray | None = None,
) -> NDArray[np.float32]:
    """Every robot's set observation, built from the team's observation blocks.

    Parameters
    ----------
    team_blocks : ndarray, shape (..., N, F)
        The team's blocks (:mod:`koopman_envs.tasks.observation`), N >= 1.
    n_obstacle_obs : int
        Obstacles listed per block (the env's ``n_obstacle_obs``).
    formation : bool
        Whether the blocks end with the formation error (the formation task).
    config : SetFeatureConfig
    movers : ndarray, shape (..., N, S, MOVER_SIZE), optional
        The movers each block listed (:func:`split_movers`: taken off the blocks first); None:
        none listed (every mover slot masked).

    Returns
    -------
    ndarray, shape (..., N, config.size), float32
    """
    blocks = np.asarray(team_blocks, dtype=np.float64)
    n = blocks.shape[-2]
    if not 1 <= n <= MAX_TEAM:
        raise ValueError(f"a set policy runs teams of 1..{MAX_TEAM} robots; these blocks hold {n}")
    layout = ObservationLayout(n, n_obstacle_obs, formation)
    expected = layout.size
    if blocks.shape[-1] != expected:
        raise ValueError(
            f"blocks of {blocks.shape[-1]} entries do not match N={n}, n_obstacle_obs={n_obstacle_obs}, "
            f"formation={formation} (expected {expected})"
        )
    batch = blocks.shape[:-2]
    c, s = blocks[..., layout.entry("heading", 0)], blocks[..., layout.entry("heading", 1)]  # (..., N)
    target = blocks[..., layout["target"]]
    distance = blocks[..., layout.entry("target_distance")]
    leader = np.zeros(batch + (n,))
    if formation:
        leader[..., 0] = 1.0
        error = blocks[..., layout["formation_error"]]
        ex, ey = _rotate_into_body(c, s, error[..., 0], error[..., 1])
    else:
        ex = ey = np.zeros(batch + (n,))
    safe = np.maximum(distance, 1e-6)
    ego = np.stack(
        [
            np.clip(target[..., 0] / _TARGET_SCALE, -2, 2),
            np.clip(target[..., 1] / _TARGET_SCALE, -2, 2),
            np.minimum(distance, 2 * _TARGET_SCALE) / _TARGET_SCALE,
            target[..., 0] / safe,
            target[..., 1] / safe,
            np.log(distance + _EPS),
            blocks[..., layout.entry("target_heading", 0)],
            blocks[..., layout.entry("target_heading", 1)],
            np.clip(ex / _FORMATION_SCALE, -2, 2),
            np.clip(ey / _FORMATION_SCALE, -2, 2),
            leader,
        ],
        axis=-1,
    )
    parts = [ego, _neighbour_slots(blocks, layout, c, s, target, leader, config)]
    parts.append(_obstacle_slots(blocks, layout, config))
    if config.movers:
        parts.append(_mover_slots(movers, batch + (n,), config))
    return np.concatenate(parts, axis=-1).astype(np.float32)


def split_movers(team_blocks: NDArray, layout: ObservationLayout) -> tuple[NDArray, NDArray]:
    """The blocks (..., N, ``layout.size``) without the movers they list, in the layout
    ``layout.without_movers()``, and those movers (..., N, S, 5), nearest first, their entries named
    by :class:`koopman_envs.MoverEntry` (dx, dy, vx, vy, clearance); S = ``layout.count("movers")``
    (0 with lidar or without movers: nothing listed). Where the movers part lies is the layout's
    (``layout["movers"]``), not counted here; ``ValueError`` for blocks of another width."""
    blocks = np.asarray(team_blocks, dtype=np.float64)
    if not isinstance(layout, ObservationLayout):
        raise TypeError(f"layout must be an ObservationLayout, not {type(layout).__name__}")
    if blocks.ndim < 2 or blocks.shape[-1] != layout.size:
        raise ValueError(
            f"blocks of shape {blocks.shape} do not hold (..., N, {layout.size}) entries: the size of one "
            f"block of {layout}"
        )
    if not layout.has("movers"):
        return blocks, np.zeros(blocks.shape[:-1] + (0, PART_WIDTH["movers"]))
    return np.delete(blocks, layout["movers"], axis=-1), layout.items(blocks, "movers")


def without_message_ages(team_obs: np.ndarray, n_robots: int) -> np.ndarray:
    """Team observations (..., N*F) without the message ages and arrival flags that end every
    block of an env with a ``comm`` setting (2 (N - 1) entries per block) once its movers are
    off (:func:`split_movers`): the ``messages`` part, the last
    of :class:`~koopman_envs.layout.ObservationLayout`'s parts before ``movers``."""
    tail = ObservationLayout(n_robots, comm=True).count("messages") * PART_WIDTH["messages"]
    if tail == 0:
        return team_obs
    batch = team_obs.shape[:-1]
    blocks = team_obs.reshape(batch + (n_robots, -1))
    return blocks[..., :-tail].reshape(batch + (-1,))


def state_layout(
    width: int, n_robots: int, *, formation: bool | None = None, comm: bool = False, movers: int = 0
) -> ObservationLayout:
    """The layout of a state-sensing env's block of ``width`` entries for these settings: the one
    count of listed obstacles (and, with ``formation`` None, the one task: the formation error's
    two entries and an obstacle's three tell them apart) whose :class:`ObservationLayout` has that
    size; what a policy reads when it is handed observations without their env
    (:func:`baselines.sb3.inference.policy_inputs`). ``ValueError`` naming ``width`` when none has it."""
    tasks = (False, True) if formation is None else (bool(formation),)
    for task in tasks:
        base = ObservationLayout(n_robots, 0, task, 0, comm, movers)
        listed, left = divmod(width - base.size, PART_WIDTH["obstacles"])
        if listed >= 0 and not left:
            return ObservationLayout(n_robots, listed, task, 0, comm, movers)
    sizes = " or ".join(str(ObservationLayout(n_robots, 0, task, 0, comm, movers).size) for task in tasks)
    raise ValueError(
        f"a block of {width} entries is no state-sensing block of n_robots={n_robots}, formation={formation}, "
        f"comm={comm}, movers={movers}: those hold {sizes} + {PART_WIDTH['obstacles']} per listed obstacle"
    )


def _mover_slots(movers: NDArray | None, lead: tuple[int, ...], config: SetFeatureConfig) -> NDArray:
    """The mover slots (..., N, slots * (MOVER_SIZE + 1)), nearest first (as listed)."""
    k = config.movers
    out = np.zeros(lead + (k, MOVER_SIZE + 1))
    chosen = 0 if movers is None else min(k, movers.shape[-2])
    if chosen:
        assert movers is not None
        listed = np.asarray(movers, dtype=np.float64)[..., :chosen, :]
        gap = listed[..., MoverEntry.CLEARANCE]
        present = (gap < FAR - 1.0) & (gap <= config.sensing_radius)  # absent ones read FAR
        features = np.stack(
            [
                np.clip(listed[..., MoverEntry.DX] / _NEAR_SCALE, -3, 3),
                np.clip(listed[..., MoverEntry.DY] / _NEAR_SCALE, -3, 3),
                np.clip(listed[..., MoverEntry.VX] / _SPEED_SCALE, -3, 3),
                np.clip(listed[..., MoverEntry.VY] / _SPEED_SCALE, -3, 3),
                np.clip(gap / _NEAR_SCALE, -1, 3),
            ],
            axis=-1,
        )
        out[..., :chosen, :MOVER_SIZE] = features * present[..., None]
        out[..., :chosen, MOVER_SIZE] = present
    return out.reshape(lead + (-1,))


@lru_cache(maxsize=64)
def _others(n: int) -> NDArray[np.int64]:
    """others[i]: the team indices that robot i's block lists, in its order (built once per N)."""
    others = np.array([[j for j in range(n) if j != i] for i in range(n)], dtype=np.int64).reshape(n, n - 1)
    others.setflags(write=False)
    return others


def _neighbour_slots(
    blocks: NDArray,
    layout: ObservationLayout,
    c: NDArray,
    s: NDArray,
    target: NDArray,
    leader: NDArray,
    config: SetFeatureConfig,
) -> NDArray:
    """The neighbour slots (..., N, K * (NEIGHBOUR_SIZE + 1)), nearest first."""
    n = blocks.shape[-2]
    batch = blocks.shape[:-2]
    k = config.neighbours
    out = np.zeros(batch + (n, k, NEIGHBOUR_SIZE + 1))
    if n == 1:
        return out.reshape(batch + (n, -1))
    others = _others(n)
    listed = layout.items(blocks, "team")  # (..., N, N - 1, entries)
    dx, dy, gap = listed[..., TeamEntry.DX], listed[..., TeamEntry.DY], listed[..., TeamEntry.CLEARANCE]
    # relative heading of j seen from i, and j's target offset rotated from j's frame into i's
    c_j, s_j = c[..., others], s[..., others]
    ci, si = c[..., None], s[..., None]
    cr, sr = c_j * ci + s_j * si, s_j * ci - c_j * si
    tx, ty = target[..., others, 0], target[..., others, 1]
    gx, gy = cr * tx - sr * ty, sr * tx + cr * ty
    features = np.stack(
        [
            np.clip(dx / _NEAR_SCALE, -3, 3),
            np.clip(dy / _NEAR_SCALE, -3, 3),
            np.clip(gap / _NEAR_SCALE, -1, 3),
            cr,
            sr,
            np.clip(gx / _TARGET_SCALE, -2, 2),
            np.clip(gy / _TARGET_SCALE, -2, 2),
            leader[..., others],
        ],
        axis=-1,
    )  # (..., N, N - 1, NEIGHBOUR_SIZE)
    chosen = min(k, n - 1)
    order = nearest_order(gap, chosen)  # nearest first
    picked = np.take_along_axis(features, order[..., None], axis=-2)
    present = np.take_along_axis(gap, order, axis=-1) <= config.sensing_radius
    out[..., :chosen, :NEIGHBOUR_SIZE] = picked * present[..., None]
    out[..., :chosen, NEIGHBOUR_SIZE] = present
    return out.reshape(batch + (n, -1))


def _obstacle_slots(blocks: NDArray, layout: ObservationLayout, config: SetFeatureConfig) -> NDArray:
    """The obstacle slots (..., N, slots * (OBSTACLE_SIZE + 1)), nearest first."""
    batch, n = blocks.shape[:-2], layout.n_robots
    k = config.obstacles
    out = np.zeros(batch + (n, k, OBSTACLE_SIZE + 1))
    chosen = min(k, layout.n_obstacle_obs)
    if chosen:
        listed = layout.items(blocks, "obstacles")[..., :chosen, :]  # (..., N, chosen, entries)
        gap = listed[..., ObstacleEntry.CLEARANCE]
        # the env lists absent obstacles at clearance FAR
        present = (gap < FAR - 1.0) & (gap <= config.sensing_radius)
        features = np.stack(
            [
                np.clip(listed[..., ObstacleEntry.DX] / _NEAR_SCALE, -3, 3),
                np.clip(listed[..., ObstacleEntry.DY] / _NEAR_SCALE, -3, 3),
                np.clip(gap / _NEAR_SCALE, -1, 3),
            ],
            axis=-1,
        )
        out[..., :chosen, :OBSTACLE_SIZE] = features * present[..., None]
        out[..., :chosen, OBSTACLE_SIZE] = present
    return out.reshape(batch + (n, -1))


def split_set_observation(size: int, config: SetFeatureConfig) -> tuple[slice, slice, slice, slice]:
    """Slices of ego, neighbour slots, obstacle slots and mover slots (empty without) in an
    observation of ``size`` entries."""
    if size != config.size:
        raise ValueError(f"a set observation of {config} has {config.size} entries, not {size}")
    a = EGO_SIZE
    b = a + config.neighbours * (NEIGHBOUR_SIZE + 1)
    c = b + config.obstacles * (OBSTACLE_SIZE + 1)
    return slice(0, a), slice(a, b), slice(b, c), slice(c, size)


# the largest value an entry can take (bounds of the observation space)
SET_FEATURE_BOUND = float(max(3.0, abs(math.log(_EPS)), math.log(FAR + _EPS)))
