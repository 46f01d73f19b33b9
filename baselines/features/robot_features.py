"""What a shared per-robot policy sees beside its own observation block (the ``rl-ppo`` policies'
``features``, and MAPPO's when trained with them): the target's bearing and log distance, and
the team-mates' relative headings. numpy only, so that the TorchRL and BenchMARL fronts use it
without stable-baselines3."""

from __future__ import annotations

import numpy as np

from baselines.shaping import PRECISION_EPS
from koopman_envs import TeamEntry, nearest_order
from koopman_envs.checks import check_choice, check_int
from koopman_envs.layout import ObservationLayout

__all__ = ["FEATURE_SETS", "feature_bounds", "feature_count", "robot_features"]

#: what a shared (``"robot"`` layout) policy sees beside its block; see :func:`robot_features`
FEATURE_SETS = ("bearing", "bearing+headings")
_PRECISION_EPS = PRECISION_EPS  # [m]: the log-distance feature's floor, the potential's


def _nearest_neighbours(blocks: np.ndarray, neighbours: int) -> tuple[np.ndarray, np.ndarray]:
    """Blocks that list only ``neighbours`` other robots, and those robots' team indices.

    Each robot keeps the ``neighbours`` others with the smallest surface clearance, listed in
    team-index order as the full block lists them (so with N - 1 == ``neighbours`` nothing
    changes); with fewer others than that, the missing slots read like absent obstacles
    (0, 0, FAR) and point at the robot itself.
    """
    from koopman_envs import FAR

    n = blocks.shape[-2]
    layout = ObservationLayout(n)
    team = layout["team"]  # the parts before and after it keep their places
    width = len(TeamEntry)  # entries per team-mate
    others = np.array([[j for j in range(n) if j != i] for i in range(n)], dtype=np.int64).reshape(n, n - 1)
    listed = min(neighbours, n - 1)
    clearance = layout.items(blocks, "team")[..., TeamEntry.CLEARANCE]  # (..., N, N - 1)
    # the nearest ``listed`` slots, then back into index order (a stable sort keeps ties in order)
    slots = np.sort(nearest_order(clearance, listed), axis=-1)
    entries = team.start + width * slots[..., None] + np.arange(width)  # (..., N, listed, width)
    chosen = np.take_along_axis(blocks, entries.reshape(entries.shape[:-2] + (-1,)), axis=-1)
    absent = np.zeros(width)  # a missing slot reads as an absent team-mate: (0, 0, FAR)
    absent[TeamEntry.CLEARANCE] = FAR
    pad = np.tile(absent, neighbours - listed)
    chosen = np.concatenate([chosen, np.broadcast_to(pad, chosen.shape[:-1] + pad.shape)], axis=-1)
    index = np.broadcast_to(others, slots.shape[:-2] + others.shape)
    robots = np.take_along_axis(index, slots, axis=-1)
    robots = np.concatenate(
        [robots, np.broadcast_to(np.arange(n)[:, None], robots.shape[:-1] + (neighbours - listed,))], axis=-1
    )
    rest = blocks[..., team.stop :]
    return np.concatenate([blocks[..., : team.start], chosen, rest], axis=-1), robots


def robot_features(
    team_blocks: np.ndarray, features: str = "bearing", neighbours: int | None = None
) -> np.ndarray:
    """Every robot's feature block plus entries that a shared policy learns from more easily.

    ``"bearing"`` appends the unit bearing of the target in the body frame (body x, y divided by
    the distance) and ``log(distance + 5 cm)``. Observation normalization scales the raw
    body-frame offsets by their spread over whole episodes (metres), which leaves a 10 cm offset
    at a few hundredths of a unit; the bearing and the log distance keep their resolution near
    the goal, where a unicycle must turn before it can close the gap.
    ``"bearing+headings"`` also appends, for every other robot (in the block's order), the cos
    and sin of its heading relative to this robot's: where a team-mate is going, which a robot's
    own block does not say and which crossing paths (Map 2) need.

    Parameters
    ----------
    team_blocks : ndarray, shape (..., N, F)
        The team's feature blocks (:class:`koopman_envs.layout.ObservationLayout`: read are the
        ``heading``, ``target`` and ``target_distance`` parts).
    features : str
        One of :data:`FEATURE_SETS`.
    neighbours : int, optional
        Other robots a block lists (default: all N - 1). A policy trained with N robots runs any
        team size with ``neighbours=N - 1``: each robot then sees its nearest team-mates, in the
        layout it was trained on.

    Returns
    -------
    ndarray, shape (..., N, F + 3) or (..., N, F + 3 + 2 (N - 1)), float32
    """
    check_choice("features", features, FEATURE_SETS)
    blocks = np.asarray(team_blocks, dtype=np.float64)
    n = blocks.shape[-2]
    if neighbours is not None:
        check_int("neighbours", neighbours, 0)
    if neighbours is None or neighbours == n - 1:
        others = np.broadcast_to(
            np.array([[j for j in range(n) if j != i] for i in range(n)], dtype=np.int64).reshape(n, n - 1),
            blocks.shape[:-1] + (n - 1,),
        )
    else:
        blocks, others = _nearest_neighbours(blocks, int(neighbours))
    layout = ObservationLayout(n)  # the parts read here come before every optional one
    distance = blocks[..., layout["target_distance"]]
    bearing = blocks[..., layout["target"]] / np.maximum(distance, 1e-6)
    parts = [blocks, bearing, np.log(distance + _PRECISION_EPS)]
    if features == "bearing+headings" and others.shape[-1] > 0:
        c, s = blocks[..., layout.entry("heading", 0)], blocks[..., layout.entry("heading", 1)]  # (..., N)
        c_o = np.take_along_axis(c[..., None, :], others, axis=-1)  # (..., N, listed others)
        s_o = np.take_along_axis(s[..., None, :], others, axis=-1)
        ci, si = c[..., None], s[..., None]
        relative = np.stack([c_o * ci + s_o * si, s_o * ci - c_o * si], axis=-1)
        parts.append(relative.reshape(relative.shape[:-2] + (-1,)))
    return np.concatenate(parts, axis=-1).astype(np.float32)


def feature_count(block_size: int, n_robots: int, features: str) -> int:
    """Length of one robot's policy input for a feature set."""
    extra = 2 * (n_robots - 1) if features == "bearing+headings" else 0
    return block_size + 3 + extra


def feature_bounds(
    low: np.ndarray, high: np.ndarray, n_robots: int, features: str
) -> tuple[np.ndarray, np.ndarray]:
    """The bounds (float32, ``(..., F + extra)``) of a robot's block of bounds ``low``/``high``
    (``(..., F)``) with ``features`` appended: the unit bearing in [-1, 1], the log distance from
    its floor to its value at the block's largest distance, relative headings in [-1, 1]."""
    low, high = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
    extra = feature_count(0, n_robots, features) - 3
    far = high[..., ObservationLayout(n_robots).entry("target_distance")]
    lead = low.shape[:-1]
    new_low = np.concatenate(
        [
            np.full(lead + (2,), -1.0),
            np.full(lead + (1,), np.log(_PRECISION_EPS)),
            np.full(lead + (extra,), -1.0),
        ],
        axis=-1,
    )
    new_high = np.concatenate(
        [np.ones(lead + (2,)), np.log(far + _PRECISION_EPS)[..., None], np.ones(lead + (extra,))], axis=-1
    )
    return (
        np.concatenate([low, new_low], axis=-1).astype(np.float32),
        np.concatenate([high, new_high], axis=-1).astype(np.float32),
    )
